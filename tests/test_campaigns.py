"""Paper data, fits, the paper's reproduction, manifests and batch runs."""

from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pandas as pd
import pytest
from test_cli_basics import assert_one_line_error, run
from warned import of_code

from grainplug import datasets
from grainplug.campaigns import fit_line, read_manifest, run_campaign
from grainplug.campaigns.paper import reproduce
from grainplug.errors import ParameterError
from grainplug.synthetic import SynthConfig, synthesize


def test_paper_tables():
    t1, t2 = datasets.table1(), datasets.table2()
    assert len(t1) == 17 and len(t2) == 15
    assert set(t1.surface) == {"rough", "smooth"}
    assert (t1.celerity_m_s < 0).all() and (t2.celerity_m_s > 0).all()
    assert t1.loc[t1.run == 12, "mass_flow_rate_g_s"].item() == 1.05
    assert t2.loc[t2.run == 3, "celerity_m_s"].item() == 0.0652
    np.testing.assert_allclose(t1.plug_length_mm, t1.plug_length_cm * 10)
    assert "10.1016/j.physa.2016.08.071" == datasets.source()["doi"]
    assert len(datasets.paper_runs()) == 32


def test_fit_line_against_scipy(rng):
    from scipy import stats

    x = rng.uniform(0, 1, 20)
    y = 0.3 - 0.1 * x + rng.normal(0, 0.01, 20)
    f = fit_line(x, y)
    ref = stats.linregress(x, y)
    assert f.slope == pytest.approx(ref.slope)
    assert f.intercept == pytest.approx(ref.intercept)
    assert f.slope_stderr == pytest.approx(ref.stderr)
    assert f.intercept_stderr == pytest.approx(ref.intercept_stderr)
    assert f.r2 == pytest.approx(ref.rvalue**2)
    lo, hi = f.band(np.array([f.x_mean, 0.0, 1.0]))
    assert np.all(hi > lo)
    assert (hi - lo)[0] < (hi - lo)[1]  # the band is narrowest at the mean
    assert fit_line([1.0], [2.0]) is None


def test_fit_coverage(rng):
    """The 95% interval of the slope covers the true slope about 95% of the time."""
    from scipy import stats

    hits = 0
    trials = 400
    for _ in range(trials):
        x = rng.uniform(0.2, 1.0, 12)
        y = -0.05 + 0.09 * x + rng.normal(0, 0.003, 12)
        f = fit_line(x, y)
        half = stats.t.ppf(0.975, f.n - 2) * f.slope_stderr
        hits += abs(f.slope - 0.09) <= half
    assert 0.92 <= hits / trials <= 0.98


def test_paper_reproduction():
    rep = reproduce(simulate=False)
    d = rep.as_dict()
    panel = d["model_vs_experiment"]
    assert panel["measured"]["n_runs"] == 17  # Table 1
    lin = {q["label"]: q for q in panel["predictions"]}
    assert lin["as printed"]["most_unstable_lambda_D"] is None
    assert lin["frozen friction"]["most_unstable_lambda_D"] == pytest.approx(2 * np.pi / 0.1476, rel=0.02)
    assert lin["frozen friction, atmospheric air"]["most_unstable_lambda_D"] is None  # longer than the pipe
    assert not any(q["nonlinear"] for q in panel["predictions"])  # simulate=False
    for key in ("propagative/rough", "propagative/smooth", "oscillating"):
        f = d["fits"][key]
        assert {"slope_m_s_per_g_s", "intercept_m_s", "slope_stderr", "intercept_stderr", "r2", "n"} <= set(f)
    t1 = datasets.table1()
    rough = t1[t1.surface == "rough"]
    ref = np.polyfit(rough.mass_flow_rate_g_s, rough.celerity_m_s, 1)
    assert d["fits"]["propagative/rough"]["slope_m_s_per_g_s"] == pytest.approx(ref[0])
    assert d["fits"]["propagative/rough"]["n"] == 7
    assert d["fits"]["oscillating"]["n"] == 15
    assert d["lengths"]["propagative"]["mean_over_diameter"] == pytest.approx(t1.plug_length_mm.mean() / 3)
    checks = {c["claim"]: c for c in d["checks"]}
    assert checks["oscillating v_p 'within 0.2 - 0.65 m/s'"]["agrees"] is False  # the factor-10 misprint
    assert checks["propagative celerity ranges between -0.0366 and -0.0963 m/s"]["agrees"] is True
    assert d["stability"]["printed"]["most_unstable"] is None
    assert d["stability"]["frozen-friction"]["most_unstable"]["k"] == pytest.approx(0.1476, abs=2e-3)
    # no false disagreements: the co-author's two surnames, a run Table 2 (low amplitude) does not claim to hold
    assert checks["'Franklin and Alvarez [Franklin_7]' cited for the Janssen closure and 3 < lambda/D < 11"]["agrees"]
    assert not any("0.019 m/s" in claim for claim in checks)


def test_paper_cli(tmp_path, capsys):
    code, out, err = run(capsys, "paper", "--out", tmp_path / "p", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert set(d["fits"]) == {"propagative/rough", "propagative/smooth", "oscillating"}
    for name in ("paper.json", "reproduction.md", "report.html", "celerity_propagative.png",
                 "length_oscillating.png", "growth_rates_printed.png", "growth_rates_frozen_friction.png"):
        assert (tmp_path / "p" / name).stat().st_size > 0, name
    text = (tmp_path / "p" / "reproduction.md").read_text()
    assert "Where it does not" in text and "misprint" in text
    # the model against Table 1, with the simulations: the direction disagrees, the length is set by the box
    panel = d["model_vs_experiment"]
    assert "the model does not predict the observed waves' direction" in panel["verdict"][0]
    # Table 2's plugs move down, the model's way: said, with how much faster the model's waves are
    assert any(v.startswith("Celerity, Table 2") and "times faster" in v for v in panel["verdict"])
    frozen = next(q for q in panel["predictions"] if q["label"] == "frozen friction")
    small, large = frozen["nonlinear"]
    assert small["n_waves"] == large["n_waves"] == 1
    assert large["dense_length_D"] > 1.5 * small["dense_length_D"]
    # every simulated set-up carries its movie measures as numbers (None where the analysis finds no plugs)
    runs = [n for q in panel["predictions"] for n in q["nonlinear"]]
    assert runs
    for n in runs:
        assert isinstance(n["regime"], str)
        for key in ("plug_length_mm", "bubble_length_mm", "celerity_m_s"):
            assert n[key] is None or (isinstance(n[key], float) and math.isfinite(n[key])), (key, n[key])
        assert n["regime"] != "none" or n["celerity_m_s"] is None
    assert "movie: plug (mm)" in (tmp_path / "p" / "report.html").read_text()
    assert (tmp_path / "p" / "model_vs_experiment.png").stat().st_size > 0
    assert "Model against experiment" in (tmp_path / "p" / "report.html").read_text()


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("camp")
    runs = [("a", 0.40, -0.040, "rough"), ("b", 0.55, -0.054, "rough"), ("c", 0.67, -0.063, "rough"),
            ("d", 0.50, -0.052, "smooth"), ("e", 0.84, -0.083, "smooth")]
    rows = []
    for i, (name, m, c, surf) in enumerate(runs):
        synthesize(SynthConfig(n_frames=120, celerity_m_s=c, seed=i, noise_sigma=2), d / name, fmt="avi")
        rows.append({"run": name, "movie": f"{name}/movie.avi", "mass_flow_rate_g_s": m, "humidity_pct": 44,
                     "surface": surf, "mm_per_px": 0.185, "operator": "lab-3"})
    with open(d / "manifest.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    toml = ["[defaults]", "mm_per_px = 0.185", "humidity_pct = 44", ""]
    for r in rows:
        toml += ["[[run]]", f'run = "{r["run"]}"', f'movie = "{r["movie"]}"',
                 f"mass_flow_rate_g_s = {r['mass_flow_rate_g_s']}", f'surface = "{r["surface"]}"', ""]
    (d / "manifest.toml").write_text("\n".join(toml))
    return d


def test_manifest_formats_agree(campaign_dir):
    a = read_manifest(campaign_dir / "manifest.csv")
    b = read_manifest(campaign_dir / "manifest.toml")
    assert [s.run for s in a] == [s.run for s in b]
    assert [s.movie for s in a] == [s.movie for s in b]
    assert a[0].params.mm_per_px == b[0].params.mm_per_px == 0.185
    assert a[0].meta["operator"] == "lab-3"
    assert a[1].meta["mass_flow_rate_g_s"] == 0.55


@pytest.mark.parametrize("content,word", [("movie,fps\n,250\n", "movie"), ("a,b\n1,2\n", "movie"),
                                          ("movie,fps\nx.avi,fast\n", "fps"), ("movie\n", "no runs"),
                                          ("run,movie\nx,a.avi\nx,b.avi\n", "repeat"),
                                          ('movie,roi\na.avi,"0,0,64"\n', "four pixel numbers"),
                                          ("movie,allow_truncated\na.avi,maybe\n", "true or false")])
def test_bad_manifests(tmp_path, content, word):
    p = tmp_path / "m.csv"
    p.write_text(content)
    with pytest.raises(ParameterError, match=word):
        read_manifest(p)


def test_a_column_that_looks_misspelt_is_warned_about(campaign_dir, tmp_path, capsys):
    """mm_per_pix was kept as metadata without a word and the run analysed with the tube's scale: it is said, as the
    run's warning, on the terminal and in campaign.csv; a name that extends a known one (group2) is its own."""
    import pandas as pd

    (campaign_dir / "typo.csv").write_text("run,movie,mm_per_pix,group2,Tube_Diameter_mm\n"
                                           "a,a/movie.avi,0.185,x,3\n")
    [spec] = read_manifest(campaign_dir / "typo.csv")
    assert spec.meta["mm_per_pix"] == "0.185" and spec.params.mm_per_px is None
    assert [w.split("'")[-2] for w in of_code(spec, "manifest.column_unknown")] == ["mm_per_px", "tube_diameter_mm"]
    assert len(spec.warnings) == 2
    code, _, err = run(capsys, "batch", campaign_dir / "typo.csv", "--out", tmp_path / "o", "--no-figures",
                       "--no-simulations")
    assert code == 0 and "warning: run a: column 'mm_per_pix' is not one grainplug knows" in err
    table = pd.read_csv(tmp_path / "o" / "campaign.csv")
    said = table.warnings[0].split(" | ")  # the manifest's doubts first, then the run's own
    assert table.warning_codes[0].split(" | ")[:2] == ["manifest.column_unknown"] * 2
    assert len(table.warning_codes[0].split(" | ")) == len(said) and "if it means 'mm_per_px'" in said[0]
    # from Python the campaign says it too, with the runs that failed
    (campaign_dir / "gone.csv").write_text("run,movie,mm_per_pix\na,a/movie.avi,0.185\nb,nowhere.avi,0.185\n")
    camp = run_campaign(campaign_dir / "gone.csv", tmp_path / "p", figures=False, simulate=False)
    assert camp.n_failed == 1
    assert any(w.startswith("run a: column 'mm_per_pix' is not one grainplug knows") for w in camp.warnings)
    assert any(w.startswith("run b failed: ") and "nowhere.avi" in w for w in camp.warnings), camp.warnings


def test_every_analysis_setting_is_a_manifest_column(tmp_path):
    """roi, allow_truncated and the detection thresholds reach the run's parameters (roi was kept as metadata, the
    run analysed on the whole frame), in CSV and in TOML; a column of one's own notes stays metadata."""
    (tmp_path / "m.csv").write_text('movie,roi,allow_truncated,min_gap_mm,sample_frames,operator\n'
                                    'a.tif,"0,0,64,640",yes,0.8,16,lab-3\n')
    (tmp_path / "m.toml").write_text('[defaults]\nallow_truncated = true\n[[run]]\nmovie = "a.tif"\n'
                                     'roi = [0, 0, 64, 640]\nmin_gap_mm = 0.8\nsample_frames = 16\n'
                                     'operator = "lab-3"\n')
    for name in ("m.csv", "m.toml"):
        [spec] = read_manifest(tmp_path / name)
        p = spec.params
        assert (p.roi, p.allow_truncated, p.min_gap_mm, p.sample_frames) == ((0, 0, 64, 640), True, 0.8, 16)
        assert spec.meta == {"operator": "lab-3"}


def test_batch_serial_cache_and_failures(campaign_dir, tmp_path, capsys):
    out = tmp_path / "out"
    camp = run_campaign(campaign_dir / "manifest.csv", out)
    t = camp.table
    # the model against the measured runs: linear and simulated predictions, sentences from the numbers
    report_text = (out / "report.html").read_text()
    assert "Model against experiment" in report_text and "this campaign, 3 mm pipe" in report_text
    panel = json.loads((out / "fits.json").read_text())["model_vs_experiment"]
    assert panel["measured"]["n_runs"] == 5 and panel["measured"]["celerity_max_m_s"] < 0
    assert any(q["nonlinear"] for q in panel["predictions"])
    assert panel["verdict"][0].startswith("Celerity: the measured plugs climb")
    assert (out / "model_vs_experiment.png").exists()
    assert list(t.status) == ["ok"] * 5
    assert t.celerity_m_s.to_numpy() == pytest.approx([-0.040, -0.054, -0.063, -0.052, -0.083], rel=0.02)
    assert set(camp.fits) == {"propagative/rough", "propagative/smooth", "all"}
    assert camp.fits["propagative/rough"]["celerity"]["n"] == 3
    assert list(t.scale_source) == ["user"] * 5 and list(t.scale_rel_sd) == [0.0] * 5
    report = (out / "report.html").read_text()
    assert "warnings" in t and "scale from" in report and "celerity (m/s)" in report
    tables = re.sub(r'(src="data:image/png;base64,|data-v=")[^"]*"', "", report.split("<details>")[0])
    # (the figures are base64 text, sort keys full precision, the provenance raw JSON: left out)
    assert 'href="runs/a/report.html"' in report  # each run links to its own report
    assert "nan" not in tables.lower() and not re.search(r"\d\.\d{6,}", tables)  # rounded, "—" when missing
    assert pd.read_parquet(out / "campaign.parquet").shape[0] == 5
    for name in ("campaign.csv", "fits.json", "report.html", "celerity_vs_mass_flow.png",
                 "length_vs_mass_flow.png", "runs/a/summary.json", "runs/a/report.html"):
        assert (out / name).exists(), name
    # rerun: nothing changed, nothing analysed again
    again = run_campaign(campaign_dir / "manifest.csv", out, simulate=False)
    assert list(again.table.status) == ["ok"] * 5 and again.n_reused == 5
    assert again.table.celerity_m_s.tolist() == t.celerity_m_s.tolist()
    # a changed parameter re-runs that run only; a missing movie fails alone
    m = (campaign_dir / "manifest.csv").read_text().splitlines()
    m[1] = m[1].replace("0.185", "0.19")
    m.append("z,missing.avi,0.3,40,rough,0.185,lab-3")
    (campaign_dir / "manifest2.csv").write_text("\n".join(m) + "\n")
    code, _, err = run(capsys, "batch", campaign_dir / "manifest2.csv", "--out", out, "--no-simulations")
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]  # one line per failed run, then the error
    assert code == 3 and len(lines) == 2 and "Traceback" not in err
    assert lines[0].startswith("failed: run z: ") and "missing.avi" in lines[0] and "check the movie column" in lines[0]
    assert lines[1].startswith("error: 1 of 6 runs failed, each named above")
    t3 = pd.read_csv(out / "campaign.csv")
    assert list(t3.status) == ["ok", "ok", "ok", "ok", "ok", "failed"]
    # typed columns under a versioned schema: a failed run's measures are missing, not "nan" text
    import pyarrow.parquet as pq_io

    from grainplug.campaigns.schema import SCHEMA_VERSION

    pq = pd.read_parquet(out / "campaign.parquet")
    assert str(pq.has_plugs.dtype) == "boolean" and str(pq.n_plugs.dtype) == "Int64"
    assert str(pq.celerity_m_s.dtype) == "Float64" and pq.celerity_m_s.isna().tolist()[-1]
    assert pq_io.read_schema(out / "campaign.parquet").metadata[b"grainplug_schema_version"] == b"1"
    schema = json.loads((out / "campaign.schema.json").read_text())
    assert schema["schema_version"] == SCHEMA_VERSION
    kinds = {c["name"]: c["dtype"] for c in schema["columns"]}
    assert kinds["celerity_m_s"] == "Float64" and kinds["operator"] != "Float64"  # manifest metadata as read


def test_batch_prints_each_runs_warnings(campaign_dir, tmp_path, capsys, monkeypatch):
    """A run's warnings reach the terminal as analyze's do (they were only in campaign.csv and the report: a
    frame rate ten times off went unsaid), the same sentence of several runs once naming them, at most
    MAX_RUN_WARNINGS lines and a count of the rest."""
    from grainplug.cli import campaigns as app

    (campaign_dir / "fast.csv").write_text("run,movie,mm_per_px,fps\na,a/movie.avi,0.185,5000\n"
                                           "b,b/movie.avi,0.185,5000\n")
    code, _, err = run(capsys, "batch", campaign_dir / "fast.csv", "--out", tmp_path / "o", "--no-figures",
                       "--no-simulations")
    said = [ln for ln in err.splitlines() if ln.startswith(("warning: run ", "warning: runs "))]
    assert code == 0 and [ln.split(":")[1] for ln in said if "frame rate given" in ln] == [" runs a, b"]
    monkeypatch.setattr(app, "MAX_RUN_WARNINGS", 1)
    code, _, err = run(capsys, "batch", campaign_dir / "fast.csv", "--out", tmp_path / "o", "--no-figures",
                       "--no-simulations")
    lines = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert lines[0].startswith("warning: runs a, b: ") and f"{len(said) - 1} more run warnings" in lines[1]
    code, out, err = run(capsys, "batch", campaign_dir / "fast.csv", "--out", tmp_path / "o", "--no-figures",
                         "--no-simulations", "--json")  # on stderr too, the JSON alone on stdout
    assert code == 0 and err.startswith("warning: runs a, b: ") and json.loads(out)["n_reused"] == 2


def test_batch_workers_match_serial(campaign_dir, tmp_path):
    a = run_campaign(campaign_dir / "manifest.toml", tmp_path / "s", figures=False).table
    b = run_campaign(campaign_dir / "manifest.toml", tmp_path / "p", workers=2, figures=False).table
    cols = ["run", "celerity_m_s", "plug_length_mm", "regime", "bubble_length_mm"]
    pd.testing.assert_frame_equal(a[cols], b[cols])


@pytest.mark.slow
def test_batch_on_dask_local_cluster(campaign_dir, tmp_path):
    distributed = pytest.importorskip("distributed")
    serial = run_campaign(campaign_dir / "manifest.csv", tmp_path / "s", figures=False).table
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        dist = run_campaign(campaign_dir / "manifest.csv", tmp_path / "d", scheduler=cluster.scheduler_address,
                            figures=False).table
    cols = ["run", "status", "celerity_m_s", "plug_length_mm", "regime", "oscillation_frequency_hz"]
    pd.testing.assert_frame_equal(serial[cols], dist[cols])


def test_scheduler_unreachable(campaign_dir, tmp_path, capsys):
    code, _, err = run(capsys, "batch", campaign_dir / "manifest.csv", "--out", tmp_path / "o",
                       "--scheduler", "tcp://127.0.0.1:9")
    assert_one_line_error(code, err, "scheduler")


def test_manifest_calibration_column(tmp_path):
    from test_calibrate import uniform_calibration

    import grainplug as gp

    (tmp_path / "cal").mkdir()
    gp.save_calibration(uniform_calibration(0.19), tmp_path / "cal" / "day1.json")
    (tmp_path / "m.csv").write_text("run,movie,calibration\na,a.avi,cal/day1.json\nb,b.avi,\n")
    a, b = read_manifest(tmp_path / "m.csv")
    assert a.params.calibration.mm_per_px == 0.19 and b.params.calibration is None
    assert "calibration" not in a.meta
    (tmp_path / "bad.csv").write_text("run,movie,calibration\na,a.avi,cal/missing.json\n")
    with pytest.raises(ParameterError, match=r"bad\.csv.*calibration: no such calibration file"):
        read_manifest(tmp_path / "bad.csv")


def test_paper_figures_for_print(tmp_path, capsys):
    """--publication: every figure of the reproduction as PNG (200 dpi), SVG and PDF."""
    code, _, err = run(capsys, "paper", "--out", tmp_path / "p", "--no-simulations", "--publication")
    assert code == 0, err
    pngs = sorted(p.stem for p in (tmp_path / "p").glob("*.png"))
    assert len(pngs) >= 7
    for stem in pngs:
        for ext in ("svg", "pdf"):
            assert (tmp_path / "p" / f"{stem}.{ext}").stat().st_size > 1000, (stem, ext)
    # without simulations the report does not describe simulations
    page = (tmp_path / "p" / "report.html").read_text()
    assert "No simulation was run" in page and "Simulated: grainplug.simulation" not in page


def test_runs_without_a_measured_direction_are_left_out_of_the_celerity_fit(tmp_path):
    """A run whose celerity's interval holds 0 and is far wider than the others' (a scene that is no plug
    train: +1.1 +- 1.2 m/s) would weigh in the least-squares line as much as the others: it is left out of the
    celerity fit, and said to be; its plug length still counts. A well-measured drift about 0 (f: 0.0002 +-
    0.001 m/s) is a measure and stays. A run without a mass flow rate is left out of every fit; a misnamed
    mass-flow column is said; no column at all is a campaign without fits, by choice."""
    from grainplug.campaigns.fits import ALL_RUNS, campaign_fits, fit_selection
    from grainplug.campaigns.report import campaign_report

    m = np.array([10.0, 20.0, 30.0, 25.0, np.nan, 0.02])
    c = -0.01 * m
    c[3], c[5] = 1.1, 0.0002
    tab = pd.DataFrame({"run": list("abcdef"), "movie": ["m"] * 6, "status": ["ok"] * 6,
                        "mass_flow_rate_g_s": m, "regime": ["propagative"] * 6, "group": ["g"] * 6,
                        "celerity_m_s": c, "celerity_ci95_low_m_s": c - 0.001, "celerity_ci95_high_m_s": c + 0.001,
                        "plug_length_mm": [30.0] * 6})
    tab.loc[3, ["celerity_ci95_low_m_s", "celerity_ci95_high_m_s"]] = [-0.1, 2.3]
    kept, why = fit_selection(tab)
    assert list(kept.run) == list("abcdf") and list(kept.run[kept.fit_celerity]) == list("abcf")
    assert why == {"d": "left out of the celerity fit: no direction of travel, its celerity's 95 % interval holds 0 "
                        "and is over 10 times wider than the campaign's",
                   "e": "left out of the fits: no mass flow rate in the manifest"}
    fits = campaign_fits(tab)
    assert fits["g"]["celerity"]["slope_m_s_per_g_s"] == pytest.approx(-0.01, abs=1e-4)
    assert fits["g"]["celerity_runs"] == list("abcf") and fits["g"]["runs"] == list("abcdf")
    page = campaign_report(tab, fits, tmp_path, [], {})
    assert "<b>d</b>: left out of the celerity fit: no direction of travel" in page
    misspelled = tab.rename(columns={"mass_flow_rate_g_s": "mass_flow_g_s"})
    assert fit_selection(misspelled)[1] == {ALL_RUNS: "the manifest has no mass_flow_rate_g_s column (is "
                                            "'mass_flow_g_s' meant? name it mass_flow_rate_g_s): nothing to fit the "
                                            "runs against"}
    assert fit_selection(tab.drop(columns="mass_flow_rate_g_s"))[1] == {}  # a campaign without fits, by choice
    # runs without plugs are left out without a word (a group of None, or "nan" from pandas' string columns)
    none = tab.assign(regime=["none"] * 6, group=[None] * 6, celerity_m_s=np.nan)
    assert all(w.endswith("no plugs measured") for w in fit_selection(none)[1].values() if "mass flow" not in w)


def test_the_fits_table_gives_each_value_to_its_uncertainty(tmp_path):
    """A slope known to 1.2e-6 is not printed "−0.0030 ± 0.0000": the error to two significant figures, the value
    to the same place; a group of one run has no spread ("—", not 0.00)."""
    from grainplug.campaigns.report import campaign_report

    tab = pd.DataFrame({"run": ["a"], "movie": ["m"], "status": ["ok"]})
    fits = {"A": {"celerity": {"slope_m_s_per_g_s": -0.0030015, "slope_stderr": 1.2e-6, "intercept_m_s": 0.02002,
                               "intercept_stderr": 1.15e-5, "r2": 1.0, "n": 3},
                  "length": {"mean_mm": 30.9, "sd_mm": 0.4, "mean_over_diameter": 10.3, "n": 3}},
            "B": {"celerity": None, "length": {"mean_mm": 30.94, "sd_mm": 0.0, "mean_over_diameter": 10.3, "n": 1}}}
    page = campaign_report(tab, fits, tmp_path, [], {})
    row_a = re.search(r"<tr><td>A</td>(.*?)</tr>", page).group(1)
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row_a)
    assert cells[:4] == ["−0.0030015", "0.0000012", "0.020020", "0.000012"]
    row_b = re.findall(r"<td[^>]*>(.*?)</td>", re.search(r"<tr><td>B</td>(.*?)</tr>", page).group(1))
    assert row_b[7] == "—"


def test_a_line_through_two_runs_claims_no_fit_quality():
    """Two runs give a line through them: the figure said "R² = 1.000" and listed a 95 % band it could not draw."""
    from grainplug.campaigns.fits import fit_line
    from grainplug.plotting.campaign import plot_vs_mass_flow

    x, y = np.array([0.4, 0.6]), np.array([-0.04, -0.06])
    fig = plot_vs_mass_flow({"g": (x, y)}, {"g": fit_line(x, y)}, ylabel="c", title="t")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any("line through 2 runs" in s for s in labels)
    assert not any("R²" in s or ("band" in s and "no band" not in s) for s in labels)


def test_the_report_gives_no_r2_for_a_line_through_two_runs(tmp_path):
    """The campaign report's fits table read "R² 1.000, n 2" with no caveat, as the terminal did."""
    from grainplug.campaigns.fits import fit_line
    from grainplug.campaigns.report import campaign_report

    tab = pd.DataFrame({"run": ["a", "b", "c", "d", "e"], "movie": ["m"] * 5, "status": ["ok"] * 5})
    two, three = fit_line(np.array([0.4, 0.6]), np.array([-0.04, -0.06])), fit_line(
        np.array([0.4, 0.5, 0.6]), np.array([-0.04, -0.051, -0.06]))
    fits = {g: {"celerity": f.as_dict(), "length": None} for g, f in (("two", two), ("three", three))}
    page = campaign_report(tab, fits, tmp_path, [], {})
    cells = {g: re.findall(r"<td[^>]*>(.*?)</td>", re.search(rf"<tr><td>{g}</td>(.*?)</tr>", page).group(1))
             for g in fits}
    assert cells["two"][4:6] == ["—", "2"] and cells["three"][4:6] == [f"{three.r2:.3f}", "3"]
    assert "<b>two</b>: a line through 2 runs fits them exactly" in page and "<b>three</b>:" not in page


def test_one_run_has_no_spread_to_state():
    """A group of one run states its length, not a spread: sd and interval are null (they read 0 and
    [L, L], an exactness no single run has); two runs give finite ones."""
    from grainplug.campaigns import summarize_lengths

    one = summarize_lengths(np.array([0.5]), np.array([33.36]), diameter_mm=3.0).as_dict()
    assert (one["mean_mm"], one["n"], one["sd_mm"], one["ci95_mm"]) == (33.36, 1, None, None)
    two = summarize_lengths(np.array([0.5, 0.6]), np.array([30.0, 34.0]), diameter_mm=3.0).as_dict()
    assert two["sd_mm"] > 0 and two["ci95_mm"][0] < 32.0 < two["ci95_mm"][1]


def test_a_batch_whose_every_run_failed_does_not_say_the_others_are_done(tmp_path, capsys):
    (tmp_path / "m.csv").write_text("run,movie\na,nope.tif\n")
    code, _, err = run(capsys, "batch", tmp_path / "m.csv", "--out", tmp_path / "o", "--no-figures",
                       "--no-simulations")
    assert code == 3 and "1 of 1 runs failed, each named above (none is done;" in err
    assert "no such file or folder — check the movie column" in err


def test_ctrl_c_after_the_runs_says_what_is_kept(campaign_dir, tmp_path, monkeypatch):
    """Ctrl-C while the fits and the report are written said only "interrupted": it says the runs are kept and
    that the same command writes the rest."""
    from grainplug.campaigns import batch
    from grainplug.errors import CampaignInterrupted

    (campaign_dir / "one.csv").write_text("run,movie,mm_per_px\na,a/movie.avi,0.185\n")

    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "campaign_fits", stop)
    with pytest.raises(CampaignInterrupted, match=r"1 of 1 runs have a complete result, kept.*run the same command"):
        run_campaign(campaign_dir / "one.csv", tmp_path / "o", figures=False, simulate=False)
    monkeypatch.undo()
    again = run_campaign(campaign_dir / "one.csv", tmp_path / "o", figures=False, simulate=False)
    assert again.n_reused == 1 and (tmp_path / "o" / "campaign.csv").is_file()


def test_run_folders_left_by_removed_rows_are_pointed_out(campaign_dir, tmp_path, capsys):
    """A row taken out of the manifest leaves its run's folder: kept (it is the user's data), said once."""
    (campaign_dir / "two.csv").write_text("run,movie,mm_per_px\na,a/movie.avi,0.185\nb,b/movie.avi,0.185\n")
    (campaign_dir / "one_a.csv").write_text("run,movie,mm_per_px\na,a/movie.avi,0.185\n")
    out = tmp_path / "o"
    assert run_campaign(campaign_dir / "two.csv", out, figures=False, simulate=False).stale_runs == ()
    code, _, err = run(capsys, "batch", campaign_dir / "one_a.csv", "--out", out, "--no-figures", "--no-simulations")
    assert code == 0 and "1 run folder(s) under" in err and "(b): kept, but left out of the campaign" in err
    assert (out / "runs" / "b" / "summary.json").is_file()


def test_a_two_run_fit_printed_says_its_r2_means_nothing(campaign_dir, tmp_path, capsys):
    """The smooth group has two runs: the terminal printed "R² 1.000, n 2" as if the line fitted well."""
    code, out, err = run(capsys, "batch", campaign_dir / "manifest.csv", "--out", tmp_path / "o", "--no-figures",
                         "--no-simulations")
    assert code == 0, err
    smooth = next(line for line in out.splitlines() if line.strip().startswith("propagative/smooth"))
    assert "R² 1" not in smooth and "a line through 2 runs fits them exactly" in smooth
    rough = next(line for line in out.splitlines() if line.strip().startswith("propagative/rough"))
    assert "R² " in rough and "n 3" in rough and "few runs" in rough


def test_a_misspelt_column_is_said_once_for_all_runs(campaign_dir, tmp_path, capsys):
    """A misspelt column in a manifest of several runs was said once per run (7 lines for 7 runs)."""
    (campaign_dir / "typo3.csv").write_text("run,movie,mm_per_pix\na,a/movie.avi,0.185\nb,b/movie.avi,0.185\n"
                                            "c,c/movie.avi,0.185\n")
    code, _, err = run(capsys, "batch", campaign_dir / "typo3.csv", "--out", tmp_path / "o", "--no-simulations")
    assert code == 0, err
    said = [line for line in err.splitlines() if "mm_per_pix" in line]
    assert len(said) == 1 and said[0].startswith("warning: runs a, b, c: column 'mm_per_pix'"), err
    # the campaign's report too: once for the three runs, and with the command line's option beside the
    # library's keyword (the tube model's warning named tube_outer_diameter_mm= alone, once per run)
    page = re.sub(r"<[^>]+>", "", (tmp_path / "o" / "report.html").read_text())  # the text read
    assert page.count("column &#x27;mm_per_pix&#x27;") == 1
    assert page.count("tube_outer_diameter_mm=") == page.count("tube_outer_diameter_mm= (--tube-outer-diameter-mm)")
    assert page.count("(--tube-outer-diameter-mm)") == 1


def test_the_paper_s_celerity_figure_keeps_the_sign_of_its_table(tmp_path):
    """celerity_propagative.png plotted |v_p| with a slope of +0.091 beside a table saying -0.0906."""
    import matplotlib.pyplot as plt

    from grainplug.campaigns.paper import reproduce
    from grainplug.campaigns.paper_outputs import celerity_figure

    rep = reproduce(simulate=False)
    fig = celerity_figure(rep, "propagative")
    slope = next(float(re.search(r"slope ([+-][\d.e-]+)", t.get_text()).group(1))
                 for t in fig.axes[0].get_legend().get_texts() if "slope" in t.get_text())
    plt.close(fig)
    g = "propagative/rough"  # the first group's fit is the legend's first slope
    assert rep.fits[g].slope < 0 and slope == pytest.approx(rep.fits[g].slope, rel=1e-3)
