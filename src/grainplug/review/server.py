"""``grainplug review``: a local page to check an analysis against its frames and correct it.

Notes
-----
The server is Python's own :class:`http.server.ThreadingHTTPServer`, bound to
127.0.0.1. The page is one HTML file, one script and one stylesheet shipped in the package, with no
JavaScript library and no CDN, so it works offline. Nothing to install, nothing fetched
at run time, and nothing listening beyond this machine. Panel/Bokeh would bring a
zoomable plot for free, but also ~50 MB of dependencies and a server of their own for a
page with one image, one table and a few buttons.

Endpoints (``R`` is a run's name: its folder's name, a single analysis' or each of a
campaign's runs):

- ``GET /`` and ``/app.js``, ``/app.css``: the page (``/?token=...`` sets the token's cookie);
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
  measures recomputed) or rewrite the run's outputs (:func:`grainplug.remeasure`; the answer's ``saved``
  names the folder and the files written). A body
  with the ``version`` the page was shown is refused (409, with the state as it is now) when
  the files changed since: the page's edit named tracks of what it showed.

Every request is checked before anything is read or written (:class:`_Handler`): its ``Host`` must be
``127.0.0.1:PORT`` or ``localhost:PORT`` (DNS rebinding), it must come from no other page (``Origin``,
``Sec-Fetch-Site``: CSRF), and it must carry the server's random token (:attr:`ReviewServer.token`: other users of
the machine reach the port too) — in the ``X-Grainplug-Token`` header the page's script sends, or in the cookie the
printed address (``/?token=...``) sets; a POST needs the header, and a JSON body of at most :data:`MAX_BODY` bytes.
Refusals are a 4xx with one JSON error. See ``docs/security.md``.

The session never writes over what it has not read: each request first compares
``corrections.json`` (its bytes) and ``result.npz`` (inode, size, time) with what it read,
and reads them again when they changed (a hand edit, a colleague's copy, another review
page, ``grainplug batch`` analysing the run again). An edit is appended to the file as it
is on disk.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import hmac
import io
import json
import logging
import os
import re
import secrets
import socket
import threading
import time
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, unquote

import numpy as np

from .._atomic import atomic_file
from ..corrections import CORRECTIONS_FILE, Corrections, Edit, apply_corrections, detection, replayed
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


#: what an edit sent by the page may hold (its time is the server's)
_EDIT_FIELDS = frozenset(f.name for f in dataclasses.fields(Edit)) - {"at"}


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
        detected_links = st.links if st is not None else detection(res, Corrections())[1]
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
                                               "oscillation_amplitude_mm", "oscillation_frequency_ci95_hz",
                                               "oscillation_amplitude_ci95_mm", "oscillation_kind",
                                               "oscillation_stick_fraction", "n_plugs", "n_edges_used")},
            "statement": res.statement, "warnings": list(res.warnings),
            "diagram": {"t0": float(t[0]), "t1": float(t[-1]), "n_frames": int(res.diagram.n_frames),
                        "z0": float(res.diagram.position_mm[0]), "z1": float(res.diagram.position_mm[-1]),
                        "fps": res.info.fps},
            "tracks": rows, "edges": edges,
            "corrections": [{"text": e.describe(), "at": e.at} for e in run.corrections.edits],
            "window": list(window), "no_plugs": [list(span) for span in spans],
            "blind": [b.as_dict() for b in res.blind],
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
        """Frame ``k`` of the analysis with the tube and the edges of that frame drawn on it, as the overlay video
        draws it (:func:`grainplug.overlay.draw_frame`: full resolution, its time, a scale bar, the tracks'
        numbers), in about 15 ms: fast enough to play 25 frames a second (matplotlib's figure took 70-100 ms)."""
        import cv2

        run = self.run(name)
        n = run.result.diagram.n_frames
        if not 0 <= k < n:
            raise ParameterError(f"frame {k} is outside the analysis (0 to {n - 1})")
        movie = self._movie(run)
        if movie is None:
            raise GrainplugError(run.movie_error or "no movie")
        from ..overlay import analysed_region, draw_frame, sensor_top

        with self._lock:  # one reader at a time
            frame = analysed_region(run.result, movie.read(run.offset + k))
        ok, png = cv2.imencode(".png", draw_frame(run.result, frame, k, top_value=sensor_top(run.result)),
                               [cv2.IMWRITE_PNG_COMPRESSION, 1])
        if not ok:
            raise GrainplugError(f"frame {k} could not be encoded as a PNG image")
        return png.tobytes()

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
        unknown = sorted(str(k) for k in edit if k not in _EDIT_FIELDS)  # "at", "on": not the page's to set
        if unknown:
            raise ParameterError(f"{edit['action']!s:.40}: unknown argument {', '.join(unknown)!s:.200}")
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

    def save(self, name: str, *, version: object = None) -> dict[str, object]:
        """Rewrite the run's outputs with the corrections (as ``grainplug remeasure``); returns what was written:
        ``{"folder": path, "files": [names], "corrections": number of edits applied}`` (the page says it)."""
        from ..workflows import remeasure

        run = self._check_version(name, version)
        with self._lock:
            since = time.time_ns() - 1_000_000_000  # file systems' times may be coarse (1 s at worst here)
            run.result = remeasure(run.folder)
            run.result_id, run.corrections_id = _result_id(run.folder), _corrections_id(run.folder)
            return {"folder": str(run.folder), "files": _written(run.folder, since),
                    "corrections": len(run.corrections.edits)}


def _written(folder: Path, since_ns: int) -> list[str]:
    """The files of ``folder`` written since ``since_ns`` (``time.time_ns()``): the outputs just rewritten (a user's
    files carried over, and ``corrections.json``, keep their times)."""
    names = []
    for p in folder.iterdir():
        with contextlib.suppress(OSError):
            if p.is_file() and not p.name.startswith(".") and p.stat().st_mtime_ns >= since_ns:
                names.append(p.name)
    return sorted(names)


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


#: the header the page sends its token in (``Authorization: token ...`` is taken too)
TOKEN_HEADER = "X-Grainplug-Token"
#: a POST body larger than this is refused unread (an edit is a few hundred bytes)
MAX_BODY = 64 * 1024
#: how long a closed connection waits for what its client still sends (see :func:`_linger`), s
LINGER_S = 1.0
#: the page's own policy: its script and style files only, no inline script, never framed
PAGE_POLICY = ("default-src 'self'; img-src 'self' data: blob:; script-src 'self'; style-src 'self'; "
               "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
#: every other answer (JSON, PNG, the refusals) is data, never a document
DATA_POLICY = "default-src 'none'; frame-ancestors 'none'; sandbox"
_STATIC = {"app.js": "text/javascript; charset=utf-8", "app.css": "text/css; charset=utf-8"}
_FRAME = re.compile(r"([0-9]{1,9})\.png", re.ASCII)
_LENGTH = re.compile(r"[0-9]{1,19}", re.ASCII)
_TOKEN_SLOT = b'<meta name="grainplug-token" content="">'
_FORBIDDEN_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>grainplug review: no access</title></head>
<body><h1>grainplug review</h1>
<p>This address needs the review's access token. Open the address printed by
<code>grainplug review</code> (it ends in <code>/?token=...</code>) in this browser.</p></body></html>
"""


class _Refused(Exception):
    """A request answered with a 4xx and nothing else done (``page``: the refusal is the HTML page's)."""

    def __init__(self, status: HTTPStatus, message: str, *, page: bool = False, allow: str = "") -> None:
        super().__init__(message)
        self.status, self.message, self.page, self.allow = status, message, page, allow


def _bounded_int(text: str) -> int:
    """A JSON integer of at most 15 digits (a track, a frame): larger ones are no such number, and overflow floats."""
    if len(text.lstrip("-")) > 15:
        raise ValueError(f"the number {text[:20]}... is too large")
    return int(text)


def _no_constant(name: str) -> object:
    raise ValueError(f"{name} is not JSON (numbers must be finite)")


def _same(given: str, token: bytes) -> bool:
    """Whether ``given`` is the token, compared in constant time."""
    return hmac.compare_digest(given.encode("utf-8", "surrogateescape"), token)


class _Handler(BaseHTTPRequestHandler):
    """The review's HTTP answers, each request checked first.

    Every request must name this server in its ``Host`` (``127.0.0.1:PORT`` or ``localhost:PORT``: a DNS-rebound
    name is refused), carry no foreign ``Origin`` nor come from another site's page (``Sec-Fetch-Site``), and carry
    the server's token: in the ``X-Grainplug-Token`` header (every request of the page's script, and the only way for
    a POST), in the cookie set at the first visit (the page's images), or in the ``?token=`` of the printed address
    (GET only). A POST must be ``application/json`` of at most :data:`MAX_BODY` bytes with its ``Content-Length``.
    Every refusal is a 4xx with one JSON error (the page's own: a short HTML page), and nothing is read or written.
    """

    session: ReviewSession  # set on the subclass made by ReviewServer
    token: str  # likewise: the server's token
    timeout = 60  # an idle connection is dropped after a minute
    server_version = "grainplug-review"

    def version_string(self) -> str:
        return self.server_version  # not Python's version

    # -- what http.server itself answers: malformed request lines, versions, unknown methods -------------------
    def log_message(self, fmt: str, *args: object) -> None:
        log.debug("review: %s", (fmt % args).replace(self.token, "<token>"))  # never the token in a log

    def parse_request(self) -> bool:
        ok = super().parse_request()
        if ok and self.request_version == "HTTP/0.9":  # an answer to it would have no status line
            self.send_error(HTTPStatus.BAD_REQUEST, "HTTP/0.9 requests are not answered: send HTTP/1.0 or 1.1")
            return False
        return ok

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals as one JSON error, always a 4xx: an unknown method is 405 (not 501),
        an HTTP version beyond 1.x is 400 (not 505)."""
        status = HTTPStatus(code)
        if status == HTTPStatus.NOT_IMPLEMENTED:
            self._refuse(_Refused(HTTPStatus.METHOD_NOT_ALLOWED, f"method {self.command!s:.40} is not allowed: "
                                  "GET or POST", allow="GET, POST"))
            return
        if status >= 500:
            status = HTTPStatus.BAD_REQUEST
        self._refuse(_Refused(status, message or status.phrase))

    # -- answers --------------------------------------------------------------------------------------------
    def _send(self, body: bytes, ctype: str, status: int = 200, *, headers: dict[str, str] | None = None,
              policy: str = DATA_POLICY) -> None:
        if self.request_version == "HTTP/0.9":  # answered with a status line, as 1.0
            self.request_version = "HTTP/1.0"
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("X-Frame-Options", "DENY")
        self.send_header("Content-Security-Policy", policy)
        self.send_header("Referrer-Policy", "no-referrer")  # the first address holds the token
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")  # no other page shows a frame or PNG
        self.send_header("Cross-Origin-Opener-Policy", "same-origin")
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data: object, status: int = 200, *, headers: dict[str, str] | None = None) -> None:
        self._send(dumps(data).encode(), "application/json", status, headers=headers)

    def _refuse(self, refused: _Refused) -> None:
        """A 4xx, and the connection closed (a body left unread is never taken for the next request)."""
        path = getattr(self, "path", "").partition("?")[0]  # never the token in a log
        log.info("review: refused %s %.200r: %s", self.command, path, refused.message)
        self.close_connection = True
        headers = {"Connection": "close"}
        if refused.allow:
            headers["Allow"] = refused.allow
        if refused.page:
            self._send(_FORBIDDEN_PAGE.encode(), "text/html; charset=utf-8", refused.status, headers=headers)
        else:
            self._json({"error": refused.message}, refused.status, headers=headers)

    def _error(self, exc: Exception, name: str = "") -> None:
        """A request the session could not do: 400 (its parameters), 409 (made on files changed since: with the
        state as it is now), 404 (what the run cannot show: its movie), 500 (a bug, logged)."""
        if isinstance(exc, StaleReview):  # the page shows what is on disk now
            body: dict[str, object] = {"error": exc.message}
            try:
                body["state"] = self.session.state(name)
            except (GrainplugError, ValueError) as again:
                body["error"] = f"{exc.message} ({again})"
            return self._json(body, HTTPStatus.CONFLICT)
        if isinstance(exc, ParameterError):
            return self._json({"error": exc.message}, HTTPStatus.BAD_REQUEST)
        if isinstance(exc, GrainplugError):
            return self._json({"error": str(exc)}, HTTPStatus.NOT_FOUND)
        if isinstance(exc, BrokenPipeError | ConnectionResetError):  # the page went away mid-answer (a reload)
            log.debug("review: %s %.200r: the client closed the connection", self.command, self.path)
            return None
        log.error("review: %s %.200r failed", self.command, self.path.partition("?")[0], exc_info=exc)
        self._json({"error": f"internal error ({type(exc).__name__}): see the log of grainplug review"},
                   HTTPStatus.INTERNAL_SERVER_ERROR)

    # -- the checks, in order: Host, Origin, Sec-Fetch-Site, token -------------------------------------------
    @property
    def _port(self) -> int:
        return int(self.server.server_address[1])

    def _one(self, name: str) -> str | None:
        """The request's ``name`` header (None without one); refused when it is given more than once."""
        values = self.headers.get_all(name) or []
        if len(values) > 1:
            raise _Refused(HTTPStatus.BAD_REQUEST, f"more than one {name} header")
        return values[0].strip() if values else None

    def _check_host(self) -> None:
        """Refuse a request for another host name: a page whose name was rebound to 127.0.0.1 (DNS rebinding)."""
        host = self._one("Host")
        if host is None or host.lower() not in (f"127.0.0.1:{self._port}", f"localhost:{self._port}"):
            raise _Refused(HTTPStatus.FORBIDDEN, f"this server answers requests for 127.0.0.1:{self._port} or "
                           f"localhost:{self._port} only, not for host {host!s:.100}")

    def _check_origin(self, page: bool) -> None:
        """Refuse what another page sends or loads: a foreign ``Origin``, or (``Sec-Fetch-Site``) a request made by
        another site's page (other ports of 127.0.0.1 included); a navigation to the page itself is let through
        (the token still decides)."""
        origin = self._one("Origin")
        if origin is not None and origin not in (f"http://127.0.0.1:{self._port}", f"http://localhost:{self._port}"):
            raise _Refused(HTTPStatus.FORBIDDEN, f"requests from another page ({origin:.100}) are refused")
        site = (self._one("Sec-Fetch-Site") or "").lower()
        navigate = (self._one("Sec-Fetch-Mode") or "").lower() == "navigate"
        if site in ("cross-site", "same-site") and not (page and navigate and self.command == "GET"):
            raise _Refused(HTTPStatus.FORBIDDEN, "requests from another site's page are refused")

    def _header_token(self) -> str | None:
        given = self._one(TOKEN_HEADER)
        if given is not None:
            return given
        scheme, _, value = (self._one("Authorization") or "").partition(" ")
        return value.strip() if scheme.lower() in ("token", "bearer") else None

    def _cookie_name(self) -> str:
        return f"grainplug-review-token-{self._port}"  # cookies are shared by the ports of a host

    def _cookie_tokens(self) -> list[str]:
        """Every value of the token cookie (a page of another port may have set one more of that name)."""
        found = []
        for header in self.headers.get_all("Cookie") or []:
            for part in header.split(";"):
                key, eq, value = part.strip().partition("=")
                if eq and key == self._cookie_name():
                    found.append(value.strip().strip('"'))
        return found

    def _authorise(self, query: str, page: bool) -> dict[str, str]:
        """Refuse a request without the token; the headers to answer with (the cookie, set by the first visit)."""
        token = self.token.encode()
        given = self._header_token()
        if given is not None and _same(given, token):
            return {}
        if self.command == "POST":  # a form or another page's fetch can send the cookie, never this header
            raise _Refused(HTTPStatus.FORBIDDEN, f"a change needs the page's token in the {TOKEN_HEADER} header")
        if any(_same(c, token) for c in self._cookie_tokens()):
            return {}
        try:
            asked = parse_qs(query, keep_blank_values=True, max_num_fields=20).get("token", [])
        except ValueError:
            asked = []
        if any(_same(a, token) for a in asked):
            return {"Set-Cookie": f"{self._cookie_name()}={self.token}; Path=/; HttpOnly; SameSite=Strict"}
        raise _Refused(HTTPStatus.FORBIDDEN, "no valid token: open the address printed by grainplug review "
                       "(it ends in /?token=...)", page=page)

    def _checked(self) -> tuple[list[str], dict[str, str]]:
        """The request's path as parts (percent-decoded), once every check passed; the headers to answer with."""
        self._check_host()
        target, _, query = self.path.partition("?")
        if not target.startswith("/"):
            raise _Refused(HTTPStatus.BAD_REQUEST, f"bad request target {self.path:.100}")
        parts = [unquote(p) for p in target.split("#")[0].strip("/").split("/")]
        page = parts in ([""], ["index.html"])
        self._check_origin(page)
        return parts, self._authorise(query, page)

    # -- the methods ------------------------------------------------------------------------------------------
    def do_GET(self) -> None:
        name = ""
        try:
            parts, headers = self._checked()
            s = self.session
            if parts in ([""], ["index.html"]):
                html = _static("index.html").replace(
                    _TOKEN_SLOT, f'<meta name="grainplug-token" content="{self.token}">'.encode())
                return self._send(html, "text/html; charset=utf-8", headers=headers, policy=PAGE_POLICY)
            if len(parts) == 1 and parts[0] in _STATIC:
                return self._send(_static(parts[0]), _STATIC[parts[0]], headers=headers)
            if parts == ["api", "runs"]:
                return self._json({"runs": list(s.targets)}, headers=headers)
            if parts == ["favicon.ico"]:
                return self._send(b"", "image/x-icon", HTTPStatus.NO_CONTENT)
            if len(parts) >= 4 and parts[:2] == ["api", "run"]:
                name, rest = parts[2], parts[3:]
                if rest == ["state"]:
                    return self._json(s.state(name), headers=headers)
                if rest == ["version"]:
                    return self._json(s.version(name), headers=headers)
                if rest == ["diagram.png"]:
                    return self._send(s.diagram_png(name), "image/png", headers=headers)
                frame = _FRAME.fullmatch(rest[1]) if len(rest) == 2 and rest[0] == "frame" else None
                if frame is not None:
                    return self._send(s.frame_png(name, int(frame.group(1))), "image/png", headers=headers)
            raise _Refused(HTTPStatus.NOT_FOUND, f"no such page {self.path:.200}")
        except _Refused as refused:
            self._refuse(refused)
        except Exception as exc:
            self._error(exc, name)

    def do_POST(self) -> None:
        name = ""
        try:
            parts, _ = self._checked()
            if not (len(parts) == 4 and parts[:2] == ["api", "run"] and parts[3] in ("edit", "undo", "save")):
                raise _Refused(HTTPStatus.NOT_FOUND, f"no such action {self.path:.200}")
            name, action = parts[2], parts[3]
            body = self._body()
            version = body.pop("version", None)
            if action == "edit":
                self.session.edit(name, body, version=version)
            elif action == "undo":
                self.session.undo(name, version=version)
            else:  # the page says what was written, and where
                saved = self.session.save(name, version=version)
                return self._json({**self.session.state(name), "saved": saved})
            self._json(self.session.state(name))
        except _Refused as refused:
            self._refuse(refused)
        except Exception as exc:
            self._error(exc, name)

    def _body(self) -> dict[str, Any]:
        """The POST's JSON object: ``application/json``, with a ``Content-Length`` of at most :data:`MAX_BODY`
        (refused unread otherwise), strict JSON (no ``NaN``, no integer over 15 digits)."""
        ctype = self._one("Content-Type") or ""
        if ctype.split(";")[0].strip().lower() != "application/json":
            raise _Refused(HTTPStatus.UNSUPPORTED_MEDIA_TYPE,
                           f"a change is sent as application/json, not {ctype or 'without a Content-Type'!s:.100}")
        if self.headers.get_all("Transfer-Encoding"):
            raise _Refused(HTTPStatus.LENGTH_REQUIRED, "send the body with a Content-Length, not chunked")
        length = self._one("Content-Length")
        if length is None:
            raise _Refused(HTTPStatus.LENGTH_REQUIRED, "a change needs its Content-Length")
        if not _LENGTH.fullmatch(length):
            raise _Refused(HTTPStatus.BAD_REQUEST, f"bad Content-Length {length:.40}")
        n = int(length)
        if n > MAX_BODY:
            raise _Refused(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"the body is over {MAX_BODY} bytes")
        raw = self.rfile.read(n) if n else b"{}"
        if len(raw) < n:
            raise _Refused(HTTPStatus.BAD_REQUEST, "the body is shorter than its Content-Length")
        try:
            body = json.loads(raw.decode("utf-8"), parse_int=_bounded_int, parse_constant=_no_constant)
        except (ValueError, RecursionError) as exc:
            raise _Refused(HTTPStatus.BAD_REQUEST, f"the body is not JSON: {exc}") from None
        if not isinstance(body, dict):
            raise _Refused(HTTPStatus.BAD_REQUEST, "the request's body must be a JSON object")
        return body


def _linger(sock: socket.socket) -> None:
    """Half-close ``sock``, then read for a moment what the client still sends (the body of a refused request)
    before it is closed: closed with unread input, the connection is reset, and the client may lose the answer."""
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_WR)
        sock.settimeout(LINGER_S)
        left = 4 * MAX_BODY
        while left > 0 and (chunk := sock.recv(min(65536, left))):
            left -= len(chunk)


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
        _linger(request)  # still in _open: close_connections ends it at once when the server stops
        with self._open_lock:
            self._open.discard(request)
        super().shutdown_request(request)

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A connection that failed (the client gone mid-answer): logged, and the server goes on."""
        log.debug("review: a connection from %s failed", client_address, exc_info=True)

    def close_connections(self) -> None:
        """End every open connection: their handlers see the end of input and finish."""
        with self._open_lock:
            open_now = list(self._open)
        for sock in open_now:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)


class ReviewServer:
    """The review page served on ``127.0.0.1:port`` from a thread (a context manager: stops it).

    Each server draws its own access token (:attr:`token`): every request must carry it, and the address to open,
    :attr:`url`, holds it. See :class:`_Handler` for every check a request passes, and ``docs/security.md``.

    Parameters
    ----------
    folder : path
        An analysis folder or a campaign's.
    port : int
        0 picks a free port (see :attr:`url`).
    """

    def __init__(self, folder: str | Path, *, port: int = 0) -> None:
        self.session = ReviewSession(folder)
        self.token = secrets.token_urlsafe(32)  # 32 random bytes
        handler = type("Handler", (_Handler,), {"session": self.session, "token": self.token})
        self.httpd = _Server(("127.0.0.1", port), handler)
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="grainplug-review", daemon=False)

    @property
    def base_url(self) -> str:
        """The server's address without its token (``http://127.0.0.1:PORT/``): what the page's requests are
        relative to; opened as is, it is refused."""
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/"

    @property
    def url(self) -> str:
        """The address to open: :attr:`base_url` with the token (``http://127.0.0.1:PORT/?token=...``)."""
        return f"{self.base_url}?token={self.token}"

    @property
    def headers(self) -> dict[str, str]:
        """The header that authorises a request made from a script (``{"X-Grainplug-Token": token}``)."""
        return {TOKEN_HEADER: self.token}

    def __enter__(self) -> ReviewServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.httpd.shutdown()
        self._thread.join()
        self.httpd.close_connections()
        self.httpd.server_close()  # joins the request threads
        self.session.close()
