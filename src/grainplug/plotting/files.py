"""Write a figure to files: one per format of :class:`~grainplug.plotting.options.FigureOptions`.

The lowest place for it, below the analysis's outputs (:mod:`grainplug.outputs`), a
simulation's (:mod:`grainplug.simulation.store`) and a campaign's, which all call it.
"""

from __future__ import annotations

from pathlib import Path

from .options import FigureOptions


def save_figure(fig: object, folder: str | Path, name: str, options: FigureOptions | None = None) -> list[str]:
    """Save ``fig`` as ``name`` (a ``.png`` name) in every format of ``options``; returns the file names."""
    options = options or FigureOptions()
    stem = Path(name).stem
    names = []
    # images drawn as the data's own pixels ("none"): so in SVG, whose viewers show them crisp; in PDF resampled
    # at the figure's resolution instead, as PDF viewers (pdfium, Chrome's) smooth an image drawn larger
    # than its pixels
    unsampled = [im for ax in fig.axes for im in ax.get_images()  # type: ignore[attr-defined]
                 if im.get_interpolation() == "none"]
    for fmt in options.formats:
        target = Path(folder) / f"{stem}.{fmt}"
        for im in unsampled:
            im.set_interpolation("nearest" if fmt == "pdf" else "none")
        # PNG at zlib level 1: a fraction of the default's time, files ~15% larger
        kw = {"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}
        fig.savefig(target, dpi=options.dpi, format=fmt, **kw)  # type: ignore[attr-defined]
        names.append(target.name)
    for im in unsampled:
        im.set_interpolation("none")
    return names
