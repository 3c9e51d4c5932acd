"""Self-contained HTML reports (figures embedded)."""

from .html import images, page, provenance, run_report, table

__all__ = ["images", "page", "provenance", "run_report", "table"]
