"""Save a simulation: fields as NetCDF, a JSON summary and the diagram, in one atomic folder.

Notes
-----
The fields go to ``fields.nc`` through xarray's ``scipy`` engine (NetCDF 3): it needs
no library beyond SciPy, which grainplug already uses, and every lab's tools read it
(xarray, netCDF4, MATLAB's ``ncread``, ParaView). Zarr would need another
dependency and HDF5 a C library; a run's fields (a few tens of MB) do not need
chunked storage. Values are stored as float32 (7 digits, far below the scheme's
error); the totals used for the conservation check are in ``summary.json`` at full
precision.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._atomic import atomic_directory
from .._version import __version__

if TYPE_CHECKING:
    import xarray as xr

    from .state import SimulationResult

FIELDS_FILE, SUMMARY_FILE, DIAGRAM_FILE = "fields.nc", "summary.json", "diagram.png"


def to_xarray(res: SimulationResult) -> xr.Dataset:
    """The fields with coordinates in the model's units and in SI (``time_s``, ``position_mm``)."""
    import xarray as xr

    p = res.model
    coords = {"time_tc": ("time", res.time), "z_D": ("z", res.z),
              "time_s": ("time", res.time * p.t_c_s), "position_mm": ("z", res.z * p.diameter_mm)}
    ds = xr.Dataset(
        {"c": (("time", "z"), res.c.astype(np.float32), {"long_name": "compactness", "units": "1"}),
         "v": (("time", "z"), res.v.astype(np.float32),
               {"long_name": "grain velocity, positive downward", "units": "v_c"}),
         "v_m_s": (("time", "z"), (res.v * p.v_c_m_s).astype(np.float32),
                   {"long_name": "grain velocity, positive downward (downstream)", "units": "m s-1"}),
         "P": (("time", "z"), res.P.astype(np.float32), {"long_name": "absolute air pressure", "units": "P_c"})},
        coords=coords,
        attrs={"grainplug_version": __version__, "boundary": res.params.boundary,
               "friction_law": p.law, "v_c_m_s": p.v_c_m_s, "t_c_s": p.t_c_s, "P_c_pa": p.P_c_pa,
               "D_mm": p.diameter_mm})
    return ds


def save_simulation(res: SimulationResult, out_dir: str | Path, summary: dict[str, object], *,
                    figure: object | None = None, figure_options: object | None = None) -> dict[str, Path]:
    """Write ``fields.nc``, ``summary.json`` (and ``diagram.png``, in the formats of ``figure_options``)
    into ``out_dir`` atomically."""
    from ..jsonio import dumps
    from ..plotting.files import save_figure

    written: dict[str, Path] = {}
    with atomic_directory(out_dir, written, replace=True, kind="simulation") as tmp:
        to_xarray(res).to_netcdf(tmp / FIELDS_FILE, engine="scipy")
        (tmp / SUMMARY_FILE).write_text(dumps(summary), encoding="utf-8")
        if figure is not None:
            save_figure(figure, tmp, DIAGRAM_FILE, figure_options)  # type: ignore[arg-type]
    return written
