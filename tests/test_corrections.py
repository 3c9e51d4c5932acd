"""A reviewer's corrections: measures recomputed from the detected plugs, kept, reapplied, honoured by batch."""

from __future__ import annotations

import json

import numpy as np
import pytest
from warned import codes, of_code

import grainplug as gp
from grainplug.cli import main
from grainplug.corrections import Corrections, apply_corrections
from grainplug.errors import ParameterError
from grainplug.synthetic import SynthConfig, synthesize

CELERITY = -0.05


@pytest.fixture(scope="module")
def movie(tmp_path_factory):
    return synthesize(SynthConfig(n_frames=160, seed=5, fps=250.0, celerity_m_s=CELERITY),
                      tmp_path_factory.mktemp("m"), fmt="tiff")


@pytest.fixture(scope="module")
def result(movie):
    return gp.analyze(movie.movie)


def _measures(res):
    return (res.celerity_m_s, res.plug_length_mm, res.lengths.bubble_length_mm if res.lengths else None,
            res.motion.regime if res.motion else None, len(res.runs))


def test_excluding_a_track_removes_it_and_restoring_gives_the_detection_back(result):
    tid = int(result.tracks.sort_values("n_frames").plug_id.iloc[-1])  # the longest-lived plug
    ex = apply_corrections(result, Corrections().add("exclude", track=tid))
    assert tid not in set(ex.edges.plug_id)
    assert len(ex.runs) < len(result.runs)
    assert ex.motion.n_edges < result.motion.n_edges
    assert ex.summary["corrections"] == [f"excluded track {tid}"]
    back = apply_corrections(ex, ex.corrections.add("restore", track=tid))
    assert _measures(back) == _measures(result)


def test_corrections_start_from_the_detection_every_time(result):
    a = Corrections().add("exclude", track=0)
    once = apply_corrections(result, a)
    twice = apply_corrections(once, a)
    assert _measures(once) == _measures(twice)
    assert apply_corrections(once, Corrections()).celerity_m_s == result.celerity_m_s


def test_split_then_merge_back_is_the_detection(result):
    t = result.tracks.sort_values("n_frames").iloc[-1]
    tid, mid = int(t.plug_id), int((t.first_frame + t.last_frame) // 2)
    split = apply_corrections(result, Corrections().add("split", track=tid, frame=mid))
    new = int(split.links.run_track.max())
    assert new == len(result.links) and {tid, new} <= set(split.edges.plug_id)
    assert split.edges[split.edges.plug_id == new].frame.min() == mid
    tracks = split.tracks.set_index("plug_id")  # each part says it was cut (the first said "end")
    assert tracks.loc[tid, "ended_by"] == "cut" and tracks.loc[new, "started_by"] == "cut"
    assert not tracks.loc[tid, "composite"] and not tracks.loc[new, "composite"]
    merged = apply_corrections(result, split.corrections.add("merge", track=tid, other=new))
    assert _measures(merged) == _measures(result)
    assert merged.tracks.set_index("plug_id").loc[tid, "ended_by"] == result.tracks.set_index("plug_id").loc[
        tid, "ended_by"]  # whole again


def test_a_time_window_and_spans_without_plugs(result):
    t_end = float(result.diagram.time_s[-1])
    late = apply_corrections(result, Corrections().add("window", start_s=0.4 * t_end))
    assert late.edges.time_s.min() >= 0.4 * t_end
    assert late.celerity_m_s == pytest.approx(CELERITY, rel=0.03)  # the truth, from fewer frames
    gap = apply_corrections(result, Corrections().add("no_plugs", start_s=0.2 * t_end, end_s=0.5 * t_end))
    assert not ((gap.edges.time_s >= 0.2 * t_end) & (gap.edges.time_s <= 0.5 * t_end)).any()
    none = apply_corrections(result, Corrections().add("no_plugs", start_s=0.0, end_s=t_end))
    assert not none.has_plugs and none.celerity_m_s is None
    assert "no plugs left after the corrections" in none.statement
    cleared = apply_corrections(result, none.corrections.add("clear_no_plugs"))
    assert _measures(cleared) == _measures(result)
    # from the emptied result itself (as remeasure does from its folder): the plugs come back
    again = apply_corrections(none, Corrections())
    assert again.has_plugs and _measures(again) == _measures(result) and again.statement == result.statement


@pytest.fixture(scope="module")
def joined(tmp_path_factory):
    """Plugs that merge: tracks 0 and 1 end by a merge at frame 169, track 3 starts by it (composite), track 2
    enters at frame 60 and lasts to the end."""
    movie = synthesize(SynthConfig(n_frames=200, fps=250.0, merge_split=True, seed=0), tmp_path_factory.mktemp("j"),
                       fmt="tiff")
    return gp.analyze(movie.movie)


def _ends(res, tid):
    row = res.tracks.set_index("plug_id").loc[tid]
    return row.started_by, row.ended_by, bool(row.composite)


def test_a_reviewer_s_cut_is_said_where_it_is_whatever_follows(joined):
    """Each part of a split says "cut" where it was cut and keeps the detected beginning or ending elsewhere,
    whatever is done to the other part (excluded, windowed away) and whichever way it is merged back."""
    assert _ends(joined, 2) == ("entered", "end", False)
    split = Corrections().add("split", track=2, frame=100, on=joined)
    new = len(joined.links)
    cut = apply_corrections(joined, split)
    assert _ends(cut, 2) == ("entered", "cut", False) and _ends(cut, new) == ("cut", "end", False)
    gone = apply_corrections(joined, split.add("exclude", track=new, on=joined))
    assert _ends(gone, 2)[1] == "cut"  # its later part excluded: it was cut all the same
    for a, b in ((2, new), (new, 2)):  # merged back either way: whole again
        back = apply_corrections(joined, split.add("merge", track=a, other=b, on=joined))
        assert _ends(back, a) == ("entered", "end", False)
        assert _measures(back) == _measures(joined)
    # a part cut off a track that begins by the tracker's merge keeps it, and stays composite
    three = apply_corrections(joined, Corrections().add("split", track=3, frame=185, on=joined))
    assert _ends(three, 3) == ("merge", "cut", True) and _ends(three, new) == ("cut", "end", False)


def test_two_plugs_seen_together_are_not_merged(result):
    """Merging two tracks seen in the same frames made one track of two plugs (two rows a frame, a celerity of
    neither): refused when made on the analysis, and not applied (with a warning) from a file."""
    e = result.edges
    frames = {tid: set(g.frame) for tid, g in e.groupby("plug_id")}
    a, b = next((x, y) for x in frames for y in frames if x < y and frames[x] & frames[y])
    with pytest.raises(ParameterError, match=rf"merge: tracks {a} and {b} are both seen in \d+ frames"):
        Corrections().add("merge", track=a, other=b, on=result)
    by_hand = apply_corrections(result, Corrections().add("merge", track=a, other=b))  # no trace: replayed by number
    assert _measures(by_hand) == _measures(result)
    [note] = of_code(by_hand, "corrections.not_applied")
    assert f"tracks {a} and {b} are both seen in" in note, by_hand.warnings


def test_start_here_then_end_here_keep_the_frames_between(result):
    """The review page's two clicks make two window edits, each naming one end: together they keep the frames
    between them (the second used to replace the first, keeping the start-up transient the report said was cut);
    a later edit moves one end back, a window without ends keeps the whole record, an end before the start is
    not applied and said."""
    t_end = float(result.diagram.time_s[-1])
    a, b = 0.2 * t_end, 0.8 * t_end
    two = apply_corrections(result, Corrections().add("window", start_s=a).add("window", end_s=b))
    one = apply_corrections(result, Corrections().add("window", start_s=a, end_s=b))
    assert two.edges.time_s.min() >= a and two.edges.time_s.max() <= b
    assert _measures(two) == _measures(one)
    assert two.summary["corrections"] == [f"kept the frames from {a:g} s on", f"kept the frames up to {b:g} s"]
    assert two.summary["kept_window_s"] == [pytest.approx(a), pytest.approx(b)]  # n_frames is the record's
    assert result.summary["kept_window_s"] == [result.diagram.time_s[0], pytest.approx(t_end)]
    wider = apply_corrections(result, two.corrections.add("window", start_s=0.1 * t_end))
    assert wider.edges.time_s.min() < a and wider.edges.time_s.max() <= b
    whole = apply_corrections(result, two.corrections.add("window"))
    assert _measures(whole) == _measures(result)
    crossed = apply_corrections(result, two.corrections.add("window", start_s=0.9 * t_end))
    assert _measures(crossed) == _measures(two)
    [note] = of_code(crossed, "corrections.not_applied")
    assert f"it would end the window ({b:g} s) before it starts ({0.9 * t_end:g} s)" in note, crossed.warnings


def test_a_run_emptied_by_its_corrections_comes_back_when_they_go(result, tmp_path, capsys):
    """Saved with corrections that leave no plugs, then the corrections file removed: remeasure gives the
    detection's measures back (the emptied result is not the new detection)."""
    t_end = float(result.diagram.time_s[-1])
    out = tmp_path / "run"
    apply_corrections(result, Corrections().add("no_plugs", start_s=0.0, end_s=t_end)).save(out, figures=False)
    assert json.loads((out / "summary.json").read_text())["has_plugs"] is False
    (out / "corrections.json").unlink()
    assert main(["remeasure", str(out), "--no-figures"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["has_plugs"] is True and summary["celerity_m_s"] == pytest.approx(result.celerity_m_s, abs=1e-6)


def test_corrections_are_checked_and_read_back():
    c = Corrections().add("exclude", track=2, at="2026-11-25T10:00:00+00:00").add("window", start_s=0.1)
    assert Corrections.from_dict(json.loads(json.dumps(c.as_dict()))) == c
    with pytest.raises(ParameterError, match="unknown correction 'delete'"):
        Corrections().add("delete", track=1)
    with pytest.raises(ParameterError, match="merge needs other"):
        Corrections().add("merge", track=1)
    with pytest.raises(ParameterError, match="must come after the start"):
        Corrections().add("no_plugs", start_s=2.0, end_s=1.0)
    with pytest.raises(ParameterError, match="newer"):
        Corrections.from_dict({"format": "grainplug-corrections", "format_version": 99, "edits": []})
    with pytest.raises(ParameterError, match="edit 1"):
        Corrections.from_dict({"format": "grainplug-corrections", "format_version": 1, "edits": [{"track": 1}]})


def test_saved_with_corrections_loaded_back_and_reported(result, tmp_path):
    from test_api import assert_same

    fixed = apply_corrections(result, Corrections().add("exclude", track=0))
    fixed.save(tmp_path / "run", figures=False)
    again = gp.load_result(tmp_path / "run")
    assert_same(fixed, again)
    saved = json.loads((tmp_path / "run" / "corrections.json").read_text())
    assert saved["format"] == "grainplug-corrections" and saved["edits"][0]["action"] == "exclude"
    assert "Corrections applied (1)" in (tmp_path / "run" / "report.html").read_text()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["corrections"] == ["excluded track 0"]


def test_remeasure_command_reapplies_the_file(result, tmp_path, capsys):
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    before = json.loads((out / "summary.json").read_text())
    (out / "corrections.json").write_text(json.dumps(Corrections().add("exclude", track=0).as_dict()))
    assert main(["remeasure", str(out), "--no-figures"]) == 0
    stdout = capsys.readouterr().out
    assert "1 applied: excluded track 0" in stdout
    after = json.loads((out / "summary.json").read_text())
    assert after["n_edges_used"] < before["n_edges_used"]
    (out / "corrections.json").unlink()
    assert main(["remeasure", str(out), "--no-figures"]) == 0
    restored = json.loads((out / "summary.json").read_text())
    assert restored["celerity_m_s"] == before["celerity_m_s"] and restored["corrections"] == []


def test_a_bad_corrections_file_is_one_line_and_changes_nothing(result, tmp_path, capsys):
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    before = (out / "summary.json").read_bytes()
    (out / "corrections.json").write_text('{"format": "grainplug-corrections", "format_version": 1, '
                                          '"edits": [{"action": "explode"}]}')
    assert main(["remeasure", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "corrections.json" in err and "explode" in err
    assert (out / "summary.json").read_bytes() == before


def test_batch_honours_each_runs_corrections(movie, tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,surface\na,{movie.movie},0.5,rough\n")
    out = tmp_path / "camp"
    first = gp.run_campaign(manifest, out, figures=False)
    run_summary = out / "runs" / "a" / "summary.json"
    n0 = json.loads(run_summary.read_text())["n_edges_used"]
    assert first.table.n_corrections.tolist() == [0]
    (out / "runs" / "a" / "corrections.json").write_text(
        json.dumps(Corrections().add("exclude", track=0).as_dict()))
    second = gp.run_campaign(manifest, out, figures=False)
    assert second.n_reused == second.n_remeasured == 1  # measured again from the saved detection, not analysed
    assert second.table.n_corrections.tolist() == [1]
    summary = json.loads(run_summary.read_text())
    assert summary["n_edges_used"] < n0
    assert summary["corrections"] == ["excluded track 0"] and summary["batch"]["run"] == "a"
    third = gp.run_campaign(manifest, out, figures=False)  # nothing changed: plain reuse
    assert third.n_reused == 1 and third.n_remeasured == 0
    assert third.table.celerity_m_s.tolist() == second.table.celerity_m_s.tolist()
    assert np.isfinite(third.table.celerity_m_s.iloc[0])
    (out / "runs" / "a" / "corrections.json").write_text(json.dumps(Corrections().as_dict()))
    assert main(["batch", str(manifest), "--out", str(out), "--no-figures", "--json"]) == 0
    said = json.loads(capsys.readouterr().out)  # the command line's JSON says the same
    assert (said["n_reused"], said["n_remeasured"], said["left_out_of_fits"]) == (1, 1, {})


def test_batch_redraws_a_reused_runs_figures_when_their_options_change(movie, tmp_path):
    """A reused run whose figures were written otherwise (the default, then --publication) has them redrawn
    from the saved result, without reading the movie: it is not counted as measured again."""
    from grainplug.outputs import PUBLICATION

    manifest = tmp_path / "m.csv"
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,surface\na,{movie.movie},0.5,rough\n")
    out = tmp_path / "camp"
    run_dir = out / "runs" / "a"
    gp.run_campaign(manifest, out, simulate=False)
    assert {p.name for p in run_dir.glob("diagram.*")} == {"diagram.npz", "diagram.tif", "diagram.png"}
    again = gp.run_campaign(manifest, out, figure_options=PUBLICATION, simulate=False)
    assert again.n_reused == 1 and again.n_remeasured == 0
    assert {p.name for p in run_dir.glob("diagram.*")} == {"diagram.npz", "diagram.tif", "diagram.png", "diagram.svg",
                                                            "diagram.pdf"}
    written = (run_dir / "summary.json").stat().st_mtime_ns
    third = gp.run_campaign(manifest, out, figure_options=PUBLICATION, simulate=False)  # the same: nothing rewritten
    assert third.n_reused == 1 and (run_dir / "summary.json").stat().st_mtime_ns == written
    assert json.loads((run_dir / "summary.json").read_text())["figures"]["formats"] == ["png", "svg", "pdf"]


def test_batch_keeps_a_reused_runs_metadata_current(movie, tmp_path):
    """A manifest's metadata corrected after a batch (a mass flow rate mistyped) reaches the reused run's own
    summary.json, not only the campaign's table; the movie is not read again."""
    manifest = tmp_path / "m.csv"
    out = tmp_path / "camp"
    summary = out / "runs" / "a" / "summary.json"
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,surface\na,{movie.movie},0.5,rough\n")
    gp.run_campaign(manifest, out, figures=False, simulate=False)
    assert json.loads(summary.read_text())["batch"]["meta"]["mass_flow_rate_g_s"] == 0.5
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,surface\na,{movie.movie},0.45,rough\n")
    again = gp.run_campaign(manifest, out, figures=False, simulate=False)
    assert again.n_reused == 1 and again.n_remeasured == 0
    assert again.table.mass_flow_rate_g_s.tolist() == [0.45]
    assert json.loads(summary.read_text())["batch"]["meta"]["mass_flow_rate_g_s"] == 0.45
    written = summary.stat().st_mtime_ns
    assert gp.run_campaign(manifest, out, figures=False, simulate=False).n_reused == 1
    assert summary.stat().st_mtime_ns == written  # unchanged: plain reuse
    assert not (out / "runs" / "a" / "corrections.json").exists()  # no empty corrections file made up


def test_a_metadata_change_in_a_batch_without_figures_keeps_the_run_s_figures(movie, tmp_path):
    manifest = tmp_path / "m.csv"
    out = tmp_path / "camp"
    run_dir = out / "runs" / "a"
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,operator\na,{movie.movie},0.5,alice\n")
    gp.run_campaign(manifest, out, simulate=False)
    drawn = {p.name for p in run_dir.iterdir()}
    assert {"diagram.png", "frame.png", "report.html"} <= drawn
    manifest.write_text(f"run,movie,mass_flow_rate_g_s,operator\na,{movie.movie},0.5,bob\n")
    gp.run_campaign(manifest, out, figures=False, simulate=False)
    assert {p.name for p in run_dir.iterdir()} == drawn  # nothing deleted, nothing added
    assert json.loads((run_dir / "summary.json").read_text())["batch"]["meta"]["operator"] == "bob"


def test_batch_says_when_edits_without_traces_meet_a_new_analysis_until_they_go(movie, tmp_path):
    """Edits saved without where their tracks were (format 1) are replayed by number on a re-analysis, with a
    warning; the warning stays through later remeasures while such edits remain, and goes with them."""
    out = tmp_path / "camp"
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"run,movie\na,{movie.movie}\n")
    gp.run_campaign(manifest, out, figures=False)
    corr_file = out / "runs" / "a" / "corrections.json"
    corr_file.write_text(json.dumps({"format": "grainplug-corrections", "format_version": 1,
                                     "edits": [{"action": "exclude", "track": 0, "at": ""}]}))

    def warned() -> list[str]:
        return of_code(json.loads((out / "runs" / "a" / "summary.json").read_text()), "corrections.unchecked")

    gp.run_campaign(manifest, out, figures=False)  # same analysis: measured again, nothing to check
    assert warned() == []
    manifest.write_text(f"run,movie,start_frame\na,{movie.movie},2\n")  # parameters changed: analysed again
    again = gp.run_campaign(manifest, out, figures=False)
    assert again.n_reused == 0
    [note] = warned()
    assert note.split(": ")[1].startswith("1 edit(s)")
    later = json.loads(corr_file.read_text())  # one more edit, with its trace: still one edit unchecked
    later["edits"].append({"action": "window", "start_s": 0.0, "at": ""})
    corr_file.write_text(json.dumps(later))
    gp.run_campaign(manifest, out, figures=False)
    assert len(warned()) == 1
    corr_file.write_text(json.dumps(Corrections().as_dict()))  # the reviewer removed the edits
    cleared = gp.run_campaign(manifest, out, figures=False)
    assert cleared.n_reused == 1 and warned() == []


def test_an_edit_replayed_on_another_analysis_never_falls_on_another_plug(movie, result):
    """Edits keep where their tracks were: replayed on a re-analysis whose tracker numbered the
    plugs otherwise, an edit whose track is now another plug is not applied, and a warning says so;
    on a re-analysis of another window, the same plug keeps the edit."""
    rows = result.tracks.set_index("plug_id")
    short = int(rows.median_length_mm.idxmin())  # the shorter of the two whole plugs
    corr = Corrections().add("exclude", track=short, on=result)
    trace = corr.edits[0].track_trace
    assert trace[0][0] == pytest.approx(rows.first_time_s[short])
    same = apply_corrections(gp.analyze(movie.movie), corr)  # the same analysis again: the edit applies
    assert short not in set(same.links.run_track) and "corrections.not_applied" not in codes(same)
    # a larger --min-plug-mm drops the shorter plug: the tracker gives its number to another plug
    fewer = gp.analyze(movie.movie, min_plug_mm=float(rows.median_length_mm[short]) + 1)
    assert short in set(fewer.links.run_track), "the number is not reused: the test shows nothing"
    applied = apply_corrections(fewer, corr)
    assert len(applied.runs) == len(fewer.runs)  # nothing excluded: that number is another plug here
    [note] = of_code(applied, "corrections.not_applied")
    assert f"excluded track {short}" in note and "was not applied" in note
    again = apply_corrections(applied, corr)  # replaying again does not repeat the warning
    assert of_code(again, "corrections.not_applied") == [note]
    # another window of the same movie: the plug that entered late is excluded there too
    late = int(rows.first_time_s.idxmax())
    corr_late = Corrections().add("exclude", track=late, on=result)
    window = apply_corrections(gp.analyze(movie.movie, start_frame=100), corr_late)
    assert late not in set(window.links.run_track) and "corrections.not_applied" not in codes(window)
    # the file keeps the traces (format 2) and reads back; format 1 files (no traces) are replayed as they are
    back = Corrections.from_dict(json.loads(json.dumps(corr.as_dict())))
    assert back == corr and corr.as_dict()["format_version"] == 2
    old = Corrections.from_dict({"format": "grainplug-corrections", "format_version": 1,
                                 "edits": [{"action": "exclude", "track": short, "at": ""}]})
    assert short not in set(apply_corrections(fewer, old).links.run_track)
    with pytest.raises(ParameterError, match="no track 999"):
        Corrections().add("exclude", track=999, on=result)


def test_edits_replayed_on_another_window_keep_their_plug_and_their_time(movie, result):
    """A split is kept by its time (another window numbers the frames otherwise); a window that
    holds only the middle of a plug's life still finds the plug; a restore may name a track left
    without plugs."""
    rows = result.tracks.set_index("plug_id")
    tid = int(rows.n_frames.idxmax())  # a plug seen over the whole movie
    corr = Corrections().add("split", track=tid, frame=130, on=result)
    t_split = float(result.diagram.time_s[130])
    assert corr.edits[0].frame_time_s == pytest.approx(t_split)
    later = gp.analyze(movie.movie, start_frame=20)
    after = apply_corrections(later, corr)
    assert "corrections.not_applied" not in codes(after), after.warnings
    new_id = int(after.links.run_track.max())
    new_first = after.diagram.time_s[after.runs.frame[after.links.run_track == new_id]].min()
    assert new_first == pytest.approx(t_split)  # cut at 0.52 s, not at the window's frame 130
    middle = gp.analyze(movie.movie, start_frame=84, end_frame=156)  # between the ends of every track
    ex = Corrections().add("exclude", track=tid, on=result)
    kept = apply_corrections(middle, ex)
    assert "corrections.not_applied" not in codes(kept), kept.warnings
    assert len(kept.runs) < len(middle.runs)  # the plug was found and excluded there too
    # a track emptied by a split at its first frame can still be restored from the page
    first = int(result.runs.frame[result.links.run_track == tid].min())
    emptied = Corrections().add("exclude", track=tid, on=result).add("split", track=tid, frame=first, on=result)
    emptied.add("restore", track=tid, on=apply_corrections(result, emptied))
    with pytest.raises(ParameterError, match="outside the analysis"):
        Corrections().add("split", track=tid, frame=10_000, on=result)


def test_edits_that_name_nothing_are_said_not_applied(result):
    """Written by hand: a track that does not exist and a frame outside the analysis are left out, with a
    warning that says why, not reported as applied. A window after the record's end is applied (what it cuts
    away stays cut: no plugs are left) and said."""
    t_end = float(result.diagram.time_s[-1])
    n_tracks = len(result.links)
    corr = Corrections().add("exclude", track=n_tracks + 5).add("split", track=0, frame=10**6)
    res = apply_corrections(result, corr)
    assert _measures(res) == _measures(result)
    notes = of_code(res, "corrections.not_applied")
    assert len(notes) == 2, res.warnings
    assert f"there is no track {n_tracks + 5}" in notes[0]
    assert "frame 1000000 is outside this analysis" in notes[1]
    assert res.summary["corrections"] == []  # none applied (the file's edits stay in corrections_applied)
    late = apply_corrections(result, corr.add("window", start_s=t_end + 5.0))
    assert not late.has_plugs and late.summary["corrections"] == [f"kept the frames from {t_end + 5.0:g} s on"]
    said = of_code(late, "corrections.not_applied")  # the two above, and the window that holds none
    assert len(said) == 3 and "edit 3, " in said[2] and "holds none of this record" in said[2], late.warnings


def test_a_restore_may_name_a_track_a_split_emptied(result):
    """Exclude a track, split it at its first frame (every plug moves to the new track), restore it: the
    restore is applied (the review page offers it), nothing is left excluded, no warning."""
    t = result.tracks.sort_values("n_frames").iloc[-1]
    tid, first = int(t.plug_id), int(t.first_frame)
    corr = Corrections().add("exclude", track=tid).add("split", track=tid, frame=first).add("restore", track=tid)
    res = apply_corrections(result, corr)
    assert "corrections.not_applied" not in codes(res), res.warnings
    assert len(res.summary["corrections"]) == 3 and len(res.runs) == len(result.runs)


@pytest.mark.parametrize(("edit", "says"), [
    ({"action": "exclude", "track": 3.7}, "track must be a whole number"),
    ({"action": "exclude", "track": True}, "track must be a whole number"),
    ({"action": "exclude", "track": "3"}, "track must be a whole number"),
    ({"action": "merge", "track": 1, "other": False}, "other must be a whole number"),
    ({"action": "split", "track": 1, "frame": 10.5}, "frame must be a whole number"),
    ({"action": "window", "start_s": "0.5s"}, "start_s must be a finite time in seconds"),
    ({"action": "no_plugs", "start_s": 0.1, "end_s": True}, "end_s must be a finite time in seconds"),
    ({"action": "exclude", "track": 1, "track_trace": [[0.1, True]]}, "track_trace must be a list"),
])
def test_a_malformed_edit_is_refused_not_reinterpreted(result, tmp_path, capsys, edit, says):
    """3.7 used to exclude track 3, true track 1; "0.5s" crashed with a bare ValueError (exit 1, "report it"). Each
    is now one line naming the file, the edit and the fix (exit 2), from the API a ParameterError, and nothing
    is written."""
    args = {k: v for k, v in edit.items() if k != "action"}
    with pytest.raises(ParameterError, match=says):
        Corrections().add(edit["action"], **args)
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    before = (out / "summary.json").read_bytes()
    (out / "corrections.json").write_text(json.dumps(
        {"format": "grainplug-corrections", "format_version": 2, "edits": [{"action": "window"}, edit]}))
    assert main(["remeasure", str(out), "--no-figures"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "corrections.json: edit 2: " in err[0], err
    assert says in err[0] and "report it" not in err[0]
    assert (out / "summary.json").read_bytes() == before


def test_whole_floats_are_track_numbers():
    assert Corrections().add("exclude", track=3.0).edits[0].track == 3


@pytest.mark.parametrize("version", ["2", True, 0, 1.5, None])
def test_a_malformed_format_version_is_not_called_newer(version):
    """"format_version": "2" used to be "newer than this grainplug reads (2)"."""
    with pytest.raises(ParameterError, match="format_version\" must be a whole number from 1 to 2") as err:
        Corrections.from_dict({"format": "grainplug-corrections", "format_version": version, "edits": []})
    assert "newer" not in str(err.value)
    with pytest.raises(ParameterError, match=r"format 3 is newer than this grainplug reads \(up to 2\)"):
        Corrections.from_dict({"format": "grainplug-corrections", "format_version": 3, "edits": []})


@pytest.mark.parametrize("name", [".", "./"])
def test_remeasure_inside_the_result_folder(result, tmp_path, capsys, monkeypatch, name):
    """`grainplug remeasure .` used to be refused ("the output folder is the current folder"). It rewrites the
    folder by its absolute path, leaves nothing beside it, and tells the shell (left in the old, removed folder)
    how to see the new one; the library never changes the working directory."""
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    (out / "corrections.json").write_text(json.dumps(Corrections().add("exclude", track=0).as_dict()))
    monkeypatch.chdir(out)
    assert main(["remeasure", name, "--no-figures"]) == 0
    captured = capsys.readouterr()
    assert "1 applied: excluded track 0" in captured.out
    assert "`cd .`" in captured.err
    assert json.loads((out / "summary.json").read_text())["corrections"] == ["excluded track 0"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary or old folder left
    monkeypatch.chdir(out)  # the user's `cd .`: the library leaves the working directory alone
    assert main(["remeasure", name, "--no-figures"]) == 0  # and again, from the new folder


def test_remeasure_keeps_what_the_lab_put_in_the_folder(result, tmp_path, capsys):
    """A run folder holding a user's notes (a file, a folder) used to be refused by remeasure ("move it out
    first"). remeasure rewrites the same analysis: the notes stay, remeasure after remeasure, and stay the
    user's (not listed as grainplug's, so a new analysis there still refuses to delete them)."""
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    (out / "notes.txt").write_text("lamp flickered at 0.3 s")
    (out / "mine").mkdir()
    (out / "mine" / "sketch.txt").write_text("x")
    for _ in range(2):
        assert main(["remeasure", str(out), "--no-figures"]) == 0
        assert (out / "notes.txt").read_text() == "lamp flickered at 0.3 s"
        assert (out / "mine" / "sketch.txt").read_text() == "x"
    listed = json.loads((out / ".grainplug").read_text())["files"]
    assert "notes.txt" not in listed and not any(f.startswith("mine") for f in listed)
    from grainplug._atomic import is_complete

    assert is_complete(out)
    movie = result.input["path"]
    assert main(["analyze", movie, "--out", str(out), "--overwrite", "--no-figures"]) == 2
    assert "notes.txt" in capsys.readouterr().err


def test_remeasure_says_the_edits_it_did_not_apply(result, tmp_path, capsys):
    """remeasure used to print only "corrections 0 applied" (the reason in summary.json alone), and "1 applied"
    for a window outside the record that summary.json said holds none of it. Its warnings are printed as
    analyze prints them, and the count says what was not applied and what left no plugs."""
    out = tmp_path / "run"
    result.save(out, figures=False, report=False)
    t_end = float(result.diagram.time_s[-1])
    corr = Corrections().add("exclude", track=len(result.links) + 5).add("exclude", track=0)
    (out / "corrections.json").write_text(json.dumps(corr.as_dict()))
    assert main(["remeasure", str(out), "--no-figures"]) == 0
    captured = capsys.readouterr()
    assert "corrections        1 of 2 applied: excluded track 0 — 1 not applied (see the warnings)" in captured.out
    lines = [w for w in captured.err.splitlines() if "no longer fits" in w]
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "was not applied" in lines[0]
    late = Corrections().add("window", start_s=t_end + 5, end_s=t_end + 6)
    (out / "corrections.json").write_text(json.dumps(late.as_dict()))
    assert main(["remeasure", str(out), "--no-figures", "--json"]) == 0
    captured = capsys.readouterr()
    assert any(w.startswith("warning: ") and "holds none of this record" in w for w in captured.err.splitlines())
    assert main(["remeasure", str(out), "--no-figures"]) == 0
    captured = capsys.readouterr()
    assert "1 applied" in captured.out and "it holds none of the record: no plugs are left" in captured.out
    summary = json.loads((out / "summary.json").read_text())
    [said] = of_code(summary, "corrections.not_applied")
    assert "was applied but holds none" in said, summary["warnings"]


def test_an_excluded_plug_is_never_taken_for_air(result):
    """Excluding a plug used to join the bubbles either side into one (the mean bubble went from 27.7 to 89 mm on
    this movie): the bubbles beside it are cut there and not measured; every other bubble keeps its length."""
    det = result.lengths
    assert det.n_bubbles_measured >= 2
    detected = {tuple(p): v for p, v in zip(det.bubble_tracks.tolist(), det.per_bubble_mm, strict=True)}
    for tid in {t for pair in detected for t in pair}:
        ex = apply_corrections(result, Corrections().add("exclude", track=tid))
        kept = {tuple(p): v for p, v in zip(ex.lengths.bubble_tracks.tolist(), ex.lengths.per_bubble_mm, strict=True)}
        assert kept == {p: v for p, v in detected.items() if tid not in p}, tid
        assert ex.lengths.plug_length_mm is not None and tid not in ex.lengths.per_track_mm


@pytest.fixture(scope="module")
def still_object():
    """A dark object laid over the tube (55.5-61.1 mm) a quarter into the record of a climbing train: not still over
    the whole record, so not a blind stretch, and taken for a plug that stays put."""
    from grainplug.synthetic.render import Renderer
    cfg = SynthConfig(n_frames=200, seed=5, celerity_m_s=0.05, plug_length_mm=10, bubble_length_mm=8,
                      plug_length_sd_mm=1, bubble_length_sd_mm=1)
    frames = np.stack(list(Renderer(cfg).frames()))
    frames[60:, 300:330] = np.clip(30 + np.random.default_rng(1).normal(0, 3, frames[60:, 300:330].shape), 0, 255)
    return gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)


def test_the_warnings_follow_the_corrections(still_object):
    """The warnings that judge the plug train are given again on what the corrections keep: the still object's
    warning goes with its track, and comes back with it."""
    [said] = of_code(still_object, "still.track")
    tid = int(said.split()[1])  # "plug N at ..."
    ex = apply_corrections(still_object, Corrections().add("exclude", track=tid))
    assert "still.track" not in codes(ex), ex.warnings
    back = apply_corrections(ex, ex.corrections.add("restore", track=tid))
    assert back.warnings == still_object.warnings
    none = Corrections()
    for t in range(len(still_object.links)):
        none = none.add("exclude", track=t)
    empty = apply_corrections(still_object, none)
    assert not empty.has_plugs and not (codes(empty) & {"still.track", "plugs.near_min_length"}), empty.warnings


def test_a_blind_stretch_removed_takes_its_warning():
    """A clamp over the whole record is found as a blind stretch and said; the reviewer removes it (it was not
    one): the warning goes with it, and comes back when it is marked again."""
    from grainplug.synthetic.render import Renderer
    cfg = SynthConfig(n_frames=200, seed=5, celerity_m_s=0.05, plug_length_mm=10, bubble_length_mm=8,
                      plug_length_sd_mm=1, bubble_length_sd_mm=1)
    frames = np.stack(list(Renderer(cfg).frames()))
    frames[:, 300:330] = np.clip(30 + np.random.default_rng(1).normal(0, 3, frames[:, 300:330].shape), 0, 255)
    res = gp.analyze(frames, fps=cfg.fps, mm_per_px=cfg.mm_per_px)
    assert "still.region" in codes(res)
    gone = apply_corrections(res, Corrections().add("unblind", from_mm=56.0, to_mm=60.0))
    assert "still.region" not in codes(gone), gone.warnings
    assert "still.track" in codes(gone)  # measured as a plug again, it is said to stay put
    again = apply_corrections(gone, gone.corrections.add("blind", from_mm=55.5, to_mm=61.1))
    assert "still.region" not in codes(again) and "still.track" not in codes(again)  # marked by the reviewer
