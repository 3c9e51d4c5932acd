"""Large wavenumber counts and sweeps: checked before they start, computed with flat memory, same results."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from grainplug.errors import ParameterError
from grainplug.stability import ModelParams, analyze_stability, roots, sweep

SETUPS = [
    {},  # printed: stable everywhere
    {"variant": "frozen-friction"},  # one band, one cut-off
    {"friction_law": "coulomb-weight"},  # growth largest at k_max
    {"variant": "frozen-friction", "base_pressure_pa": 101_325.0},  # largest at k_min
    {"jamming": True, "variant": "frozen-friction"},
    {"theta_deg": 80.0, "mu_s": 0.0},
]


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "grainplug", "stability", *args], capture_output=True, text=True,
                          timeout=120)


def _same(a, b, *, arrays: bool = True) -> None:
    """Same most unstable mode, cut-offs and bands, to the last bit (and the same arrays)."""
    assert a.most_unstable == b.most_unstable
    assert a.cutoff_k == b.cutoff_k
    assert a.unstable_bands == b.unstable_bands
    assert a.n_k == b.n_k
    if arrays:
        assert np.array_equal(a.k, b.k) and np.array_equal(a.omega, b.omega)


# -- refused before they start -----------------------------------------------------------------------------
@pytest.mark.parametrize("args, flag", [
    (["--sweep", "c0=0.45:0.6:1000000000000"], "--sweep"),
    (["--n-k", "1e12"], "--n-k"),
])
def test_huge_sweep_and_wavenumber_count_are_refused_in_one_line(args, flag):
    done = _cli(*args)
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {flag}: "), done.stderr
    assert "Traceback" not in done.stderr and "MemoryError" not in done.stderr


def test_library_refuses_what_does_not_fit_or_lasts_too_long():
    p = ModelParams()
    # every root of 10^13 wavenumbers kept: refused before anything is allocated
    with pytest.raises(ParameterError) as err:
        analyze_stability(p, n_k=10**13, max_points=None)
    assert err.value.param == "n_k"
    # the time measured on the first chunk, against the limit
    with pytest.raises(ParameterError) as err:
        analyze_stability(p, n_k=10**6, max_seconds=1e-3)
    assert err.value.param == "n_k"
    with pytest.raises(ParameterError) as err:
        sweep(p, "c0", np.linspace(0.5, 0.6, 50), n_k=200, max_seconds=1e-4)
    assert err.value.param == "values"
    with pytest.raises(ParameterError) as err:
        sweep(p, "c0", [0.55], n_k=10**13, max_points=None)
    assert err.value.param == "n_k"
    with pytest.raises(ParameterError):
        analyze_stability(p, n_k=1)


# -- chunked equals unchunked ------------------------------------------------------------------------------
@pytest.mark.parametrize("setup", SETUPS)
def test_chunks_give_the_same_results_as_one(setup):
    p = ModelParams(**setup)
    for n_k, k_min in ((1000, 1e-3), (100_000, 1e-3), (3001, 1e-5)):
        one = analyze_stability(p, k_min=k_min, n_k=n_k, chunk_size=n_k)
        assert np.array_equal(one.k, np.linspace(k_min, 3.0, n_k))  # the grid, to the last bit
        for chunk in ((7, 1000, 4096) if n_k < 10_000 else (4096, 30_001)):
            _same(one, analyze_stability(p, k_min=k_min, n_k=n_k, chunk_size=chunk))
    k = np.geomspace(1e-4, 3.0, 2000)  # wavenumbers given
    _same(analyze_stability(p, k, chunk_size=2000), analyze_stability(p, k, chunk_size=333))
    np.testing.assert_array_equal(roots(p, k, chunk_size=2000), roots(p, k, chunk_size=7))


def test_a_chunk_boundary_on_a_cut_off():
    """The sign change between the last wavenumber of a chunk and the first of the next is found and refined."""
    p = ModelParams(variant="frozen-friction")
    one = analyze_stability(p, n_k=5000, chunk_size=5000)
    assert len(one.cutoff_k) == 1
    i = int(np.nonzero(np.diff(one.omega.imag.max(axis=1) > 0))[0][0])  # k[i] unstable, k[i + 1] stable
    j = int(np.argmax(one.omega.imag.max(axis=1)))
    for chunk in (i - 1, i, i + 1, i + 2, j, j + 1):  # boundaries just before, on and after the cut-off and peak
        _same(one, analyze_stability(p, n_k=5000, chunk_size=chunk))
        curve = analyze_stability(p, n_k=5000, chunk_size=chunk, max_points=100, curve_points=20)
        _same(one, curve, arrays=False)
        assert one.k[i] in curve.k and one.k[i + 1] in curve.k


# -- what a large count keeps --------------------------------------------------------------------------------
@pytest.mark.parametrize("setup", SETUPS[:3])
def test_a_decimated_curve_keeps_the_peak_and_the_cut_offs(setup):
    p = ModelParams(**setup)
    full = analyze_stability(p, n_k=20_000)
    assert not full.decimated and len(full.k) == full.n_k == 20_000
    curve = analyze_stability(p, n_k=20_000, max_points=10_000, curve_points=500, chunk_size=3000)
    _same(full, curve, arrays=False)
    assert curve.decimated and curve.n_k == 20_000 and 500 <= len(curve.k) <= 500 + 1 + 2 * len(curve.cutoff_k)
    at = np.searchsorted(full.k, curve.k)
    assert np.array_equal(full.k[at], curve.k) and np.array_equal(full.omega[at], curve.omega)  # the roots computed
    assert curve.k[0] == full.k[0] and curve.k[-1] == full.k[-1]
    assert curve.omega.imag.max() == full.omega.imag.max()  # the peak's grid point
    # the same sign changes of the largest growth rate, between the same grid points
    sign_full = np.nonzero(np.diff(full.omega.imag.max(axis=1) > 0))[0]
    sign_curve = np.nonzero(np.diff(curve.omega.imag.max(axis=1) > 0))[0]
    assert np.array_equal(full.k[sign_full], curve.k[sign_curve])
    assert np.array_equal(full.k[sign_full + 1], curve.k[sign_curve + 1])
    d = curve.as_dict()
    assert d["n_k"] == 20_000 and d["decimated"] is True and len(d["k"]) == len(curve.k)
    assert "a curve of" in repr(curve)


def test_ordinary_counts_keep_every_root():
    res = analyze_stability(ModelParams(variant="frozen-friction"))
    assert len(res.k) == res.n_k == 1000 and res.omega.shape == (1000, 3) and not res.decimated
    assert res.as_dict()["decimated"] is False


def test_cli_million_wavenumbers_json_holds_a_curve():
    done = _cli("--variant", "frozen-friction", "--n-k", "1e6", "--json")
    assert done.returncode == 0, done.stderr
    d = json.loads(done.stdout)
    assert d["n_k"] == 1_000_000 and d["decimated"] is True
    assert 10_000 <= len(d["k"]) <= 10_003 and len(d["omega_imag"][0]) == len(d["k"])
    assert d["most_unstable"]["wavelength_over_diameter"] == pytest.approx(42.57, abs=0.01)
    assert len(d["cutoff_k"]) == 1


# -- peak memory of the whole process -------------------------------------------------------------------------
def test_a_million_wavenumbers_stay_under_200_MB():
    """``grainplug stability --n-k 1e6 --json``, the whole process: interpreter, numpy, scipy and the run
    (10^6 wavenumbers solved at once took 1.0 GB, 1.3 GB with --json)."""
    code = textwrap.dedent(f"""
        import resource, subprocess, sys
        done = subprocess.run([{sys.executable!r}, "-m", "grainplug", "stability", "--n-k", "1e6", "--json"],
                              stdout=subprocess.DEVNULL)
        print(done.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    status, peak_kb = map(int, out.stdout.split())
    assert status == 0
    assert peak_kb < 200 * 1024, f"peak RSS {peak_kb / 1024:.0f} MB"
