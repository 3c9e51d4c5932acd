"""The campaign table's columns: their types, units and meaning (``campaign.schema.json``).

Notes
-----
``campaign.csv`` and ``campaign.parquet`` hold one row per run. Every column grainplug
writes is listed in :data:`COLUMNS` with a pandas dtype: ``string``, ``Float64``,
``Int64`` or ``boolean`` (nullable: a failed run has empty measures, not ``nan`` strings).
Units are in the names (``_m_s``, ``_mm``, ``_hz``, ``_px``, ``_deg``, ``_s``, ``_g_s``,
``_pct``). Manifest columns grainplug does not know (operator, notes...) are kept as they
were read. :data:`SCHEMA_VERSION` changes whenever a column changes meaning or type; it is
in ``campaign.schema.json``, in the Parquet file's metadata and in ``fits.json``.
"""

from __future__ import annotations

import json

import pandas as pd

SCHEMA_VERSION = 1

#: column -> (pandas dtype, meaning)
COLUMNS: dict[str, tuple[str, str]] = {
    "run": ("string", "the run's name (manifest)"),
    "movie": ("string", "the movie, as given in the manifest"),
    "status": ("string", "ok or failed"),
    "error": ("string", "why the run failed (one line)"),
    "run_key": ("string", "identity of the movie and parameters; a finished run with the same key is reused"),
    "mass_flow_rate_g_s": ("Float64", "grains' mass flow rate, g/s (manifest)"),
    "humidity_pct": ("Float64", "relative humidity, % (manifest)"),
    "surface": ("string", "grains' surface state, rough or smooth (manifest)"),
    "group": ("string", "fit group (manifest)"),
    "celerity_m_s": ("Float64", "mean celerity of the plugs, m/s, positive downstream"),
    "celerity_ci95_low_m_s": ("Float64", "its 95 % interval, low end"),
    "celerity_ci95_high_m_s": ("Float64", "its 95 % interval, high end"),
    "plug_length_mm": ("Float64", "mean plug length, mm"),
    "plug_length_ci95_low_mm": ("Float64", "its 95 % interval, low end"),
    "plug_length_ci95_high_mm": ("Float64", "its 95 % interval, high end"),
    "plug_length_over_diameter": ("Float64", "mean plug length over the tube diameter"),
    "plug_length_sd_mm": ("Float64", "standard deviation of the plug lengths, mm"),
    "bubble_length_mm": ("Float64", "mean bubble length, mm"),
    "oscillation_frequency_hz": ("Float64", "frequency of the oscillating regime, Hz"),
    "oscillation_amplitude_mm": ("Float64", "its amplitude, mm"),
    "regime": ("string", "propagative, oscillating, static (no motion of a pixel over the record) or none"),
    "has_plugs": ("boolean", "whether plugs were found"),
    "n_plugs": ("Int64", "plugs whose length entered the mean"),
    "n_frames": ("Int64", "frames analysed"),
    "fps": ("Float64", "frame rate, Hz"),
    "duration_s": ("Float64", "duration analysed, s"),
    "mm_per_px": ("Float64", "scale, mm per pixel"),
    "scale_source": ("string", "where the scale came from"),
    "scale_rel_sd": ("Float64", "relative standard uncertainty of the scale"),
    "tube_diameter_px": ("Float64", "tube bore in pixels"),
    "tube_axis_angle_deg": ("Float64", "angle of the tube's axis in the image, degrees"),
    "flow_direction": ("string", "direction of the flow in the image"),
    "mass_flow_rate_images_g_s": ("Float64", "the grains' mass flow rate from the movie (compactness, grain "
                                             "velocity, celerity), g/s: beside the weighed mass_flow_rate_g_s"),
    "mass_flow_rate_images_ci95_low_g_s": ("Float64", "its 95 % interval, low end"),
    "mass_flow_rate_images_ci95_high_g_s": ("Float64", "its 95 % interval, high end"),
    "input_sha256_sampled": ("string", "SHA-256 of sampled content of the movie"),
    "input_bytes": ("Int64", "size of the movie, bytes"),
    "grainplug_version": ("string", "the version that analysed the run"),
    "warnings": ("string", "the run's warnings, separated by ' | '"),
    "warning_codes": ("string", "the code of each of the run's warnings, in the same order, separated by ' | ' "
                                "(docs/analysis.md lists them)"),
    "n_corrections": ("Int64", "a reviewer's corrections applied (corrections.json)"),
}


def _missing(v: object) -> bool:
    return v is None or v is pd.NA or (isinstance(v, float) and v != v)


def typed(table: pd.DataFrame) -> pd.DataFrame:
    """The table with every known column in its schema dtype (unknown columns as they are)."""
    out = table.copy()
    for name, (dtype, _) in COLUMNS.items():
        if name in out:
            col = out[name]
            if dtype == "boolean":
                col = col.map(lambda v: None if _missing(v) else bool(v))
            elif dtype == "string":
                col = col.map(lambda v: None if _missing(v) else str(v))
            elif dtype in ("Float64", "Int64"):
                col = pd.to_numeric(col, errors="coerce")
                if dtype == "Int64":
                    col = col.round()
            out[name] = col.astype(dtype)
    return out


def schema_json(table: pd.DataFrame) -> str:
    """``campaign.schema.json``: the version and every column of ``table`` with its type and meaning."""
    cols = []
    for name in table.columns:
        dtype, meaning = COLUMNS.get(name, (str(table[name].dtype), "manifest metadata"))
        cols.append({"name": name, "dtype": dtype, "meaning": meaning})
    return json.dumps({"schema": "grainplug-campaign-table", "schema_version": SCHEMA_VERSION, "columns": cols},
                      indent=1) + "\n"
