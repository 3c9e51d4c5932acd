"""Work made of the layers below: read an analysis, apply a reviewer's corrections, write it again.

Above :mod:`grainplug.result` (it loads results) and :mod:`grainplug.outputs` (it writes them); used by
``grainplug remeasure``, the review page and ``gp.remeasure``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from .outputs import FILES, write_outputs
from .plotting.options import FigureOptions
from .result import AnalysisResult, load_result


def remeasure(folder: str | Path, *, figures: bool = True, report: bool = True) -> AnalysisResult:
    """Reapply ``folder/corrections.json`` to the analysis saved in ``folder`` and rewrite its outputs.

    The measures are recomputed from the detected tracks (the movie is not read); without a
    corrections file, the detection is restored as it was. Returns the corrected result.

    The folder is rewritten where it is, by its absolute path, so ``remeasure(".")`` from inside it
    works (the process then finds itself in the new folder). What grainplug did not write there (a
    user's notes) is kept in the new folder.
    """
    from .corrections import Corrections, apply_corrections
    from .store import read_corrections

    folder = Path(os.path.abspath(folder))  # "." names the folder by its name in its parent
    res = load_result(folder)
    corr = read_corrections(folder)
    new = apply_corrections(res, corr if corr is not None else Corrections())
    extra = {}
    try:
        old = json.loads((Path(folder) / FILES["summary"]).read_text())
    except (OSError, ValueError):
        old = {}
    old = old if isinstance(old, dict) else {}
    if isinstance(old.get("batch"), dict):
        extra["batch"] = old["batch"]  # a campaign's run keeps its key
    # the figures as they were written: their formats, resolution and style
    write_outputs(new, folder, figures=figures, report=report, extra=extra,
                  figure_options=FigureOptions.recorded(old), carry=True)
    return new
