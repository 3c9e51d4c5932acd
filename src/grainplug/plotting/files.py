"""Figure files: which figures an analysis has, their names, and saving a figure in every format asked.

Used by the analysis' outputs (:mod:`grainplug.outputs`), the figure worker
(:mod:`grainplug.plotting.worker`), the campaigns' and the simulations' figures; it imports nothing
above :mod:`grainplug.plotting` (an :class:`~grainplug.result.AnalysisResult` only for type checking).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from .options import FigureOptions

if TYPE_CHECKING:
    from ..result import AnalysisResult

#: output key -> file name of an analysis' figures (PNG; other formats take the same stem)
FIGURE_FILES = {
    "fig_diagram": "diagram.png",
    "fig_spectrum": "spectrum.png",
    "fig_frame": "frame.png",
}


def figures_of(res: AnalysisResult) -> list[str]:
    """The figures a result has: the diagram, the annotated frame, the spectrum when it oscillates."""
    keys = ["fig_diagram", "fig_frame"]
    if res.motion is not None and res.motion.oscillation_frequency_hz:
        keys.append("fig_spectrum")
    return keys


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


def figure_files(res: AnalysisResult, options: FigureOptions) -> dict[str, str]:
    """Output key -> file name of every figure file ``options`` makes for ``res``."""
    out = {}
    for key in figures_of(res):
        stem = Path(FIGURE_FILES[key]).stem
        for fmt in options.formats:
            out[key if fmt == "png" else f"{key}_{fmt}"] = f"{stem}.{fmt}"
    return out


def draw_figures(res: AnalysisResult, folder: str | Path, options: FigureOptions | None = None) -> list[Path]:
    """Draw the figures of ``res`` into ``folder`` (in this process, no pyplot), in each format of ``options``."""
    import contextlib

    from ..errors import ParameterError
    from .figures import plot_annotated_frame, plot_diagram, plot_spectrum

    options = options or FigureOptions()
    plots = {"fig_diagram": plot_diagram, "fig_frame": plot_annotated_frame, "fig_spectrum": plot_spectrum}
    paths = []
    with contextlib.ExitStack() as stack:
        if options.style:
            import matplotlib.style

            try:
                stack.enter_context(matplotlib.style.context(options.style))
            except OSError:
                raise ParameterError(f"{options.style!r} is neither the name of a matplotlib style "
                                     "(matplotlib.style.available) nor a style file", param="style") from None
        for key in figures_of(res):
            names = save_figure(plots[key](res), folder, FIGURE_FILES[key], options)
            paths.extend(Path(folder) / n for n in names)
    return paths
