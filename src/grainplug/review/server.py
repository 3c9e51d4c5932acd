"""``grainplug review``: a local page to check an analysis against its frames and correct it.

Notes
-----
The server is Python's own :class:`http.server.ThreadingHTTPServer`, bound to
127.0.0.1. The page is one HTML file and one script shipped in the package, with no
JavaScript library and no CDN, so it works offline. Nothing to install, nothing fetched
at run time, and nothing listening beyond this machine. Panel/Bokeh would bring a
zoomable plot for free, but also ~50 MB of dependencies and a server of their own for a
page with one image, one table and a few buttons.

Endpoints (``R`` is a run's name: its folder's name, a single analysis' or each of a
campaign's runs):

- ``GET /`` and ``/app.js``: the page;
- ``GET /api/runs``: the runs that can be reviewed;
- ``GET /api/run/R/state``: measures, tracks, edges, corrections, the movie's status, and the
  ``version`` of the files they come from;
- ``GET /api/run/R/version``: that version, as it is on disk now (the page asks every few seconds,
  and reloads when ``corrections.json`` or ``result.npz`` changed under it);
- ``GET /api/run/R/diagram.png``: the spatiotemporal diagram (time across, position down);
- ``GET /api/run/R/frame/K.png``: frame ``K`` read from the movie, with the tube and the
  plug edges drawn on it;
- ``POST /api/run/R/edit`` (a JSON edit: ``{"action": "exclude", "track": 3}``),
  ``/undo``, ``/save``: change the corrections (kept in ``corrections.json`` at once,
  measures recomputed) or rewrite the run's outputs (:func:`grainplug.remeasure`). A body
  with the ``version`` the page was shown is refused (409, with the state as it is now) when
  the files changed since: the page's edit named tracks of what it showed.

The session never writes over what it has not read: each request first compares
``corrections.json`` (its bytes) and ``result.npz`` (inode, size, time) with what it read,
and reads them again when they changed (a hand edit, a colleague's copy, another review
page, ``grainplug batch`` analysing the run again). An edit is appended to the file as it
is on disk.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import threading
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from .._atomic import atomic_file
from ..corrections import CORRECTIONS_FILE, Corrections, apply_corrections, replayed
from ..errors import GrainplugError, ParameterError
from ..jsonio import dumps
from ..result import AnalysisResult, load_result
from ..store import RESULT_FILE, read_corrections

log = logging.getLogger(__name__)

#: at most this many points per track are sent to the page (the diagram is drawn from all)
MAX_POINTS_PER_TRACK = 2000


def review_targets(folder: str | Path) -> dict[str, Path]:
    """The analyses under ``folder``: itself, or a campaign's runs (``runs/*``); name -> folder (absolute)."""
    p = Path(os.path.abspath(folder))  # "." stays the folder when it is replaced whole (Write outputs)
    if (p / RESULT_FILE).is_file():
        return {p.resolve().name or "analysis": p}
    runs = p / "runs"
    found = {q.name: q for q in sorted(runs.iterdir()) if (q / RESULT_FILE).is_file()} if runs.is_dir() else {}
    listed = _campaign_runs(p)
    if listed is not None:  # a run taken out of the manifest keeps its folder, but is no longer the campaign's
        found = {name: q for name, q in found.items() if name in listed}
    if not found:
        raise ParameterError(f"{p} holds no analysis (no {RESULT_FILE}, no runs/*/{RESULT_FILE}) — give the --out "
                             "folder of grainplug analyze or grainplug batch")
    return found


def _campaign_runs(folder: Path) -> set[str] | None:
    """The run folders of the campaign's last batch (``campaign.csv``), or None where there is no table."""
    import csv

    from ..campaigns.manifest import run_folder_name

    table = folder / "campaign.csv"
    if not table.is_file():
        return None
    with open(table, newline="", encoding="utf-8") as fh:
        return {run_folder_name(str(row.get("run", ""))) for row in csv.DictReader(fh)}


class StaleReview(ParameterError):
    """The page's edit was made on files that have changed on disk since it was shown; nothing was written."""


def _result_id(folder: Path) -> str:
    """Which ``result.npz`` is in ``folder``: inode, size and time (a new analysis replaces the folder whole)."""
    try:
        st = (folder / RESULT_FILE).stat()
    except OSError:
        return "none"
    return f"{st.st_ino}-{st.st_size}-{st.st_mtime_ns}"


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _corrections_id(folder: Path) -> str:
    """What ``corrections.json`` holds: a hash of its bytes ("none" without the file)."""
    try:
        return _digest((folder / CORRECTIONS_FILE).read_bytes())
    except FileNotFoundError:
        return "none"
    except OSError as exc:
        raise ParameterError(f"cannot read {folder / CORRECTIONS_FILE}: {exc.strerror or exc} — check the file's "
                             "permissions") from None


@dataclass
class _Run:
    folder: Path
    result: AnalysisResult
    corrections: Corrections
    result_id: str = ""
    corrections_id: str = ""
    movie: Any = None
    movie_error: str | None = None
    offset: int = 0

    @property
    def version(self) -> dict[str, str]:
        """What the run's state was made from (compared with the page's at each edit)."""
        return {"result": self.result_id, "corrections": self.corrections_id}


class ReviewSession:
    """The runs being reviewed, their corrections and open movies (a context manager: closes the movies).

    Parameters
    ----------
    folder : path
        An analysis folder, or a campaign's.
    """

    def __init__(self, folder: str | Path) -> None:
        self.targets = review_targets(folder)
        self._runs: dict[str, _Run] = {}
        self._lock = threading.Lock()

    def __enter__(self) -> ReviewSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        with self._lock:
            for run in self._runs.values():
                if run.movie is not None:
                    run.movie.close()
            self._runs.clear()

    # -- runs ------------------------------------------------------------------------
    def run(self, name: str) -> _Run:
        """The run as its files are on disk now: read again when ``result.npz`` or ``corrections.json`` changed
        since it was read (never a stale copy to write over the file)."""
        if name not in self.targets:
            raise ParameterError(f"no run named {name!r}")
        with self._lock:
            folder = self.targets[name]
            run = self._runs.get(name)
            result_id, corrections_id = _result_id(folder), _corrections_id(folder)  # before reading: a change
            # meanwhile is seen at the next request
            if run is not None and run.result_id == result_id and run.corrections_id == corrections_id:
                return run
            if run is not None and run.result_id == result_id:
                log.info("review: %s changed on disk: read again", folder / CORRECTIONS_FILE)
                corr = read_corrections(folder) or Corrections()
                run.result, run.corrections = apply_corrections(run.result, corr), corr
                run.corrections_id = corrections_id
                return run
            if run is not None:
                log.info("review: %s changed on disk (analysed again?): read again", folder / RESULT_FILE)
                if run.movie is not None:
                    run.movie.close()
            res = load_result(folder)
            corr = read_corrections(folder) or Corrections()
            self._runs[name] = _Run(folder, apply_corrections(res, corr), corr, result_id, corrections_id)
            return self._runs[name]

    def version(self, name: str) -> dict[str, str]:
        """The run's files' version on disk now (what :meth:`state` would be made from), without reading them."""
        if name not in self.targets:
            raise ParameterError(f"no run named {name!r}")
        folder = self.targets[name]
        return {"result": _result_id(folder), "corrections": _corrections_id(folder)}

    def _check_version(self, name: str, seen: object) -> _Run:
        """The run, read again if its files changed; raises :class:`StaleReview` when ``seen`` (the version the
        page was shown; None: not checked) is not what is on disk."""
        run = self.run(name)
        if seen is None or seen == run.version:
            return run
        if not isinstance(seen, dict):
            raise ParameterError("\"version\" must be the version object of the run's state")
        if seen.get("result") != run.result_id:
            raise StaleReview(f"{name}'s result.npz changed on disk since this page showed it (the run analysed "
                              "again by grainplug batch, or remeasured): its tracks may be numbered otherwise — "
                              "nothing was written; the page now shows the analysis as it is: make the edit again")
        raise StaleReview(f"{name}'s corrections.json changed on disk since this page showed it (edited by hand, "
                          "copied, or by another review page) — nothing was written; the page now shows the file "
                          "as it is: check it, then make the edit again")

    def _movie(self, run: _Run) -> Any:
        """The run's movie, opened on first use (None, with the reason, when it cannot be)."""
        if run.movie is None and run.movie_error is None:
            from ..readers import open_movie

            path = run.result.input.get("path") if isinstance(run.result.input, dict) else None
            if not path:
                run.movie_error = "the analysis was made from frames in memory: no movie to show"
            else:
                try:
                    p = run.result.params
                    run.movie = open_movie(path, fps=p.fps, glob=p.glob, allow_truncated=True)
                    from ..readers.window import window_start

                    run.offset = window_start(run.movie, p)
                except (GrainplugError, OSError) as exc:
                    run.movie_error = f"cannot open the movie {path}: {exc}"
        return run.movie

    # -- what the page shows ---------------------------------------------------------------
    def state(self, name: str) -> dict[str, object]:
        run = self.run(name)
        res = run.result
        from ..summary import track_rows

        s = res.summary
        st = replayed(res)  # what the corrections exclude and keep, as applied
        excluded, window, spans = (frozenset(), (None, None), ()) if st is None else (st.excluded, st.window, st.spans)
        detected_links = res.detected[1] if res.detected is not None else res.links
        rows = [{k: None if isinstance(v, float) and not np.isfinite(v) else v for k, v in r.items()}
                for r in track_rows(res)]
        shown = {int(r["plug_id"]) for r in rows}
        for tid in sorted(excluded - shown):
            rows.append({"plug_id": tid, "n_frames": int(np.sum(detected_links.run_track == tid)), "excluded": True})
        for r in rows:
            r["excluded"] = int(r["plug_id"]) in excluded
        edges = {}
        t = res.diagram.time_s
        for tid in np.unique(res.links.run_track):
            sel = np.flatnonzero(res.links.run_track == tid)
            step = max(1, len(sel) // MAX_POINTS_PER_TRACK)
            sel = sel[::step]
            edges[int(tid)] = _broken(t[res.runs.frame[sel]], res.runs.top_mm[sel], res.runs.bottom_mm[sel], spans)
        self._movie(run)
        return {
            "run": name, "runs": list(self.targets), "version": run.version,
            "measures": {k: s.get(k) for k in ("regime", "celerity_m_s", "celerity_ci95_m_s", "plug_length_mm",
                                               "bubble_length_mm", "oscillation_frequency_hz",
                                               "oscillation_amplitude_mm", "n_plugs", "n_edges_used")},
            "statement": res.statement, "warnings": list(res.warnings),
            "diagram": {"t0": float(t[0]), "t1": float(t[-1]), "n_frames": int(res.diagram.n_frames),
                        "z0": float(res.diagram.position_mm[0]), "z1": float(res.diagram.position_mm[-1]),
                        "fps": res.info.fps},
            "tracks": rows, "edges": edges,
            "corrections": [{"text": e.describe(), "at": e.at} for e in run.corrections.edits],
            "window": list(window), "no_plugs": [list(span) for span in spans],
            "movie": run.movie_error or "ok",
        }

    def diagram_png(self, name: str) -> bytes:
        """The diagram as an 8-bit grey PNG: time across (columns), position down (rows)."""
        from PIL import Image

        v = self.run(name).result.diagram.values.astype(np.float32)
        lo, hi = np.percentile(v, [0.5, 99.5])
        g = np.clip((v - lo) / max(hi - lo, 1e-9) * 255, 0, 255).astype(np.uint8).T
        buf = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(g)).save(buf, format="PNG", compress_level=1)
        return buf.getvalue()

    def frame_png(self, name: str, k: int) -> bytes:
        """Frame ``k`` of the analysis with the tube and the edges of that frame drawn on it."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        from ..plotting.figures import plot_annotated_frame

        run = self.run(name)
        n = run.result.diagram.n_frames
        if not 0 <= k < n:
            raise ParameterError(f"frame {k} is outside the analysis (0 to {n - 1})")
        movie = self._movie(run)
        if movie is None:
            raise GrainplugError(run.movie_error or "no movie")
        from ..overlay import analysed_region

        with self._lock:  # one reader at a time
            frame = analysed_region(run.result, movie.read(run.offset + k))
        fig = plot_annotated_frame(run.result, frame=frame, index=k)
        buf = io.BytesIO()
        FigureCanvasAgg(fig).print_png(buf)
        return buf.getvalue()

    # -- corrections -----------------------------------------------------------------------
    def _set(self, run: _Run, corr: Corrections) -> None:
        new = apply_corrections(run.result, corr)
        text = dumps(corr.as_dict())
        with self._lock:
            if _corrections_id(run.folder) != run.corrections_id:  # written since this request read it
                raise StaleReview(f"{run.folder / CORRECTIONS_FILE} changed on disk while the edit was made — "
                                  "nothing was written; the page now shows the file as it is: make the edit again")
            with atomic_file(run.folder / CORRECTIONS_FILE) as tmp:
                Path(tmp).write_text(text, encoding="utf-8")
            run.result, run.corrections = new, corr
            run.corrections_id = _digest(text.encode("utf-8"))

    def edit(self, name: str, edit: dict[str, object], *, version: object = None) -> None:
        """Add ``edit`` (``{"action": ..., ...}``) to the run's corrections, as they are on disk now.

        ``version``: the version of the state the edit was made on (:meth:`state`); when the files
        changed since, :class:`StaleReview` is raised and nothing is written.
        """
        if not isinstance(edit, dict) or "action" not in edit:
            raise ParameterError("an edit is a JSON object with an \"action\"")
        # an empty box is no number: "merge needs other", not a merge into track 0
        args = {k: None if isinstance(v, str) and not v.strip() else v for k, v in edit.items() if k != "action"}
        run = self._check_version(name, version)  # the edit keeps the spans of its tracks in this analysis
        self._set(run, run.corrections.add(str(edit["action"]), on=run.result, **args))

    def undo(self, name: str, *, version: object = None) -> None:
        """Remove the last edit (refused, as :meth:`edit`, when the files changed since ``version``)."""
        run = self._check_version(name, version)
        if not run.corrections.edits:
            raise ParameterError("there is no edit to undo")
        self._set(run, run.corrections.undo())

    def save(self, name: str, *, version: object = None) -> None:
        """Rewrite the run's outputs with the corrections (as ``grainplug remeasure``)."""
        from ..workflows import remeasure

        run = self._check_version(name, version)
        with self._lock:
            run.result = remeasure(run.folder)
            run.result_id, run.corrections_id = _result_id(run.folder), _corrections_id(run.folder)


def _broken(t: np.ndarray, top: np.ndarray, bottom: np.ndarray,
            spans: tuple[tuple[float, float], ...] | frozenset[Any]) -> dict[str, list[float | None]]:
    """A track's edges for the page, with a break (a point without positions) wherever a span marked as not
    plugs lies between two of its points: the page lifts its pen there instead of drawing across the span."""
    ts, tops, bottoms = _list(t), _list(top), _list(bottom)
    cuts = [i for i in range(1, len(t)) if any(a < t[i] and b > t[i - 1] for a, b in spans)]
    for i in reversed(cuts):
        mid = round(0.5 * (float(t[i - 1]) + float(t[i])), 4)
        ts.insert(i, mid)
        tops.insert(i, None)
        bottoms.insert(i, None)
    return {"t": ts, "top": tops, "bottom": bottoms}


def _list(a: np.ndarray) -> list[float | None]:
    return [None if not np.isfinite(x) else round(float(x), 4) for x in a]


def _static(name: str) -> bytes:
    return resources.files("grainplug.review").joinpath("static", name).read_bytes()


class _Handler(BaseHTTPRequestHandler):
    session: ReviewSession  # set on the subclass made by ReviewServer
    timeout = 60  # an idle connection is dropped after a minute

    def log_message(self, fmt: str, *args: object) -> None:
        log.debug("review: " + fmt, *args)

    def _send(self, body: bytes, ctype: str, status: int = 200) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, data: object, status: int = 200) -> None:
        self._send(dumps(data).encode(), "application/json", status)

    def _error(self, exc: Exception, name: str = "") -> None:
        status = HTTPStatus.BAD_REQUEST if isinstance(exc, ParameterError) else HTTPStatus.INTERNAL_SERVER_ERROR
        msg = exc.message if isinstance(exc, ParameterError) else str(exc)
        body: dict[str, object] = {"error": msg}
        if isinstance(exc, StaleReview):  # the page shows what is on disk now
            status = HTTPStatus.CONFLICT
            try:
                body["state"] = self.session.state(name)
            except (GrainplugError, ValueError) as again:
                body["error"] = f"{msg} ({again})"
        self._json(body, status)

    def _route(self) -> tuple[str, str, list[str]]:
        parts = [unquote(p) for p in self.path.split("?")[0].strip("/").split("/")]
        if len(parts) >= 4 and parts[:2] == ["api", "run"]:
            return "run", parts[2], parts[3:]
        return "top", "", parts

    def do_GET(self) -> None:
        try:
            kind, name, rest = self._route()
            s = self.session
            if kind == "top":
                if rest in ([""], ["index.html"]):
                    return self._send(_static("index.html"), "text/html; charset=utf-8")
                if rest == ["app.js"]:
                    return self._send(_static("app.js"), "text/javascript; charset=utf-8")
                if rest == ["api", "runs"]:
                    return self._json({"runs": list(s.targets)})
                if rest == ["favicon.ico"]:
                    return self._send(b"", "image/x-icon", HTTPStatus.NO_CONTENT)
            elif rest == ["state"]:
                return self._json(s.state(name))
            elif rest == ["version"]:
                return self._json(s.version(name))
            elif rest == ["diagram.png"]:
                return self._send(s.diagram_png(name), "image/png")
            elif len(rest) == 2 and rest[0] == "frame" and rest[1].endswith(".png"):
                return self._send(s.frame_png(name, int(rest[1][:-4])), "image/png")
            self._json({"error": f"no such page {self.path}"}, HTTPStatus.NOT_FOUND)
        except (GrainplugError, ValueError) as exc:
            self._error(exc)
        except Exception as exc:  # a bug: answer, log, keep serving
            log.exception("review: %s", self.path)
            self._error(exc)

    def do_POST(self) -> None:
        kind = name = ""
        try:
            kind, name, rest = self._route()
            if kind != "run":
                return self._json({"error": "not found"}, HTTPStatus.NOT_FOUND)
            n = int(self.headers.get("Content-Length") or 0)
            body = json.loads(self.rfile.read(n) or b"{}")
            if not isinstance(body, dict):
                raise ParameterError("the request's body must be a JSON object")
            version = body.pop("version", None)
            if rest == ["edit"]:
                self.session.edit(name, body, version=version)
            elif rest == ["undo"]:
                self.session.undo(name, version=version)
            elif rest == ["save"]:
                self.session.save(name, version=version)
            else:
                return self._json({"error": "not found"}, HTTPStatus.NOT_FOUND)
            self._json(self.session.state(name))
        except (GrainplugError, ValueError) as exc:
            self._error(exc, name if kind == "run" else "")
        except Exception as exc:
            log.exception("review: %s", self.path)
            self._error(exc)


class _Server(ThreadingHTTPServer):
    """A threading server that closes every connection when it stops (a browser keeps idle ones open)."""

    daemon_threads = False
    block_on_close = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._open: set[Any] = set()
        self._open_lock = threading.Lock()

    def process_request(self, request: Any, client_address: Any) -> None:
        with self._open_lock:
            self._open.add(request)
        super().process_request(request, client_address)

    def shutdown_request(self, request: Any) -> None:
        with self._open_lock:
            self._open.discard(request)
        super().shutdown_request(request)

    def close_connections(self) -> None:
        """End every open connection: their handlers see the end of input and finish."""
        import contextlib
        import socket

        with self._open_lock:
            open_now = list(self._open)
        for sock in open_now:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)


class ReviewServer:
    """The review page served on ``127.0.0.1:port`` from a thread (a context manager: stops it).

    Parameters
    ----------
    folder : path
        An analysis folder or a campaign's.
    port : int
        0 picks a free port (see :attr:`url`).
    """

    def __init__(self, folder: str | Path, *, port: int = 0) -> None:
        self.session = ReviewSession(folder)
        handler = type("Handler", (_Handler,), {"session": self.session})
        self.httpd = _Server(("127.0.0.1", port), handler)
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="grainplug-review", daemon=False)

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/"

    def __enter__(self) -> ReviewServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.httpd.shutdown()
        self._thread.join()
        self.httpd.close_connections()
        self.httpd.server_close()  # joins the request threads
        self.session.close()
