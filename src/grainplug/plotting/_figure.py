"""Figures without pyplot: no backend chosen, no global figure list, safe in any thread."""

from __future__ import annotations

from typing import Any

from matplotlib.figure import Figure


def new_figure(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], constrained_layout: bool = False,
               **kwargs: Any) -> tuple[Figure, Any]:
    """``(figure, axes)`` like ``pyplot.subplots``, but the figure is not registered with pyplot.

    It is drawn with the Agg canvas when saved (``fig.savefig``) and freed with its
    last reference, so library code never picks a backend (that is the user's or the
    notebook's choice) and never leaks figures.
    """
    fig = Figure(figsize=figsize, layout="constrained" if constrained_layout else None)
    return fig, fig.subplots(nrows, ncols, **kwargs)


def pt(size: float) -> float:
    """A font size of the figures' design (in points, for matplotlib's default 10-point text) scaled with the
    style sheet in force: ``font.size: 7`` draws every text of the figure at 0.7 times its size."""
    import matplotlib as mpl

    return size * float(mpl.rcParams["font.size"]) / 10.0
