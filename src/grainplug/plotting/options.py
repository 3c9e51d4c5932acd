"""How an analysis's figures are written: formats, resolution, style (:class:`FigureOptions`).

A module of its own, without numpy or matplotlib, so that the command line can check its
figure flags and start the figure worker before the analysis's heavy imports.
"""

from __future__ import annotations

import logging
import numbers
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

#: formats a figure can be written in
FIGURE_FORMATS = ("png", "svg", "pdf")


@dataclass(frozen=True)
class FigureOptions:
    """How the figures are written: by default each as PNG at 200 dpi; :data:`PUBLICATION`
    adds SVG and PDF.

    Attributes
    ----------
    dpi : int
        Resolution of the PNG files (200, enough for print; 110 is quicker to write).
    formats : tuple of str
        ``"png"``, ``"svg"``, ``"pdf"``: each figure in each format (vector for journals).
    style : str, optional
        A matplotlib style sheet (a name such as ``"seaborn-v0_8-paper"`` or a ``.mplstyle`` file)
        applied to every figure: fonts (text sizes scale with its ``font.size``), colours, line
        widths. Each figure keeps its own size and layout (a sheet's ``figure.figsize`` is not used).

    Notes
    -----
    The two vector formats are not written by default: they cost about 0.6 s a run
    (docs/performance.md), against issue 14's fixed-cost target and at the edge of its
    in-memory speed targets. ``--publication``, or ``publication = true`` in
    ``grainplug.toml``, writes them.
    """

    dpi: int = 200
    formats: tuple[str, ...] = ("png",)
    style: str | None = None

    def __post_init__(self) -> None:
        from ..errors import ParameterError

        if isinstance(self.dpi, bool) or not isinstance(self.dpi, numbers.Real) or not 20 <= self.dpi <= 1200:
            raise ParameterError(f"must be between 20 and 1200, got {self.dpi!r}", param="dpi")
        if isinstance(self.formats, str):  # "png,svg", as the command line takes them
            object.__setattr__(self, "formats", tuple(f.strip() for f in self.formats.split(",") if f.strip()))
        bad = [f for f in self.formats if f not in FIGURE_FORMATS]
        if bad or not self.formats:
            raise ParameterError(f"figure formats are {', '.join(FIGURE_FORMATS)}; got {', '.join(self.formats)}",
                                 param="formats")
        if self.style is not None:
            # a file is recorded in summary.json as a full path: remeasure, run from anywhere, finds it again
            style = Path(self.style)
            object.__setattr__(self, "style", str(style.resolve()) if style.is_file() else str(self.style))

    def as_record(self) -> dict[str, object]:
        """As ``summary.json`` records them (``"figures"``)."""
        return {"dpi": self.dpi, "formats": list(self.formats), "style": self.style}

    @classmethod
    def recorded(cls, summary: dict) -> FigureOptions:
        """The options a saved analysis's figures were written with (its ``summary.json``), for
        rewriting them alike; the defaults where it records none, a style sheet that is gone left out."""
        from ..errors import GrainplugError

        rec = summary.get("figures")
        if not isinstance(rec, dict):
            return cls()
        style = rec.get("style")
        if style and Path(style).suffix and not Path(style).is_file():
            log.warning("the style sheet %s the figures were drawn with is gone: they are redrawn without it",
                        style)
            style = None
        try:
            return cls(dpi=int(rec.get("dpi", cls.dpi)), formats=tuple(rec.get("formats", cls.formats)),
                       style=style)
        except (TypeError, ValueError, GrainplugError):
            return cls()


#: for print: PNG at 200 dpi, SVG and PDF (``--publication``)
PUBLICATION = FigureOptions(dpi=200, formats=FIGURE_FORMATS)
