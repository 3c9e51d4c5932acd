"""grainplug review: the session behind the page, its HTTP answers, and the page in headless Chromium."""

from __future__ import annotations

import contextlib
import json
import shutil
import urllib.error
import urllib.request
from collections.abc import Iterator

import pytest

import grainplug as gp
from grainplug.errors import GrainplugError, ParameterError
from grainplug.review import ReviewServer, ReviewSession, review_targets
from grainplug.synthetic import SynthConfig, synthesize

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def api(srv: ReviewServer, path: str, body: bytes | None = None) -> urllib.request.Request:
    """A request of the page's API as the page's script makes it: with the server's token in its header."""
    headers = dict(srv.headers, **({"Content-Type": "application/json"} if body is not None else {}))
    return urllib.request.Request(srv.base_url + path, data=body, headers=headers)


def get_json(srv: ReviewServer, path: str) -> object:
    with urllib.request.urlopen(api(srv, path)) as r:
        return json.loads(r.read())


@contextlib.contextmanager
def chromium_page(p: object, *args: str, errors: list[str] | None = None) -> Iterator[object]:
    """A page of a headless Chromium at 1366 x 768 (script errors gathered into ``errors``), closed after."""
    browser = p.chromium.launch(executable_path=CHROMIUM, headless=True,  # type: ignore[attr-defined]
                                args=["--no-sandbox", "--disable-gpu", "--no-first-run", *args])
    try:
        page = browser.new_context(viewport={"width": 1366, "height": 768}).new_page()  # more pages: page.context
        if errors is not None:
            page.on("pageerror", lambda e: errors.append(str(e)))
        yield page
    finally:
        browser.close()


@pytest.fixture(scope="module")
def analysis(tmp_path_factory):
    """A saved analysis of a short synthetic movie (the movie stays where it was analysed)."""
    root = tmp_path_factory.mktemp("review")
    movie = synthesize(SynthConfig(n_frames=120, seed=11, fps=250.0), root / "movie", fmt="tiff")
    out = root / "run1"
    gp.analyze(movie.movie).save(out, figures=False)
    return out


@pytest.fixture
def copy(analysis, tmp_path):
    """A fresh copy of the analysis for a test that edits it."""
    dst = tmp_path / "run1"
    shutil.copytree(analysis, dst)
    return dst


def with_stain(folder):
    """The saved analysis as if a stain on the glass (100-104 mm, every frame) had been detected as a plug:
    a false track that drags the celerity toward zero. Returns its track id."""
    import dataclasses

    import numpy as np

    from grainplug.corrections import Corrections, apply_corrections
    from grainplug.plugs import Runs, Tracks

    res = gp.load_result(folder)
    r, tr, n = res.runs, res.links, res.diagram.n_frames
    stain = len(tr)
    frame = np.concatenate([r.frame, np.arange(n)])
    start = np.concatenate([r.start, np.full(n, int(100 / res.mm_per_px))])
    order = np.lexsort((start, frame))
    runs = Runs(frame[order], start[order], np.concatenate([r.stop, np.full(n, int(104 / res.mm_per_px))])[order],
                np.concatenate([r.top_mm, np.full(n, 100.0)])[order],
                np.concatenate([r.bottom_mm, np.full(n, 104.0)])[order])
    links = Tracks(np.concatenate([tr.run_track, np.full(n, stain)])[order], np.r_[tr.first_frame, 0],
                   np.r_[tr.last_frame, n - 1], [*tr.started_by, "start"], [*tr.ended_by, "end"])
    fake = apply_corrections(dataclasses.replace(res, runs=runs, links=links), Corrections())
    dataclasses.replace(fake, detected=None, corrections=None).save(folder, figures=False, report=False)
    return stain


def test_targets_are_one_analysis_or_a_campaigns_runs(analysis, tmp_path):
    assert review_targets(analysis) == {"run1": analysis}
    camp = tmp_path / "camp"
    shutil.copytree(analysis, camp / "runs" / "a")
    shutil.copytree(analysis, camp / "runs" / "b")
    assert list(review_targets(camp)) == ["a", "b"]
    # a run taken out of the manifest keeps its folder but is not the campaign's any more (campaign.csv)
    (camp / "campaign.csv").write_text("run,movie,status\nb,b.tif,ok\n")
    assert list(review_targets(camp)) == ["b"]
    with pytest.raises(ParameterError, match="holds no analysis"):
        review_targets(tmp_path / "nothing")


def test_session_shows_measures_tracks_and_any_frame(analysis):
    with ReviewSession(analysis) as s:
        st = s.state("run1")
        assert st["movie"] == "ok" and st["measures"]["regime"] == "propagative"
        assert st["tracks"] and set(st["edges"]) == {t["plug_id"] for t in st["tracks"]}
        assert st["diagram"]["n_frames"] == 120
        png = s.frame_png("run1", 60)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
        assert s.diagram_png("run1")[:4] == b"\x89PNG"
        with pytest.raises(ParameterError, match="outside the analysis"):
            s.frame_png("run1", 120)


def test_edits_are_kept_at_once_and_measures_recomputed(copy):
    with ReviewSession(copy) as s:
        before = s.state("run1")["measures"]
        tid = s.state("run1")["tracks"][0]["plug_id"]
        s.edit("run1", {"action": "exclude", "track": tid})
        after = s.state("run1")
        assert after["measures"]["n_edges_used"] < before["n_edges_used"]
        assert [t["excluded"] for t in after["tracks"] if t["plug_id"] == tid] == [True]
        kept = json.loads((copy / "corrections.json").read_text())
        edit = kept["edits"][0]
        assert {k: edit[k] for k in ("action", "track")} == {"action": "exclude", "track": tid}
        assert edit["track_trace"][0][0] == pytest.approx(after["tracks"][0]["first_time_s"])  # where it was
        with pytest.raises(ParameterError, match="unknown correction"):
            s.edit("run1", {"action": "explode"})
        s.save("run1")  # the outputs, as grainplug remeasure
        assert json.loads((copy / "summary.json").read_text())["corrections"] == [f"excluded track {tid}"]
        s.undo("run1")
        assert s.state("run1")["measures"] == before
    with ReviewSession(copy) as again:  # a new session finds the file
        assert again.state("run1")["corrections"] == []


def test_the_page_is_told_what_the_window_and_the_spans_keep(copy):
    """The state carries the time window and the spans marked as not plugs, as applied, for the page to shade
    what is cut away; "start here" then "end here" keep the frames between them."""
    with ReviewSession(copy) as s:
        st = s.state("run1")
        assert st["window"] == [None, None] and st["no_plugs"] == []
        t0, t1 = st["diagram"]["t0"], st["diagram"]["t1"]
        a, b = t0 + 0.2 * (t1 - t0), t0 + 0.8 * (t1 - t0)
        s.edit("run1", {"action": "window", "start_s": a})
        s.edit("run1", {"action": "window", "end_s": b})
        s.edit("run1", {"action": "no_plugs", "start_s": a, "end_s": a + 0.05})
        st = s.state("run1")
        assert st["window"] == [pytest.approx(a), pytest.approx(b)]
        assert st["no_plugs"] == [[pytest.approx(a), pytest.approx(a + 0.05)]]
        kept = [t for e in st["edges"].values() for t in e["t"]]
        assert min(kept) >= a + 0.05 - 1e-9 and max(kept) <= b + 1e-9


def test_a_moved_movie_is_said_and_the_rest_still_works(copy, tmp_path):
    res = gp.load_result(copy)
    moved = dict(res.input, path=str(tmp_path / "gone.tif"))
    import dataclasses

    dataclasses.replace(res, input=moved).save(copy, figures=False, report=False)
    with ReviewSession(copy) as s:
        st = s.state("run1")
        assert st["movie"].startswith("cannot open the movie") and st["tracks"]
        with pytest.raises(GrainplugError, match="cannot open the movie"):
            s.frame_png("run1", 3)


def test_http_answers_errors_as_json(copy):
    with ReviewServer(copy) as srv:
        assert get_json(srv, "api/runs") == {"runs": ["run1"]}
        req = api(srv, "api/run/run1/edit", b'{"action": "merge", "track": 1}')
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req)
        with err.value:  # an error response holds its connection until closed
            assert err.value.code == 400 and "merge needs other" in json.loads(err.value.read())["error"]
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(api(srv, "api/run/nope/state"))
        with err.value:
            assert err.value.code == 400


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
def test_review_page_in_chromium(copy):
    """Load; click a time and see that frame; exclude a false track (a stain) and see the celerity change back
    to the truth; reload: the edit is there; no script error, no horizontal scrolling at 1366 x 768."""
    sync_api = pytest.importorskip("playwright.sync_api")
    stain = with_stain(copy)
    errors: list[str] = []
    with (ReviewServer(copy) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--disable-background-networking", errors=errors) as page):
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        box = page.locator("#diagram").bounding_box()
        page.mouse.click(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"])
        page.wait_for_function("() => { const i = document.getElementById('frame');"
                               " return i.complete && i.naturalWidth > 0; }", timeout=20_000)
        page.wait_for_function("() => document.getElementById('frame-label').textContent.startsWith('frame')",
                               timeout=20_000)  # set when the image is on screen
        label = page.inner_text("#frame-label")
        k = int(label.split()[1].rstrip(","))
        assert 50 <= k <= 70, label  # the middle of 120 frames
        before = float(page.get_attribute("#celerity", "data-value"))
        assert before == pytest.approx(-0.031, abs=0.005)  # dragged toward 0 by the stain
        page.locator(f"#tracks tbody tr[data-track='{stain}'] button").click()
        page.wait_for_function("() => document.querySelector('#corrections li').textContent.includes('excluded')",
                               timeout=20_000)
        after = float(page.get_attribute("#celerity", "data-value"))
        assert after == pytest.approx(-0.05, rel=0.03)  # the synthetic movie's truth
        assert page.inner_text("#celerity") == f"{after:.4f}"
        page.reload()
        page.wait_for_selector("#tracks tbody tr.excluded", timeout=20_000)
        assert "excluded track" in page.inner_text("#corrections")
        assert page.evaluate("document.documentElement.scrollWidth") <= 1366
    assert errors == []


def test_review_command_serves_until_ctrl_c(analysis):
    """The command prints its address, serves, and stops cleanly on Ctrl-C (exit 0)."""
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "grainplug", "review", str(analysis), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = proc.stdout.readline()
        url = line.split()[1]
        assert url.startswith("http://127.0.0.1:")
        base, _, token = url.partition("/?token=")
        assert len(token) >= 43  # 32 random bytes
        req = urllib.request.Request(base + "/api/runs", headers={"X-Grainplug-Token": token})
        with urllib.request.urlopen(req, timeout=10) as r:
            assert json.loads(r.read()) == {"runs": ["run1"]}
        with pytest.raises(urllib.error.HTTPError) as err:  # not without the token
            urllib.request.urlopen(base + "/api/runs", timeout=10)
        with err.value:
            assert err.value.code == 403
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "review stopped" in out


@pytest.mark.parametrize("suffix", [".mp4", ".webm"])
def test_overlay_video_shows_the_detected_edges(analysis, tmp_path, capsys, suffix):
    """The video (H.264 MP4 or VP8 WebM) has one frame per analysed frame at the asked rate; the red upper
    edges are where the analysis put them (within 2 px after compression)."""
    import av
    import numpy as np

    from grainplug.cli import main
    from grainplug.overlay import crop_box

    out = tmp_path / f"check{suffix}"
    assert main(["overlay", str(analysis), "--out", str(out), "--slowdown", "25"]) == 0
    assert str(out) in capsys.readouterr().out
    res = gp.load_result(analysis)
    lo, _ = crop_box(res)
    k = 60
    with av.open(str(out)) as c:
        stream = c.streams.video[0]
        assert stream.codec_context.name == ("h264" if suffix == ".mp4" else "vp8")
        assert float(stream.average_rate) == pytest.approx(10.0)
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == res.diagram.n_frames
    img = frames[k].astype(int)
    sel = np.flatnonzero((res.runs.frame == k) & np.isfinite(res.runs.top_mm))
    assert sel.size
    for i in sel:
        row = int(round(res.runs.top_mm[i] / res.mm_per_px - 0.5))
        x = int(round(float(res.tube.axis_x(np.array([row]))[0]))) - lo
        patch = img[max(row - 2, 0): row + 3, x - 2: x + 3]
        red = (patch[..., 0] > 150) & (patch[..., 1] < 110) & (patch[..., 2] < 110)
        assert red.any(), (k, row)
    # a bad name and a folder without an analysis are refused in one line
    assert main(["overlay", str(analysis), "--out", str(tmp_path / "x.avi")]) == 2
    assert main(["overlay", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and ".mp4 or .webm" in err[0]


@pytest.mark.parametrize(("args", "rate", "duration_s"), [
    ([], 30.0, 120 / 250 * 250 / 30),  # the default: 30 frames per second, slowed 8.3 x
    (["--every", "4"], 30.0, 120 / 250 * 250 / 4 / 30),  # a quarter of the frames: as fast, 4 x shorter
    (["--every", "4", "--slowdown", "25"], 2.5, 120 / 250 * 25),  # the movie's timing slowed 25 x, as asked
])
def test_overlay_every_keeps_a_player_s_rate_or_the_timing_asked(analysis, tmp_path, args, rate, duration_s):
    """``--every N`` without ``--slowdown``: the frames kept play at 30 per second (a video N times shorter), not
    at 30 / N (7.5 fps for N = 4, as long as without it); with ``--slowdown S`` the video keeps the movie's timing
    slowed S times. Read back from the file: its rate, its frame count and its duration."""
    import av

    from grainplug.cli import main

    out = tmp_path / "o.mp4"
    assert main(["overlay", str(analysis), "--out", str(out), *args]) == 0
    every = int(args[1]) if args else 1
    with av.open(str(out)) as c:
        stream = c.streams.video[0]
        got_rate = float(stream.average_rate)
        pts = [f.pts * f.time_base for f in c.decode(video=0)]
        container_s = c.duration / av.time_base
    assert got_rate == pytest.approx(rate, rel=1e-3)
    assert len(pts) == 120 // every
    assert float(pts[-1] - pts[0]) + 1 / got_rate == pytest.approx(duration_s, rel=1e-3)
    assert container_s == pytest.approx(duration_s, rel=0.02)


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
@pytest.mark.parametrize("name", ["overlay.mp4", "overlay.webm"])
def test_overlay_plays_in_chromium(analysis, tmp_path, name):
    """The overlay (H.264 MP4, or VP8 WebM without PyAV) decodes and plays in the browser: a <video>
    reaches its end with the right size."""
    from grainplug.overlay import write_overlay

    sync_api = pytest.importorskip("playwright.sync_api")
    video = write_overlay(analysis, tmp_path / name, slowdown=5)
    page_file = tmp_path / "play.html"
    page_file.write_text(f'<!DOCTYPE html><video id="v" src="{name}" muted playsinline></video>')
    with sync_api.sync_playwright() as p, chromium_page(p, "--autoplay-policy=no-user-gesture-required") as page:
        page.goto(page_file.as_uri())
        page.wait_for_function("() => document.getElementById('v').readyState >= 2", timeout=20_000)
        size = page.evaluate("() => { const v = document.getElementById('v');"
                             " return [v.videoWidth, v.videoHeight]; }")
        page.evaluate("() => { const v = document.getElementById('v'); v.playbackRate = 16; return v.play(); }")
        page.wait_for_function("() => document.getElementById('v').ended", timeout=30_000)
        error = page.evaluate("() => document.getElementById('v').error")
    import av

    with av.open(str(video)) as c:
        s = c.streams.video[0]
        assert size == [s.width, s.height]
    assert error is None


def test_the_page_and_remeasure_give_the_same_numbers_after_a_restart(copy):
    """Edits made on the page, then a new process running grainplug remeasure: the same measures."""
    import subprocess
    import sys

    with ReviewSession(copy) as s:
        tid = s.state("run1")["tracks"][0]["plug_id"]
        s.edit("run1", {"action": "exclude", "track": tid})
        t_end = s.state("run1")["diagram"]["t1"]
        s.edit("run1", {"action": "window", "start_s": 0.2 * t_end})
        shown = s.state("run1")["measures"]
    done = subprocess.run([sys.executable, "-m", "grainplug", "remeasure", str(copy), "--json", "--no-figures"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    for key in ("celerity_m_s", "plug_length_mm", "bubble_length_mm", "n_plugs", "n_edges_used", "regime"):
        assert summary[key] == shown[key], key


def test_a_new_analysis_replaces_the_folder_s_own_overlay(copy, tmp_path):
    """The overlay written beside an analysis is grainplug's: ``--overwrite`` replaces it with the rest (it was
    drawn from the old analysis) instead of refusing the folder as holding someone else's file."""
    from grainplug.cli import main
    from grainplug.overlay import write_overlay

    video = write_overlay(copy, every=20)
    assert video.parent == copy and video.exists()
    (copy / "notes.txt").write_text("mine")
    movie = gp.load_result(copy).input["path"]
    assert main(["analyze", movie, "--out", str(copy), "--overwrite", "--no-figures"]) == 2  # the notes are mine
    (copy / "notes.txt").unlink()
    assert main(["analyze", movie, "--out", str(copy), "--overwrite", "--no-figures"]) == 0
    assert not video.exists() and (copy / "summary.json").exists()


def test_a_horizontal_tube_s_overlay_is_written_upright(tmp_path):
    """Drawn in the tube's frame and turned back, the text used to come out mirrored: the time stamp's dark
    band is along the top of the image, the scale bar's along the bottom, as for a vertical tube."""

    from grainplug.overlay import draw_frame

    movie = synthesize(SynthConfig(n_frames=40, seed=4, flow_direction="right"), tmp_path, fmt="tiff").movie
    res = gp.analyze(movie)
    with gp.open_movie(movie) as m:
        img = draw_frame(res, m.read(5), 5)
    rows, cols = img.shape[:2]
    assert cols > 3 * rows  # the tube runs along the image
    dark = img.max(axis=2) < 30
    assert dark[0:16, 0:110].mean() > 0.6  # the time stamp's band, across the top left
    assert dark[20:110, 0:12].mean() < 0.2  # not down the left side (the old, transposed band)
    assert dark[rows - 20:, 0:45].mean() > 0.5  # the scale bar's band, at the bottom left


def _append_by_hand(folder, edit):
    """A hand edit of corrections.json (docs/review.md: by hand, or a colleague's copy)."""
    f = folder / "corrections.json"
    data = json.loads(f.read_text()) if f.exists() else {"format": "grainplug-corrections", "format_version": 2,
                                                          "edits": []}
    data["edits"].append(edit)
    f.write_text(json.dumps(data))


def test_an_open_session_never_writes_over_a_hand_edit(copy):
    """A session used to keep the corrections it read first and write them back with its next edit: an edit
    appended by hand meanwhile was lost. The session reads the file again when it changed and appends to it; an
    edit made on what the page showed before the change is refused (nothing written)."""
    with ReviewSession(copy) as s:
        tids = [t["plug_id"] for t in s.state("run1")["tracks"]]
        s.edit("run1", {"action": "exclude", "track": tids[0]})
        _append_by_hand(copy, {"action": "window", "start_s": 0.1})
        s.edit("run1", {"action": "exclude", "track": tids[1]})
        kept = [e["action"] for e in json.loads((copy / "corrections.json").read_text())["edits"]]
        assert kept == ["exclude", "window", "exclude"]
        assert len(s.state("run1")["corrections"]) == 3

        from grainplug.review.server import StaleReview

        shown = s.state("run1")
        _append_by_hand(copy, {"action": "no_plugs", "start_s": 0.2, "end_s": 0.25})
        on_disk = (copy / "corrections.json").read_bytes()
        with pytest.raises(StaleReview, match=r"corrections.json changed on disk .* nothing was written"):
            s.edit("run1", {"action": "restore", "track": tids[1]}, version=shown["version"])
        with pytest.raises(StaleReview):
            s.undo("run1", version=shown["version"])
        with pytest.raises(StaleReview):
            s.save("run1", version=shown["version"])
        assert (copy / "corrections.json").read_bytes() == on_disk
        now = s.state("run1")  # what the page shows after the refusal
        assert now["corrections"][-1]["text"] == "marked 0.2–0.25 s as not plugs"
        s.edit("run1", {"action": "restore", "track": tids[1]}, version=now["version"])
    kept = [e["action"] for e in json.loads((copy / "corrections.json").read_text())["edits"]]
    assert kept == ["exclude", "window", "exclude", "no_plugs", "restore"]


def test_an_open_session_sees_the_run_analysed_again(copy):
    """A campaign's review kept showing the old analysis after batch analysed the run again, and numbered new
    edits against its old tracks. The session reads result.npz again when it changed; the page's edit made on the
    old analysis is refused."""
    with ReviewSession(copy) as s:
        old = s.state("run1")
        assert old["diagram"]["n_frames"] == 120
        movie = gp.load_result(copy).input["path"]
        gp.analyze(movie, gp.AnalysisParams(start_frame=40)).save(copy, figures=False, report=False)
        new = s.state("run1")
        assert new["diagram"]["n_frames"] == 80
        s.frame_png("run1", 70)  # the movie is read at the new analysis' window

        from grainplug.review.server import StaleReview

        assert new["version"]["result"] != old["version"]["result"] and s.version("run1") == new["version"]
        with pytest.raises(StaleReview, match=r"result\.npz changed on disk"):
            s.edit("run1", {"action": "exclude", "track": 0}, version=old["version"])
        assert not (copy / "corrections.json").exists()


def test_an_empty_track_box_is_no_track(copy):
    """The page sent Number("") = 0 for an empty box: merge 3 "into" nothing merged into track 0. The server takes
    an empty string as no number at all."""
    with ReviewServer(copy) as srv:
        for body in ('{"action": "merge", "track": "", "other": 1}', '{"action": "merge", "track": 0, "other": " "}',
                     '{"action": "exclude", "track": ""}'):
            req = api(srv, "api/run/run1/edit", body.encode())
            with pytest.raises(urllib.error.HTTPError) as err:
                urllib.request.urlopen(req)
            with err.value:
                assert err.value.code == 400 and " needs " in json.loads(err.value.read())["error"]
    assert not (copy / "corrections.json").exists()


def test_edges_break_across_spans_without_plugs(copy):
    """Across a span marked as not plugs, a track's edges were drawn as a straight line through it: the state
    holds a point without positions there, where the page lifts its pen."""
    with ReviewSession(copy) as s:
        st = s.state("run1")
        tid, e = max(st["edges"].items(), key=lambda kv: kv[1]["t"][-1] - kv[1]["t"][0])
        a = e["t"][0] + 0.4 * (e["t"][-1] - e["t"][0])
        s.edit("run1", {"action": "no_plugs", "start_s": a, "end_s": a + 0.05})
        e = s.state("run1")["edges"][tid]
        gaps = [i for i, z in enumerate(e["top"]) if z is None and e["bottom"][i] is None]
        assert len(gaps) == 1 and e["t"][gaps[0] - 1] < a and e["t"][gaps[0] + 1] > a + 0.05


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
def test_the_page_refuses_empty_boxes_and_stale_edits(copy, tmp_path):
    """In Chromium: no broken image before a frame is chosen; merge with one box empty (or both) says which box
    and writes nothing; an edit made after corrections.json was changed by hand is refused with the reason and
    the page shows the file; a hand edit made while the page is idle is shown within seconds; every track has
    its number."""
    sync_api = pytest.importorskip("playwright.sync_api")
    errors: list[str] = []
    with (ReviewServer(copy) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--disable-background-networking", errors=errors) as page):
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        assert not page.is_visible("#frame")  # not the broken-image alt text
        st = get_json(srv, "api/run/run1/state")
        page.fill("#merge-b", "1")
        page.click("#merge")
        assert 'the box "into" is empty' in page.inner_text("#error")
        page.fill("#merge-b", "")
        page.fill("#merge-a", "2")
        page.click("#merge")
        assert 'the box "merge track" is empty' in page.inner_text("#error")
        page.fill("#merge-b", "1.5")
        page.click("#merge")
        assert '"1.5" in the box "merge track" is not a track number' in page.inner_text("#error")
        assert not (copy / "corrections.json").exists()
        tids = [t["plug_id"] for t in st["tracks"]]
        page.locator(f"#tracks tbody tr[data-track='{tids[0]}'] button").click()
        page.wait_for_selector("#tracks tbody tr.excluded", timeout=20_000)
        _append_by_hand(copy, {"action": "window", "start_s": 0.1})
        page.locator(f"#tracks tbody tr[data-track='{tids[1]}'] button").click()  # before the next poll
        page.wait_for_function("() => document.getElementById('error').textContent.includes('changed on disk')",
                               timeout=20_000)
        assert "kept the frames from 0.1 s on" in page.inner_text("#corrections")
        kept = json.loads((copy / "corrections.json").read_text())["edits"]
        assert [e["action"] for e in kept] == ["exclude", "window"]
        _append_by_hand(copy, {"action": "no_plugs", "start_s": 0.2, "end_s": 0.25})  # the page idle
        page.wait_for_function("() => document.getElementById('corrections').textContent.includes('not plugs')",
                               timeout=10_000)
        assert "changed on disk" in page.inner_text("#notice")
        page.locator(f"#tracks tbody tr[data-track='{tids[1]}'] button").click()
        page.wait_for_function("() => document.querySelectorAll('#corrections li').length === 4", timeout=20_000)
        assert page.inner_text("#error") == ""
        kept = json.loads((copy / "corrections.json").read_text())["edits"]
        assert [e["action"] for e in kept] == ["exclude", "window", "no_plugs", "exclude"]
    assert errors == []


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
def test_the_page_shows_the_oscillation_and_every_track_s_number(tmp_path):
    """The state had the oscillation frequency, the page never showed it. And a track whose upper edge the view
    cuts all along (this movie's first plug) had no number on the diagram: it has one, under its lower edge."""
    sync_api = pytest.importorskip("playwright.sync_api")
    movie = synthesize(SynthConfig(n_frames=200, seed=4, regime="oscillating"), tmp_path / "m", fmt="tiff").movie
    gp.analyze(movie).save(tmp_path / "osc", figures=False, report=False)
    with ReviewServer(tmp_path / "osc") as srv, sync_api.sync_playwright() as p, chromium_page(p) as page:
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        st = get_json(srv, "api/run/osc/state")["measures"]
        assert st["regime"] == "oscillating" and st["oscillation_frequency_hz"]
        f = st["oscillation_frequency_hz"]
        assert float(page.get_attribute("#frequency", "data-value")) == pytest.approx(f)
        assert page.inner_text("#frequency") == f"{f:.2f}"
        assert page.inner_text("#amplitude") == f"{st['oscillation_amplitude_mm']:.2f}"
        edges = get_json(srv, "api/run/osc/state")["edges"]
        assert any(all(z is None for z in e["top"]) for e in edges.values())  # the case is there
        labels = page.evaluate("() => { const out = []; const ctx = document.getElementById('diagram')"
                               ".getContext('2d'); const f = ctx.fillText.bind(ctx); ctx.fillText = (t, x, y) => "
                               "{ out.push(String(t)); f(t, x, y); }; draw(); return out; }")
        assert set(edges) <= set(labels)


def test_the_page_shows_and_edits_the_blind_stretches(copy):
    """Pick two positions on the diagram and mark the stretch between them blind: it is listed, drawn, and the
    measures are those of the stretch masked; remove it: back to the analysis; reload: as left."""
    sync_api = pytest.importorskip("playwright.sync_api")
    res = gp.load_result(copy)
    errors: list[str] = []
    with (ReviewServer(copy) as srv, sync_api.sync_playwright() as p, chromium_page(p, errors=errors) as page):
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        assert page.inner_text("#blind") == "none"
        for share, button in ((0.40, "#bl-start"), (0.47, "#bl-end")):  # about 40 % and 47 % down the view
            box = page.locator("#diagram").bounding_box()  # where it is now: a notice may move it
            page.mouse.click(box["x"] + 0.5 * box["width"], box["y"] + share * box["height"])
            page.click(button)
        page.wait_for_function("() => document.querySelector('#blind li button') !== null", timeout=20_000)
        listed = page.inner_text("#blind li")
        assert "added here" in listed, listed
        state = get_json(srv, "api/run/run1/state")
        [b] = state["blind"]  # type: ignore[index]
        z0, z1 = res.diagram.position_mm[0], res.diagram.position_mm[-1]
        assert b["from_mm"] == pytest.approx(z0 + 0.40 * (z1 - z0), abs=2.0)
        assert b["to_mm"] == pytest.approx(z0 + 0.47 * (z1 - z0), abs=2.0)
        masked = gp.apply_corrections(res, gp.Corrections().add("blind", from_mm=b["from_mm"], to_mm=b["to_mm"]))
        assert state["measures"]["plug_length_mm"] == pytest.approx(masked.plug_length_mm, rel=1e-4)  # type: ignore[index]
        page.click("#blind li button")  # remove
        page.wait_for_function("() => document.getElementById('blind').textContent === 'none'", timeout=20_000)
        page.reload()
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        assert page.inner_text("#blind") == "none"
        assert "marked" in page.inner_text("#corrections") and "removed the blind" in page.inner_text("#corrections")
        assert float(page.get_attribute("#celerity", "data-value")) == pytest.approx(res.celerity_m_s, abs=1e-6)
    assert errors == []


def numbered_png(k: int) -> bytes:
    """A small PNG whose width tells its frame (``k + 1`` px): the page's image says which frame it shows."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("L", (k + 1, 4), 128).save(buf, format="PNG")
    return buf.getvalue()


#: the frame in the label and the frame whose image is on screen, each time the label changes
_WATCH_LABEL = """() => {
  window.seen = [];
  const label = document.getElementById('frame-label'), img = document.getElementById('frame');
  new MutationObserver(() => {
    const m = /^frame (\\d+)/.exec(label.textContent);
    if (m) window.seen.push([performance.now() / 1000, Number(m[1]), img.naturalWidth - 1]);
  }).observe(label, {childList: true, characterData: true, subtree: true});
}"""


def _played(folder, sync_api) -> tuple[str, list, str, list[str]]:
    """Play the review of ``folder`` once through in Chromium at the default speed: the speed's label, what was
    seen (:data:`_WATCH_LABEL`), the line under the buttons, and the page's script errors."""
    errors: list[str] = []
    with (ReviewServer(folder) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--disable-background-networking", errors=errors) as page):
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        speed = page.eval_on_selector("#speed", "s => s.options[s.selectedIndex].text")
        page.evaluate(_WATCH_LABEL)
        page.click("#play")
        page.wait_for_function("() => document.getElementById('play').textContent === 'play'", timeout=30_000)
        seen = page.evaluate("window.seen")
        info = page.evaluate("() => document.getElementById('play-info')?.textContent ?? ''")
    return speed, seen, info, errors


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
@pytest.mark.parametrize("draw_s", [0.0, 0.15])
def test_play_keeps_the_movie_s_time_slowed_as_stated_and_the_label_on_the_image(analysis, monkeypatch, draw_s):
    """Play: the frames come at the rate the speed list states (this 250 fps movie: slowed 10 x, 25 frames/s), not
    at whatever pace the page asks them (one each 150 ms: 6.7/s); a server slower than that (150 ms a frame) skips
    frames and keeps the time, never falls behind; and the label names the frame on screen, never the one on its
    way (it ran a frame ahead). The frames are numbered images, so that the test reads which one is shown."""
    import time

    import numpy as np

    sync_api = pytest.importorskip("playwright.sync_api")

    def frame_png(self, name, k):
        time.sleep(draw_s)
        return numbered_png(k)

    monkeypatch.setattr(ReviewSession, "frame_png", frame_png)
    speed, seen, info, errors = _played(analysis, sync_api)
    assert speed == "slowed 10×: 25 frames/s"
    assert errors == []
    t, label, shown = (np.array(c, float) for c in zip(*seen, strict=True))
    assert (label == shown).all(), [s for s in seen if s[1] != s[2]][:5]  # the label is the image's
    assert label[0] == 0 and label[-1] == 119
    rate = 25.0  # 250 fps slowed 10 times
    late = label - (t - t[0]) * rate  # frames behind the movie's clock (negative: behind)
    # at most about one image's drawing behind (and a loaded machine's slack), never more: at main's 6.7
    # frames/s the last frame came over 300 frames behind the movie's clock
    assert late.min() > -rate * (draw_s + 0.25), late.min()
    assert t[-1] - t[0] == pytest.approx(119 / rate, abs=draw_s + 0.4)
    if draw_s == 0:
        assert len(label) >= 110  # a fast server: (nearly) every frame
    else:
        assert len(label) < 60  # frames skipped
        assert "the others skipped" in info and "25 of the movie's frames a second" in info


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
def test_play_shows_the_movie_s_own_frames_at_the_rate_stated(analysis):
    """Play with the frames read from the movie and drawn by the server (not stand-ins): at the default 25 frames a
    second (this 250 fps movie slowed 10 times), nearly every frame is shown. Drawn by matplotlib (60 ms a frame
    here), about half were skipped."""
    import numpy as np

    sync_api = pytest.importorskip("playwright.sync_api")
    speed, seen, _, errors = _played(analysis, sync_api)
    assert speed == "slowed 10×: 25 frames/s"
    assert errors == []
    t, label, width = (np.array(c, float) for c in zip(*seen, strict=True))
    assert label[0] == 0 and label[-1] == 119 and (width > 100).all()  # the frames themselves, not stand-ins
    assert len(label) >= 100, len(label)
    assert t[-1] - t[0] == pytest.approx(119 / 25.0, abs=0.4)


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")
def test_write_outputs_says_what_it_wrote_or_why_not(copy, monkeypatch):
    """"Write outputs" said nothing: it says, beside the button, the folder and the files written with the number
    of corrections; and when the writing fails, the reason, in red there and in the page's error line."""
    sync_api = pytest.importorskip("playwright.sync_api")
    errors: list[str] = []
    with (ReviewServer(copy) as srv, sync_api.sync_playwright() as p, chromium_page(p, errors=errors) as page):
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        page.locator("#tracks tbody tr button").first.click()
        page.wait_for_function("() => document.querySelector('#corrections li').textContent.includes('excluded')",
                               timeout=20_000)
        page.click("#save")
        page.wait_for_function("() => document.getElementById('save-status').className !== ''", timeout=30_000)
        said = page.inner_text("#save-status")
        assert page.get_attribute("#save-status", "class") == "ok"
        assert str(copy) in said and "with 1 correction:" in said
        for name in ("summary.json", "tracks.csv", "report.html"):
            assert name in said and (copy / name).is_file()
        assert json.loads((copy / "summary.json").read_text())["corrections"]  # written, with the edit
        assert page.is_visible("#save-status")

        def fails(self, name, *, version=None):
            raise GrainplugError(f"cannot write {copy}: No space left on device")

        monkeypatch.setattr(ReviewSession, "save", fails)
        page.click("#save")
        page.wait_for_function("() => document.getElementById('save-status').className === 'failed'", timeout=30_000)
        assert "not written" in page.inner_text("#save-status") and "No space left" in page.inner_text("#save-status")
        assert "No space left" in page.inner_text("#error")
        assert page.is_visible("#save-status") and page.is_visible("#error")
    assert errors == [], errors
