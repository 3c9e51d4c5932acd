"""grainplug review on a shared machine: the token, the Host allow-list, other pages' requests, hostile input.

The threat model is docs/security.md's ("The review page"): another user of the machine reaches the port; a page of
another origin open in the same browser sends requests to it (CSRF), or has its name rebound to 127.0.0.1 (DNS
rebinding). Every refusal must be a 4xx with one JSON error, change nothing on disk, and leave the server serving.
"""

from __future__ import annotations

import contextlib
import http.client
import http.server
import json
import logging
import os
import re
import shutil
import socket
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_review import CHROMIUM, analysis, chromium_page  # noqa: F401  (analysis: the module's fixture)

from grainplug.corrections import Corrections
from grainplug.review import ReviewServer
from grainplug.store import read_corrections

EXCLUDE = b'{"action": "exclude", "track": 0}'
FUZZ_EXAMPLES = int(os.environ.get("GRAINPLUG_FUZZ_EXAMPLES", "500"))


@pytest.fixture
def folder(analysis: Path, tmp_path: Path) -> Path:  # noqa: F811
    """A fresh copy of the analysis for a test that may be written to."""
    dst = tmp_path / "run1"
    shutil.copytree(analysis, dst)
    return dst


@dataclass
class Answer:
    status: int
    headers: http.client.HTTPMessage
    body: bytes

    def error(self) -> str:
        """The refusal's message: the body must be one JSON object ``{"error": ...}``."""
        data = json.loads(self.body)
        assert isinstance(data, dict) and isinstance(data.get("error"), str) and data["error"], data
        return data["error"]


def port(srv: ReviewServer) -> int:
    return int(srv.httpd.server_address[1])


def ask(srv: ReviewServer, method: str, path: str, *, body: bytes | None = None, token: bool = True,
        headers: dict[str, str] | None = None) -> Answer:
    """One request over http.client: by default with the server's own Host and its token in the header."""
    h = {"Host": f"127.0.0.1:{port(srv)}"}
    if token:
        h.update(srv.headers)
    if body is not None:
        h["Content-Type"] = "application/json"
    h.update(headers or {})
    h = {k: v for k, v in h.items() if v is not None}
    conn = http.client.HTTPConnection("127.0.0.1", port(srv), timeout=20)
    try:
        conn.request(method, path, body=body, headers=h)
        r = conn.getresponse()
        return Answer(r.status, r.headers, r.read())
    finally:
        conn.close()


def raw(srv: ReviewServer, data: bytes) -> bytes:
    """Send ``data`` as is, close the sending side, and read the whole answer."""
    with socket.create_connection(("127.0.0.1", port(srv)), timeout=20) as s:
        s.sendall(data)
        with contextlib.suppress(OSError):  # the server may have answered and closed already
            s.shutdown(socket.SHUT_WR)
        out = b""
        with contextlib.suppress(ConnectionResetError):
            while chunk := s.recv(65536):
                out += chunk
    return out


def status_of(answer: bytes) -> int:
    """The final status of a raw answer (an interim ``100 Continue`` skipped)."""
    while answer.startswith(b"HTTP/1.1 100") or answer.startswith(b"HTTP/1.0 100"):
        answer = answer.split(b"\r\n\r\n", 1)[1]
    line = answer.split(b"\r\n", 1)[0].split()
    assert len(line) >= 2 and line[0].startswith(b"HTTP/1."), answer[:200]
    return int(line[1])


def on_disk(folder: Path) -> dict[str, bytes | None]:
    """What a refused request must leave as it was: the corrections and the run's outputs (bytes)."""
    names = ["corrections.json", "summary.json", "result.npz", "tracks.csv"]
    return {n: (folder / n).read_bytes() if (folder / n).exists() else None for n in names}


def still_serving(srv: ReviewServer) -> None:
    """A good request is answered after whatever came before."""
    a = ask(srv, "GET", "/api/runs")
    assert a.status == 200 and json.loads(a.body) == {"runs": ["run1"]}


# -- the token ---------------------------------------------------------------------------------------------------
def test_each_server_draws_its_own_token_and_prints_it_in_its_address(folder):
    with ReviewServer(folder) as a, ReviewServer(folder) as b:
        for srv in (a, b):
            assert len(srv.token) >= 43  # secrets.token_urlsafe(32): 32 random bytes
            assert srv.url == f"http://127.0.0.1:{port(srv)}/?token={srv.token}"
            assert srv.token not in srv.base_url
        assert a.token != b.token


def test_no_token_no_answer(folder):
    """Without the token, or with another, nothing is answered: the page is a 403 saying to open the printed
    address (no data), and every API request, frame and PNG a 403 JSON error; POSTs write nothing."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        wrong = "x" + srv.token[1:]
        for path in ("/", "/index.html", "/?token=" + wrong):
            a = ask(srv, "GET", path, token=False)
            assert a.status == 403 and a.headers["Content-Type"].startswith("text/html")
            assert b"grainplug review" in a.body and b"run1" not in a.body and srv.token.encode() not in a.body
            assert "Set-Cookie" not in a.headers
        ways = [{}, {"X-Grainplug-Token": wrong}, {"X-Grainplug-Token": ""}, {"Authorization": f"token {wrong}"},
                {"Cookie": f"grainplug-review-token-{port(srv)}={wrong}"}, {"X-Grainplug-Token": "é" + srv.token}]
        for headers in ways:
            for path in ("/api/runs", "/api/run/run1/state", "/api/run/run1/version", "/api/run/run1/diagram.png",
                         "/api/run/run1/frame/3.png", f"/api/run/run1/state?token={wrong}"):
                a = ask(srv, "GET", path, token=False, headers=headers)
                assert a.status == 403 and "token" in a.error(), (path, headers)
                assert a.headers["Content-Type"] == "application/json"
            for action in ("edit", "undo", "save"):
                a = ask(srv, "POST", f"/api/run/run1/{action}", body=EXCLUDE, token=False, headers=headers)
                assert a.status == 403, (action, headers)
                a.error()
        still_serving(srv)
    assert on_disk(folder) == before


def test_the_token_s_ways_in(folder):
    """The header (or ``Authorization: token``) authorises anything; the printed address's ``?token=`` authorises
    a GET and sets the cookie (HttpOnly, SameSite=Strict, Path=/) that authorises the page's later GETs."""
    with ReviewServer(folder) as srv:
        assert ask(srv, "GET", "/api/run/run1/state").status == 200
        assert ask(srv, "GET", "/api/runs", token=False, headers={"Authorization": f"token {srv.token}"}).status == 200
        first = ask(srv, "GET", "/?token=" + srv.token, token=False)
        assert first.status == 200 and first.headers["Content-Type"].startswith("text/html")
        cookie = first.headers["Set-Cookie"]
        attributes = {p.strip().lower() for p in cookie.split(";")[1:]}
        assert attributes == {"path=/", "httponly", "samesite=strict"}
        pair = cookie.split(";")[0]
        assert pair.split("=", 1)[1] == srv.token
        for path in ("/", "/app.js", "/app.css", "/api/run/run1/state", "/api/run/run1/diagram.png",
                     "/api/run/run1/frame/3.png"):
            assert ask(srv, "GET", path, token=False, headers={"Cookie": f"other=1; {pair}"}).status == 200, path
        # a cookie of the same name set by a page of another port of 127.0.0.1 does not lock the page out
        tossed = f"{pair.split('=')[0]}=forged; {pair}"
        assert ask(srv, "GET", "/api/runs", token=False, headers={"Cookie": tossed}).status == 200


def test_a_cookie_or_the_address_alone_cannot_write(folder):
    """A POST needs the token in its header: the cookie (which a form or another page's fetch would carry) and
    the address's ``?token=`` do not authorise it."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        cookie = {"Cookie": f"grainplug-review-token-{port(srv)}={srv.token}"}
        for action in ("edit", "undo", "save"):
            assert ask(srv, "POST", f"/api/run/run1/{action}", body=EXCLUDE, token=False, headers=cookie).status == 403
            assert ask(srv, "POST", f"/api/run/run1/{action}?token={srv.token}", body=EXCLUDE,
                       token=False).status == 403
        still_serving(srv)
    assert on_disk(folder) == before


# -- Host, Origin, Sec-Fetch-Site -----------------------------------------------------------------------------------
@pytest.mark.parametrize("path", ["/", "/?token=TOKEN", "/api/runs", "/api/run/run1/state", "/api/run/run1/version",
                                  "/api/run/run1/diagram.png", "/api/run/run1/frame/3.png", "/app.js"])
def test_a_foreign_host_is_refused(folder, path):
    """DNS rebinding: a request naming another host is refused, even with the token (header, cookie, address)."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        p = port(srv)
        path = path.replace("TOKEN", srv.token)
        cookie = f"grainplug-review-token-{p}={srv.token}"
        for host in (f"evil.example:{p}", "evil.example", f"127.0.0.1:{p + 1}", "127.0.0.1", f"127.0.0.2:{p}",
                     f"[::1]:{p}", f"0.0.0.0:{p}", f"localhost.evil.example:{p}", f"127.0.0.1:{p}.evil", ""):
            a = ask(srv, "GET", path, headers={"Host": host, "Cookie": cookie})
            assert a.status == 403 and "host" in a.error(), host
            assert a.headers["Content-Type"] == "application/json" and "Set-Cookie" not in a.headers
            a = ask(srv, "POST", "/api/run/run1/edit", body=EXCLUDE, headers={"Host": host, "Cookie": cookie})
            assert a.status == 403, host
        # no Host at all (HTTP/1.0), and two of them
        answer = raw(srv, f"GET {path} HTTP/1.0\r\nX-Grainplug-Token: {srv.token}\r\n\r\n".encode())
        assert status_of(answer) == 403
        answer = raw(srv, f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{p}\r\nHost: evil.example\r\n"
                          f"X-Grainplug-Token: {srv.token}\r\n\r\n".encode())
        assert status_of(answer) in (400, 403)
        for host in (f"127.0.0.1:{p}", f"localhost:{p}", f"LOCALHOST:{p}"):
            assert ask(srv, "GET", "/api/runs", headers={"Host": host}).status == 200
    assert on_disk(folder) == before


def test_another_page_s_requests_are_refused(folder):
    """A POST with the right token and cookie but a foreign Origin, or sent by another site's page
    (Sec-Fetch-Site, which covers the other ports of 127.0.0.1), is refused; the page's own origin is not."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        p = port(srv)
        cookie = {"Cookie": f"grainplug-review-token-{p}={srv.token}"}
        for origin in ("http://evil.example", f"http://127.0.0.1:{p + 1}", f"https://127.0.0.1:{p}", "null",
                       f"http://localhost:{p}.evil.example", f"http://127.0.0.1:{p}/"):
            for action in ("edit", "undo", "save"):
                a = ask(srv, "POST", f"/api/run/run1/{action}", body=EXCLUDE, headers={**cookie, "Origin": origin})
                assert a.status == 403 and "another page" in a.error(), (origin, action)
            assert ask(srv, "GET", "/api/run/run1/state", headers={"Origin": origin}).status == 403
        for site in ("cross-site", "same-site"):
            a = ask(srv, "POST", "/api/run/run1/edit", body=EXCLUDE, headers={**cookie, "Sec-Fetch-Site": site})
            assert a.status == 403, site
            for path in ("/api/run/run1/state", "/api/run/run1/frame/3.png"):  # an <img> or fetch of another page
                a = ask(srv, "GET", path, token=False, headers={**cookie, "Sec-Fetch-Site": site,
                                                                "Sec-Fetch-Mode": "no-cors"})
                assert a.status == 403, (site, path)
        assert on_disk(folder) == before
        # the page's own requests
        for origin in (f"http://127.0.0.1:{p}", f"http://localhost:{p}"):
            a = ask(srv, "GET", "/api/run/run1/state", headers={"Origin": origin, "Sec-Fetch-Site": "same-origin"})
            assert a.status == 200
        a = ask(srv, "POST", "/api/run/run1/edit", body=EXCLUDE,
                headers={**cookie, "Origin": f"http://127.0.0.1:{p}", "Sec-Fetch-Site": "same-origin"})
        assert a.status == 200
    assert read_corrections(folder).edits[0].action == "exclude"


# -- the POST's body ----------------------------------------------------------------------------------------------
def test_a_change_is_small_json_with_its_length(folder):
    """text/plain (what a form or a simple cross-origin fetch sends), form encodings, no or a bad Content-Length,
    chunked, too large a body: refused with a JSON error, before the body is read; nothing written."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        for ctype in ("text/plain", "text/plain; charset=utf-8", "application/x-www-form-urlencoded",
                      "multipart/form-data; boundary=x", "application/jsonx", "", "application/json-patch+json"):
            a = ask(srv, "POST", "/api/run/run1/edit", body=EXCLUDE, headers={"Content-Type": ctype})
            assert a.status == 415 and "application/json" in a.error(), ctype
        a = ask(srv, "POST", "/api/run/run1/edit", body=None, headers={"Content-Type": None})
        assert a.status in (411, 415)
        p, tok = port(srv), srv.token
        head = f"POST /api/run/run1/edit HTTP/1.1\r\nHost: 127.0.0.1:{p}\r\nX-Grainplug-Token: {tok}\r\n" \
               "Content-Type: application/json\r\n"
        cases = {"": 411, "Transfer-Encoding: chunked\r\n": 411, "Content-Length: abc\r\n": 400,
                 "Content-Length: -1\r\n": 400, "Content-Length: 1e3\r\n": 400, "Content-Length: 0x20\r\n": 400,
                 f"Content-Length: {10 ** 30}\r\n": 400, "Content-Length: 65537\r\n": 413,
                 "Content-Length: 99999999999\r\n": 413, "Content-Length: 33\r\nContent-Length: 34\r\n": 400,
                 "Content-Length: 100\r\n": 400}  # shorter than said
        for extra, status in cases.items():
            body = EXCLUDE if "chunked" not in extra else b"21\r\n" + EXCLUDE + b"\r\n0\r\n\r\n"
            assert status_of(raw(srv, (head + extra + "\r\n").encode() + body)) == status, extra
        # a body over the limit is not read: the refusal comes while the client is still sending
        with socket.create_connection(("127.0.0.1", p), timeout=20) as s:
            s.sendall((head + f"Content-Length: {10 ** 9}\r\n\r\n").encode() + b" " * 65536)
            assert status_of(s.recv(65536)) == 413
        big = b'{"action": "exclude", "track": 0, "pad": "' + b"x" * 70_000 + b'"}'
        assert ask(srv, "POST", "/api/run/run1/edit", body=big).status == 413
        for body in (b"{", b"[1, 2]", b'"x"', b"null", b"3", b'{"action": "window", "start_s": NaN}',
                     b'{"action": "window", "start_s": Infinity}', b"\xff\xfe{}", b"[" * 20_000 + b"]" * 20_000,
                     b'{"action": "exclude", "track": 1' + b"0" * 30 + b"}"):
            a = ask(srv, "POST", "/api/run/run1/edit", body=body)
            assert a.status in (400, 413), body[:40]
            a.error()
        still_serving(srv)
        assert on_disk(folder) == before
        a = ask(srv, "POST", "/api/run/run1/edit", body=EXCLUDE,
                headers={"Content-Type": "Application/JSON; charset=utf-8"})
        assert a.status == 200
    assert read_corrections(folder).edits[0].action == "exclude"


HOSTILE_GETS = ["/api/run/%00/state", "/api/run/x/frame/-1.png", "/api/run/run1/frame/-1.png",
                "/api/run/run1/frame/1e99.png", "/api/run/run1/frame/99999999999999999999.png",
                "/api/run/run1/frame/120.png", "/api/run/run1/frame/%D9%A3.png", "/api/run/run1/frame/3%00.png",
                "/api/run/run1/frame/3.png/x", "/api/run/run1/frame/3", "/api/run/..%2f..%2fetc/state",
                "/api/run/%2e%2e/state", "/../../../etc/passwd", "/static/../server.py", "/%2e%2e/%2e%2e/etc/passwd",
                "/api/run/run1/%2e%2e/%2e%2e/result.npz", "/api/run/run1/result.npz", "/api/run//state",
                "/api/run/run1", "/api", "/api/runs/x", "/index.html/x", "/app.js/x", "/%", "/%zz",
                "/api/run/%ff%fe/state", "/" + "a" * 5000, "/x?" + "&".join(["a=1"] * 100),
                "http://127.0.0.1/api/runs", "*", "/api/run/run1/nope#frag"]
HOSTILE_EDITS = [b'{"action": [], "track": {}}', b'{"action": {}, "track": 1}', b'{"action": null}',
                 b'{"action": "exclude", "track": {}}', b'{"action": "exclude", "track": []}',
                 b'{"action": "exclude", "track": "3"}', b'{"action": "exclude", "track": true}',
                 b'{"action": "exclude", "track": 1e999}', b'{"action": "exclude", "track": -1e999}',
                 b'{"action": "exclude", "track": 1e300}', b'{"action": "exclude", "track": 999999999999999}',
                 b'{"action": "exclude", "track": -5}', b'{"action": "exclude", "track": 0.5}',
                 b'{"action": "exclude", "track": 1, "on": 1}', b'{"action": "exclude", "track": 1, "at": [1]}',
                 b'{"action": "exclude", "track": 1, "extra": 1}', b'{"action": "exclude", "track": 1, "version": 7}',
                 b'{"action": "exclude", "track": 1, "version": {"result": []}}',
                 b'{"action": "split", "track": 0, "frame": 999999999}', b'{"action": "split", "track": 0}',
                 b'{"action": "merge", "track": 0, "other": 0}', b'{"action": "window", "start_s": "0.2"}',
                 b'{"action": "window", "start_s": 1e308, "end_s": -1e308}', b'{"action": "no_plugs"}',
                 b'{"action": "no_plugs", "start_s": 0.1, "end_s": [1]}', b'{"action": "<script>alert(1)</script>"}',
                 b'{"action": "exclude", "track": 1, "__proto__": {}}', b'{}', b'{"version": null}']


def test_hostile_input_is_a_4xx_and_changes_nothing(folder):
    """Bad paths (NUL, traversal, negative, huge or non-ASCII frame numbers), edits with wrong types, unknown
    methods, malformed request lines and HTTP versions: a 4xx with a JSON error each, never a 5xx, nothing
    written, and the server goes on serving."""
    before = on_disk(folder)
    with ReviewServer(folder) as srv:
        for path in HOSTILE_GETS:
            a = ask(srv, "GET", path)
            assert 400 <= a.status < 500, (path, a.status, a.body[:200])
            a.error()
        for body in HOSTILE_EDITS:
            a = ask(srv, "POST", "/api/run/run1/edit", body=body)
            assert 400 <= a.status < 500, (body, a.status, a.body[:200])
            a.error()
        for action in ("undo", "nope", "edit/x", "../edit", "state"):
            a = ask(srv, "POST", f"/api/run/run1/{action}", body=b"{}")
            assert 400 <= a.status < 500, action
            a.error()
        for method in ("PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "FOO", "get", "PROPFIND"):
            a = ask(srv, method, "/api/run/run1/edit", body=EXCLUDE)
            assert a.status == 405 and "GET or POST" in a.error(), method
            assert a.headers["Allow"] == "GET, POST"
        a = ask(srv, "HEAD", "/api/runs")
        assert a.status == 405 and a.body == b""
        p = port(srv)
        for line in (b"GET / HTTP/2.0", b"GET / HTTP/1.x", b"GET / HTTP/1", b"GET / FTP/1.0", b"GET /",
                     b"POST /api/run/run1/edit", b"GET / HTTP/1.1 extra", b"GARBAGE", b"G\x00T / HTTP/1.1",
                     b"GET /\xff\xfe HTTP/1.1", b"GET " + b"/a" * 40_000 + b" HTTP/1.1", b"GET / HTTP/01.01",
                     b"GET / HTTP/1.1" + b"\r\nX: y" * 150):
            answer = raw(srv, line + f"\r\nHost: 127.0.0.1:{p}\r\nX-Grainplug-Token: {srv.token}\r\n\r\n".encode())
            assert 400 <= status_of(answer) < 500 or status_of(answer) == 200, (line[:40], answer[:200])
        assert raw(srv, b"\r\n") == b""  # an empty request: no answer, and no harm
        assert raw(srv, b"") == b""
        still_serving(srv)
    assert on_disk(folder) == before


def test_every_answer_carries_the_security_headers(folder):
    """nosniff, no framing, no referrer (the first address holds the token), same-origin resources; the page's
    Content-Security-Policy allows its own script and style files only (no inline script or style)."""
    with ReviewServer(folder) as srv:
        page = ask(srv, "GET", "/")
        policy = {d.split()[0]: d.split()[1:] for d in page.headers["Content-Security-Policy"].split(";")
                  if d.strip()}
        assert policy["default-src"] == ["'self'"] and policy["script-src"] == ["'self'"]
        assert policy["style-src"] == ["'self'"] and policy["frame-ancestors"] == ["'none'"]
        assert set(policy["img-src"]) <= {"'self'", "data:", "blob:"}
        assert "unsafe-inline" not in page.headers["Content-Security-Policy"]
        assert b"<script>" not in page.body and b"<style" not in page.body
        assert not re.search(rb"\son[a-z]+\s*=", page.body) and not re.search(rb"\sstyle\s*=", page.body)
        answers = [page, ask(srv, "GET", "/app.js"), ask(srv, "GET", "/api/run/run1/state"),
                   ask(srv, "GET", "/api/run/run1/diagram.png"), ask(srv, "GET", "/api/run/run1/frame/2.png"),
                   ask(srv, "GET", "/api/runs", token=False), ask(srv, "GET", "/", token=False),
                   ask(srv, "GET", "/api/runs", headers={"Host": "evil.example"}),
                   ask(srv, "POST", "/api/run/run1/edit", body=b"[]"), ask(srv, "DELETE", "/")]
        for a in answers:
            assert a.headers["X-Content-Type-Options"] == "nosniff"
            assert a.headers["X-Frame-Options"] == "DENY"
            assert "frame-ancestors 'none'" in a.headers["Content-Security-Policy"]
            assert a.headers["Referrer-Policy"] == "no-referrer"
            assert a.headers["Cross-Origin-Resource-Policy"] == "same-origin"
            assert a.headers["Cache-Control"] == "no-store"


# -- fuzzing the HTTP API -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fuzzed(analysis, tmp_path_factory) -> Iterator[tuple[ReviewServer, Path]]:  # noqa: F811
    """One server for every fuzzing example (it must keep serving through all of them)."""
    folder = tmp_path_factory.mktemp("fuzz") / "run1"
    shutil.copytree(analysis, folder)
    with ReviewServer(folder) as srv:
        yield srv, folder


SEGMENTS = st.sampled_from(["api", "run", "run1", "state", "version", "diagram.png", "frame", "3.png", "-1.png",
                            "1e99.png", "edit", "undo", "save", "runs", "index.html", "app.js", "..", ".", "%2e%2e",
                            "%2F", "%00", "%ff", "%", "", "a" * 300, "99999999999999999999.png", "\u0663.png"])
PATHS = st.one_of(
    st.sampled_from(["/", "/api/runs", "/api/run/run1/state", "/api/run/run1/version", "/api/run/run1/edit",
                     "/api/run/run1/undo", "/api/run/run1/frame/5.png", "/api/run/run1/diagram.png"]),
    st.lists(SEGMENTS, max_size=6).map(lambda parts: "/" + "/".join(parts)),
    st.integers(-10, 10 ** 12).map(lambda k: f"/api/run/run1/frame/{k}.png"),
    st.text(st.characters(min_codepoint=0x21, max_codepoint=0x2FF), max_size=40).map(lambda s: "/" + s),
)
JSON_VALUES = st.recursive(st.none() | st.booleans() | st.integers(-10 ** 20, 10 ** 20)
                           | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=20),
                           lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                          max_size=3), max_leaves=8)
EDITS = st.fixed_dictionaries(
    {"action": st.sampled_from(["exclude", "restore", "merge", "split", "window", "no_plugs", "clear_no_plugs",
                                "explode"]) | JSON_VALUES},
    optional={"track": st.integers(-2, 8) | JSON_VALUES, "other": st.integers(-2, 8) | JSON_VALUES,
              "frame": st.integers(-2, 130) | JSON_VALUES, "start_s": st.floats(-1, 1) | JSON_VALUES,
              "end_s": st.floats(-1, 1) | JSON_VALUES, "version": JSON_VALUES, "at": JSON_VALUES,
              "on": JSON_VALUES})
BODIES = st.one_of(EDITS.map(lambda d: json.dumps(d).encode()), JSON_VALUES.map(lambda v: json.dumps(v).encode()),
                   st.binary(max_size=200), st.just(b""))


GOOD_EDITS = st.fixed_dictionaries(
    {"action": st.sampled_from(["exclude", "restore", "merge", "split", "window", "no_plugs", "clear_no_plugs"])},
    optional={"track": st.integers(0, 8), "other": st.integers(0, 8), "frame": st.integers(0, 119),
              "start_s": st.floats(0, 0.5), "end_s": st.floats(0, 0.5)}).map(lambda d: json.dumps(d).encode())


@st.composite
def requests(draw: st.DrawFn, p: int, token: str) -> tuple[bytes, bool]:
    """A raw request: a good one (authorised, well formed: it reaches the session and may write) with each of its
    parts made hostile now and then; and whether it may write (a POST with the token in its header)."""
    def hostile() -> bool:  # each part, about one time in seven: about a third of the requests are good
        return draw(st.integers(0, 6)) == 0

    method = draw(st.sampled_from(["PUT", "DELETE", "OPTIONS", "HEAD", "PATCH", "TRACE", "FOO", "get", "G\tT"])
                  if hostile() else st.sampled_from(["GET", "POST"]))
    good_paths = ["/api/run/run1/edit"] * 8 + ["/api/run/run1/undo"] * 2 + ["/api/run/run1/save"] if method == "POST" \
        else ["/", "/app.js", "/api/runs", "/api/run/run1/state", "/api/run/run1/version", "/api/run/run1/frame/5.png",
              "/api/run/run1/diagram.png"]
    path = draw(PATHS if hostile() else st.sampled_from(good_paths))
    if hostile():
        path += "?" + draw(st.sampled_from([f"token={token}", "token=x", "token=", "a=%ff&token=" + token, "%%",
                                            "&".join(["a=1"] * 30)]))
    version = draw(st.sampled_from(["HTTP/2.0", "HTTP/0.9", "HTTP/1.x", "HTTP/3", "", "HTTP/1.1 x", "HTTP/1"])
                   if hostile() else st.sampled_from(["HTTP/1.1", "HTTP/1.0"]))
    headers = []
    host = draw(st.sampled_from([f"localhost:{p}", "evil.example", f"127.0.0.1:{p + 1}", None, f"evil.example:{p}",
                                 f"127.0.0.1:{p}\r\nHost: evil.example"]) if hostile() else st.just(f"127.0.0.1:{p}"))
    if host is not None:
        headers.append(f"Host: {host}")
    auth = draw(st.sampled_from(["cookie", "bad", "none", "authorization", "query"])) if hostile() else "header"
    headers.append({"header": f"X-Grainplug-Token: {token}", "cookie": f"Cookie: grainplug-review-token-{p}={token}",
                    "bad": "X-Grainplug-Token: nope", "none": "X-None: 1", "query": "X-None: 2",
                    "authorization": f"Authorization: token {token}"}[auth])
    if auth == "query":
        path += ("&" if "?" in path else "?") + f"token={token}"
    if hostile():
        headers.append(draw(st.sampled_from([f"Origin: http://127.0.0.1:{p}", "Origin: http://evil.example",
                                             "Origin: null", "Sec-Fetch-Site: cross-site", "Sec-Fetch-Site: same-site",
                                             "Sec-Fetch-Site: same-origin", "Expect: 100-continue", "Cookie: a=%ff;;=",
                                             "X-Grainplug-Token: \u00e9", "Content-Length: 5"])))
    body = b""
    if method != "GET" or hostile():
        body = draw(BODIES if hostile() else GOOD_EDITS)
    ctype = draw(st.sampled_from(["text/plain", None, "multipart/form-data", "application/json-seq"])
                 if hostile() else st.sampled_from(["application/json", "application/json; charset=utf-8"]))
    if ctype is not None:
        headers.append(f"Content-Type: {ctype}")
    length = draw(st.sampled_from(["none", "-1", "abc", "999999", "1", "chunked", "+5", " 5"])) if hostile() \
        else "right"
    if length == "right":
        headers.append(f"Content-Length: {len(body)}")
    elif length == "chunked":
        headers.append("Transfer-Encoding: chunked")
    elif length != "none":
        headers.append(f"Content-Length: {length}")
    head = f"{method} {path} {version}".rstrip() + "\r\n" + "".join(h + "\r\n" for h in headers) + "\r\n"
    return head.encode("utf-8") + body, method == "POST" and auth in ("header", "authorization")


@settings(max_examples=FUZZ_EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(data=st.data())
def test_fuzzed_requests_are_answered_2xx_or_4xx_and_the_corrections_stay_valid(fuzzed, data):
    """Whatever the request (path, percent-encodings, traversal, method, version, headers, body): a 2xx or a 4xx,
    never a 5xx; the server answers a good request afterwards; corrections.json, when there is one, is valid JSON
    that grainplug.corrections reads; and a request without the token in its header never changes it."""
    srv, folder = fuzzed
    request, may_write = data.draw(requests(port(srv), srv.token))
    before = on_disk(folder)["corrections.json"]
    answer = raw(srv, request)
    status = status_of(answer)
    assert 200 <= status < 500, (request[:300], answer[:300])
    head, _, payload = answer.partition(b"\r\n\r\n")
    if status >= 400 and b"Content-Type: text/html" in head:  # the page's own refusal: no data, no token
        assert status == 403 and b"run1" not in payload and srv.token.encode() not in payload
    elif status >= 400 and not request.startswith(b"HEAD "):
        assert isinstance(json.loads(payload)["error"], str)  # one JSON error
    after = on_disk(folder)["corrections.json"]
    if not may_write or status >= 400:
        assert after == before
    if after is not None:
        assert isinstance(read_corrections(folder), Corrections)
    event(f"answered {status // 100}xx" + (", corrections.json written" if after != before else ""))
    still_serving(srv)


# -- in Chromium --------------------------------------------------------------------------------------------------
needs_chromium = pytest.mark.skipif(CHROMIUM is None,
                                    reason="Debian's chromium is not installed (scripts/ensure_chromium.sh)")


@contextlib.contextmanager
def hostile_site(html: str) -> Iterator[str]:
    """A page of another origin (another port of 127.0.0.1: the same site, so the browser sends the review's
    SameSite cookie with its requests): its address."""
    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=httpd.serve_forever)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    finally:
        httpd.shutdown()
        thread.join()
        httpd.server_close()


@needs_chromium
def test_the_page_works_through_its_printed_address(folder):
    """Open the printed address: the page loads, drops the token from the address bar, shows the run, its frames
    and an edit; reloaded from the bare address (the cookie), it still works; the token opens nothing elsewhere."""
    sync_api = pytest.importorskip("playwright.sync_api")
    errors: list[str] = []
    with (ReviewServer(folder) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--disable-background-networking", errors=errors) as page):
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        assert page.url == srv.base_url  # the token is not left in the address bar
        assert page.evaluate("() => Array.from(document.getElementById('run').options).map((o) => o.value)") \
            == ["run1"]
        box = page.locator("#diagram").bounding_box()
        page.mouse.click(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"])
        page.wait_for_function("() => { const i = document.getElementById('frame');"
                               " return i.complete && i.naturalWidth > 0; }", timeout=20_000)
        tid = page.locator("#tracks tbody tr").first.get_attribute("data-track")
        page.locator(f"#tracks tbody tr[data-track='{tid}'] button").click()
        page.wait_for_selector("#tracks tbody tr.excluded", timeout=20_000)
        assert f"excluded track {tid}" in page.inner_text("#corrections")
        page.reload()
        page.wait_for_selector("#tracks tbody tr.excluded", timeout=20_000)
        answer = page.goto(srv.base_url + "api/run/run1/state")  # the browser's own GET carries the cookie
        assert answer is not None and answer.status == 200 and answer.json()["run"] == "run1"
    assert errors == []
    assert [e.action for e in read_corrections(folder).edits] == ["exclude"]


@needs_chromium
def test_the_page_shows_hostile_text_as_text(analysis, tmp_path):  # noqa: F811
    """A run named like HTML and a hand-edited corrections.json with HTML in it: shown as text, no element made,
    no script run."""
    sync_api = pytest.importorskip("playwright.sync_api")
    name = "<img src=x onerror=window.pwned=1>"
    camp = tmp_path / "camp"
    shutil.copytree(analysis, camp / "runs" / name)
    (camp / "runs" / name / "corrections.json").write_text(json.dumps(
        {"format": "grainplug-corrections", "format_version": 2,
         "edits": [{"action": "window", "start_s": 0.01, "at": "<img src=y onerror=window.pwned=2><b>bold</b>"}]}))
    with (ReviewServer(camp) as srv, sync_api.sync_playwright() as p, chromium_page(p) as page):
        page.goto(srv.url)
        page.wait_for_selector("#corrections small", timeout=20_000)
        assert page.evaluate("() => document.getElementById('run').options[0].textContent") == name
        assert "<b>bold</b>" in page.inner_text("#corrections")
        assert page.evaluate("() => document.querySelectorAll('#corrections img, #corrections b, #run img').length") \
            == 0
        assert page.evaluate("() => window.pwned === undefined")


HOSTILE_PAGE = """<!DOCTYPE html><html><body>
<iframe name="f1"></iframe><iframe name="f2"></iframe><iframe name="f3"></iframe>
<form id="edit" method="POST" action="{base}api/run/run1/edit" enctype="text/plain" target="f1">
<input name='{{"action": "exclude", "track": 0, "x": "' value='"}}'></form>
<form id="save" method="POST" action="{base}api/run/run1/save" enctype="text/plain" target="f2">
<input name='{{"a": "' value='"}}'></form>
<form id="urlenc" method="POST" action="{base}api/run/run1/edit" target="f3">
<input name="action" value="exclude"><input name="track" value="0"></form>
<img id="img" src="{base}api/run/run1/frame/3.png">
<script>
window.results = {{}};
async function attempt(name, f) {{
  try {{ window.results[name] = await f(); }} catch (e) {{ window.results[name] = "blocked: " + e; }}
}}
(async () => {{
  const base = "{base}";
  await attempt("cors", async () => (await fetch(base + "api/run/run1/state", {{credentials: "include"}})).text());
  await attempt("no-cors", async () => {{
    const r = await fetch(base + "api/run/run1/state", {{mode: "no-cors", credentials: "include"}});
    return "type " + r.type + " status " + r.status + " text " + (await r.text()).length;
  }});
  for (const action of ["edit", "save", "undo"]) {{
    await attempt("post-" + action, async () => {{
      const r = await fetch(base + "api/run/run1/" + action, {{method: "POST", mode: "no-cors", credentials: "include",
        headers: {{"Content-Type": "text/plain"}}, body: '{{"action": "exclude", "track": 0}}'}});
      return "type " + r.type + " status " + r.status;
    }});
  }}
  await attempt("post-json", async () => (await fetch(base + "api/run/run1/edit", {{method: "POST",
    credentials: "include", headers: {{"Content-Type": "application/json"}},
    body: '{{"action": "exclude", "track": 0}}'}})).text());
  document.getElementById("edit").submit();
  document.getElementById("save").submit();
  document.getElementById("urlenc").submit();
  window.done = true;
}})();
</script></body></html>"""


@needs_chromium
def test_another_origin_in_the_same_browser_can_neither_read_nor_change(folder, caplog):
    """With the review open (its cookie in the browser), a page of another origin — another port of 127.0.0.1,
    the hardest case: the same site, so the SameSite cookie is sent — tries to read the state (fetch, cors and
    no-cors), to show a frame, and to change the run (fetch POST text/plain and JSON, auto-submitted forms to
    /edit and /save): nothing read, every request that reaches the server refused (a 4xx, logged), corrections.json
    and the outputs unchanged, and the review page still works."""
    sync_api = pytest.importorskip("playwright.sync_api")
    caplog.set_level(logging.INFO, logger="grainplug.review")
    before = on_disk(folder)
    with (ReviewServer(folder) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--disable-background-networking") as page):
        page.goto(srv.url)
        page.wait_for_selector("#tracks tbody tr", timeout=20_000)
        sent: list[str] = []  # the hostile page's (and its frames') requests to the review
        answers: list[int] = []  # the statuses it saw (an answer the browser blocks is not seen)
        with hostile_site(HOSTILE_PAGE.format(base=srv.base_url)) as evil:
            other = page.context.new_page()  # the same browser: the review's cookie is there
            other.on("request", lambda r: sent.append(r.method) if r.url.startswith(srv.base_url) else None)
            other.on("response", lambda r: answers.append(r.status) if r.url.startswith(srv.base_url) else None)
            other.goto(evil)
            other.wait_for_function("() => window.done === true", timeout=20_000)
            for _ in range(100):  # the three forms' answers
                if len(answers) >= 3:
                    break
                other.wait_for_timeout(100)
            results = other.evaluate("() => window.results")
            image = other.evaluate("() => document.getElementById('img').naturalWidth")
        assert sent.count("POST") >= 6, sent  # three fetches, three forms (the JSON fetch stops at its preflight)
        assert answers and all(400 <= status < 500 for status in answers), answers
        refused = [r for r in caplog.records if r.name.startswith("grainplug.review") and "refused" in r.getMessage()]
        assert len(refused) >= len(sent), [r.getMessage() for r in refused]  # the server refused every one
        assert all(str(v).startswith("blocked") for v in results.values()), results  # nothing read
        assert image == 0
        assert on_disk(folder) == before
        # the review page, still open, still works
        tid = page.locator("#tracks tbody tr").first.get_attribute("data-track")
        page.locator(f"#tracks tbody tr[data-track='{tid}'] button").click()
        page.wait_for_selector("#tracks tbody tr.excluded", timeout=20_000)
    assert [e.action for e in read_corrections(folder).edits] == ["exclude"]


NO_LOCAL_NETWORK_CHECKS = ("--disable-features=LocalNetworkAccessChecks,PrivateNetworkAccessSendPreflights,"
                           "PrivateNetworkAccessRespectPreflightResults,BlockInsecurePrivateNetworkRequests")
REBOUND_PAGE = """<!DOCTYPE html><html><body><script>
window.results = {};
(async () => {
  for (const [name, path, opts] of [
      ["state", "api/run/run1/state", {}],
      ["state-with-token", "api/run/run1/state", {headers: {"X-Grainplug-Token": "TOKEN"}}],
      ["frame", "api/run/run1/frame/3.png", {headers: {"X-Grainplug-Token": "TOKEN"}}],
      ["page", "?token=TOKEN", {}],
      ["edit", "api/run/run1/edit", {method: "POST", body: '{"action": "exclude", "track": 0}',
                                     headers: {"Content-Type": "text/plain"}}],
      ["edit-with-token", "api/run/run1/edit", {method: "POST", body: '{"action": "exclude", "track": 0}',
                                                headers: {"Content-Type": "application/json",
                                                          "X-Grainplug-Token": "TOKEN"}}]]) {
    try {
      const r = await fetch("/" + path, opts);
      window.results[name] = [r.status, (await r.text()).includes("run1")];
    } catch (e) { window.results[name] = String(e); }
  }
  window.done = true;
})();
</script></body></html>"""


@needs_chromium
def test_a_rebound_name_gets_nothing_even_with_the_token(folder):
    """DNS rebinding: the attacker's page, first served from evil.test:PORT, then evil.test resolved to 127.0.0.1
    (the browser's resolver maps it; the page's first answer is the attacker's): its same-origin requests reach the
    review with Host evil.test:PORT and are refused, even with the token; nothing read, nothing written. Chromium's
    own Local/Private Network Access checks, which would stop these requests first, are switched off: the test is
    of the server's check (older browsers and others have none)."""
    sync_api = pytest.importorskip("playwright.sync_api")
    with (ReviewServer(folder) as srv, sync_api.sync_playwright() as p,
          chromium_page(p, "--host-resolver-rules=MAP evil.test 127.0.0.1", NO_LOCAL_NETWORK_CHECKS) as page):
        rebound = f"http://evil.test:{port(srv)}/"
        page.route(rebound, lambda route: route.fulfill(
            status=200, content_type="text/html", body=REBOUND_PAGE.replace("TOKEN", srv.token)))
        page.goto(rebound)
        page.wait_for_function("() => window.done === true", timeout=20_000)
        results = page.evaluate("() => window.results")
    assert results == {name: [403, False] for name in ("state", "state-with-token", "frame", "page", "edit",
                                                       "edit-with-token")}, results
    assert not (folder / "corrections.json").exists()
