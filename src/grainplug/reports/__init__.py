"""Self-contained HTML reports (figures embedded)."""

from .html import run_report

__all__ = ["run_report"]
