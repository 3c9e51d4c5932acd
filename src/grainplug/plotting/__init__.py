"""Figures (matplotlib). Imported only by the output writers and the CLI."""

from .figures import plot_annotated_frame, plot_diagram, plot_spectrum

__all__ = ["plot_annotated_frame", "plot_diagram", "plot_spectrum"]
