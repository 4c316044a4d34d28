"""The editor and live view as an attacker on the same machine would try them, against servers
started as subprocesses with the installed entry point (``veriloc-rt edit|view ... --port 0
--no-browser``), whose printed URL holds the session token.

Without the token (or with a wrong one) every API route is refused and nothing is written or
started; with it, the editor writes only its own config file and runs only into its ``--out``;
another origin or host is refused and no page can be framed; children never import from the
current folder; messages never quote the files a config names; a slow client neither blocks
others nor holds its thread past the timeout; random requests always get a 2xx/4xx answer.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from veriloc_rt.live.server import MAX_HANDLERS, REQUEST_DEADLINE_S, TIMEOUT_S, TOKEN_HEADER

#: the installed console script (what a user runs)
ENTRY = Path(sys.executable).with_name("veriloc-rt")
#: interpreter start and imports of a child, s (a loaded 2-core machine)
START_TIMEOUT_S = 60.0
#: a tiny UMa run: a few seconds
TINY = {"propagation": {"model": "uma"}, "trajectory": {"num_points": 6, "adversary_lag_points": 2},
        "run": {"scenarios": ["none"], "evaluate_encrypted": False, "digsig": "shared"}}
#: the API's routes
GET_ROUTES = ("/api/state", "/api/scene", "/api/form", "/api/config")
POST_ROUTES = ("/api/validate", "/api/save", "/api/run")
#: how long a refused request is given to start something anyway before we look, s
SETTLE_S = 2.0
#: a request to an idle server is answered well within this, s (interpreter already warm)
PROMPT_S = 5.0
#: Ctrl-C ends a server within this, s (its serving loop wakes every 0.5 s)
STOP_TIMEOUT_S = 20.0
#: servers stopped with Ctrl-C while connections arrive
CTRL_C_TRIES = 25
#: a line that must never come back from the server
SECRET = "root:SECRET-7f3a9c:19000:0:99999:7:::"

pytestmark = pytest.mark.skipif(not ENTRY.exists(), reason=f"needs the entry point {ENTRY}")


#: ``token`` of :meth:`Server.request`: the server's own
RIGHT = object()


class Server:
    """``veriloc-rt ARGS`` in its own process group; its URL, token, stderr (a file)."""

    def __init__(self, args: list[str], cwd: Path, tmp: Path):
        self.err_path = tmp / f"stderr-{time.monotonic_ns()}.txt"
        self.err = open(self.err_path, "w")
        self.proc = subprocess.Popen([str(ENTRY), *args], cwd=cwd, stdout=subprocess.PIPE,
                                     stderr=self.err, stdin=subprocess.DEVNULL, text=True,
                                     start_new_session=True)
        got: list[str] = []
        t = threading.Thread(target=lambda: got.append(self.proc.stdout.readline()), daemon=True)
        t.start()
        t.join(START_TIMEOUT_S)
        words = got[0].split() if got else []
        if not words or not words[-1].startswith("http://"):
            self.stop()
            raise AssertionError(f"{args[0]} printed no URL: {got!r} {self.stderr()!r}")
        self.url = words[-1]
        u = urllib.parse.urlparse(self.url)
        self.base = f"{u.scheme}://{u.netloc}"
        self.port = u.port
        self.token = urllib.parse.parse_qs(u.query)["token"][0]

    def stderr(self) -> str:
        if not self.err.closed:
            self.err.flush()
        return self.err_path.read_text()

    def stop(self) -> None:
        """Ctrl-C to the process group, as a terminal would; :attr:`needed_kill` when that
        did not end the server within :data:`STOP_TIMEOUT_S`."""
        self.needed_kill = False
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.needed_kill = True
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.proc.stdout.close()
        self.err.close()

    def request(self, method: str, route: str, body: bytes | None = None, token=RIGHT,
                headers: dict | None = None, timeout: float = 60.0):
        """(status, headers, body bytes); ``token``: :data:`RIGHT`, another text, None none."""
        h = {"Host": f"127.0.0.1:{self.port}"}
        if body is not None:
            h.update({"Content-Type": "application/json", "X-Veriloc": "1"})
        if token is not None:
            h[TOKEN_HEADER] = self.token if token is RIGHT else token
        h.update(headers or {})
        req = urllib.request.Request(self.base + route, data=body, method=method, headers=h)
        try:
            with urllib.request.urlopen(req, timeout=timeout) as r:
                return r.status, r.headers, r.read()
        except urllib.error.HTTPError as e:
            with e:
                return e.code, e.headers, e.read()

    def post(self, route: str, obj, **kw):
        return self.request("POST", route, json.dumps(obj).encode(), **kw)


@pytest.fixture
def editor(tmp_path):
    """``veriloc-rt edit CONFIG --out DIR`` on a tiny config; (server, config, out)."""
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(TINY))
    out = tmp_path / "run"
    s = Server(["edit", str(cfg), "--out", str(out), "--no-browser", "--port", "0"], tmp_path,
               tmp_path)
    try:
        yield s, cfg, out
    finally:
        s.stop()
    assert "Traceback" not in s.stderr() and not s.needed_kill, s.stderr()


def _files(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if "stderr-" not in p.name}


def test_the_printed_url_holds_a_token_of_at_least_128_bits(editor):
    s, _cfg, _out = editor
    assert s.url == f"{s.base}/edit?token={s.token}"
    # token_urlsafe: 6 bits per character
    assert re.fullmatch(r"[A-Za-z0-9_-]+", s.token) and 6 * len(s.token) >= 128


@pytest.mark.parametrize("token", [None, "wrong", "x" * 43, ""])
def test_without_the_token_every_api_route_is_refused_and_nothing_happens(editor, tmp_path,
                                                                          token):
    s, cfg, out = editor
    before = cfg.read_bytes()
    files = _files(tmp_path)
    for route in GET_ROUTES:
        status, headers, body = s.request("GET", route + "?from=0", token=token)
        assert status == 403 and b"SECRET" not in body
        assert json.loads(body)["field"] == "token"
    for route in POST_ROUTES:
        status, _, body = s.post(route, {"config": TINY, "path": str(cfg), "out": str(out)},
                                 token=token)
        assert status == 403 and json.loads(body)["field"] == "token"
    time.sleep(SETTLE_S)
    assert cfg.read_bytes() == before and not out.exists()
    assert _files(tmp_path) == files
    # the same requests with the token work (the refusals were the token's)
    assert s.request("GET", "/api/form")[0] == 200
    assert s.post("/api/validate", {"config": TINY})[0] == 200


def test_with_the_token_only_the_configured_file_and_folder(editor, tmp_path):
    s, cfg, out = editor
    before = cfg.read_bytes()
    other = tmp_path / "other.json"
    rc = Path.home() / ".veriloc-rt-test-must-not-exist"
    for path in (str(other), "../other.json", str(rc), "--force", str(tmp_path / "sub" / "c.json")):
        for route in ("/api/save", "/api/run"):
            status, _, body = s.post(route, {"config": TINY, "path": path})
            res = json.loads(body)
            assert status == 403 and res["field"] == "path", (path, res)
            assert res["error"].startswith("error: path: the editor saves only to ")
    status, _, body = s.post("/api/run", {"config": TINY, "out": str(tmp_path / "elsewhere")})
    assert status == 403 and json.loads(body)["field"] == "out"
    time.sleep(SETTLE_S)
    assert cfg.read_bytes() == before and not out.exists()
    for p in (other, tmp_path / "other.json", rc, tmp_path / "--force", tmp_path / "sub",
              tmp_path / "elsewhere", tmp_path.parent / "other.json"):
        assert not p.exists(), p
    # the configured ones work: the save writes the config given, byte for byte as JSON
    changed = json.loads(json.dumps(TINY))
    changed["seed"] = 5
    status, _, body = s.post("/api/save", {"config": changed, "path": str(cfg)})
    assert status == 200 and json.loads(cfg.read_text()) == changed


def test_a_saved_config_keeps_its_permissions(editor):
    s, cfg, _out = editor
    os.chmod(cfg, 0o600)
    assert s.post("/api/save", {"config": TINY})[0] == 200
    assert stat.S_IMODE(cfg.stat().st_mode) == 0o600 and json.loads(cfg.read_text()) == TINY


def test_edit_without_config_refuses_an_existing_default_file(tmp_path):
    unrelated = tmp_path / "results.json"
    unrelated.write_text('{"not": "a config"}')
    p = subprocess.run([str(ENTRY), "edit", "--out", "results", "--no-browser", "--port", "0"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=START_TIMEOUT_S)
    assert p.returncode == 2 and p.stdout == ""
    assert p.stderr == (f"error: {unrelated}: exists and was not given as CONFIG, so the editor "
                        "would overwrite it: give it as CONFIG to edit it, or choose another "
                        "--out\n")
    assert unrelated.read_text() == '{"not": "a config"}'


def test_a_view_server_saves_and_starts_nothing(tmp_path):
    (tmp_path / "r").mkdir()
    s = Server(["view", "r", "--no-browser", "--port", "0"], tmp_path, tmp_path)
    try:
        for route in ("/api/save", "/api/run"):
            status, _, body = s.post(route, {"config": TINY})
            assert status == 403 and json.loads(body)["field"] == "edit"
        time.sleep(SETTLE_S)
        assert not (tmp_path / "r.json").exists() and list((tmp_path / "r").iterdir()) == []
    finally:
        s.stop()


def test_foreign_origin_and_host_are_refused_and_framing_forbidden(editor):
    s, cfg, _out = editor
    before = cfg.read_bytes()
    for origin in ("http://evil.example", f"http://127.0.0.1:{s.port + 1}", "null",
                   f"https://127.0.0.1:{s.port}"):
        status, _, body = s.request("GET", "/api/config", headers={"Origin": origin})
        assert status == 403 and json.loads(body)["field"] == "Origin"
        status, _, body = s.post("/api/save", {"config": TINY}, headers={"Origin": origin})
        assert status == 403 and json.loads(body)["field"] == "Origin"
    for host in ("evil.example", f"evil.example:{s.port}", f"127.0.0.1:{s.port + 1}"):
        status, _, body = s.request("GET", "/api/config", headers={"Host": host})
        assert status == 403 and json.loads(body)["field"] == "Host"
    assert cfg.read_bytes() == before
    # the server's own origins are served
    for origin in (f"http://127.0.0.1:{s.port}", f"http://localhost:{s.port}"):
        assert s.request("GET", "/api/form", headers={"Origin": origin})[0] == 200
    # every response, of pages, files, API, refusals and errors, forbids framing
    for method, route, token in (("GET", "/edit", RIGHT), ("GET", "/", None),
                                 ("GET", "/static/live.js", None), ("GET", "/api/form", RIGHT),
                                 ("GET", "/api/form", None), ("GET", "/nothing", RIGHT),
                                 ("DELETE", "/api/form", RIGHT)):
        status, headers, _ = s.request(method, route, token=token)
        csp = headers["Content-Security-Policy"]
        assert "frame-ancestors 'none'" in csp and "default-src 'self'" in csp, (route, status)
        assert headers["X-Frame-Options"] == "DENY"


def test_children_never_import_from_the_current_folder(tmp_path):
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    marker = tmp_path / "imported"
    (cwd / "tqdm.py").write_text(f"open({str(marker)!r}, 'w').close()\n"
                                 "raise ImportError('the tqdm of the current folder')\n")
    (cwd / "c.json").write_text(json.dumps(TINY))
    # the trap works: `python -m veriloc_rt.cli` (what children ran before) imports it
    p = subprocess.run([sys.executable, "-m", "veriloc_rt.cli", "config", "schema"], cwd=cwd,
                       capture_output=True, timeout=START_TIMEOUT_S)
    assert p.returncode != 0 and marker.exists()
    marker.unlink()
    # run --live: the view process it starts
    proc = subprocess.Popen([str(ENTRY), "run", "c.json", "--out", "r", "--live", "--no-browser",
                             "--port", "0", "--workers", "1"], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    try:
        first = proc.stdout.readline()
        assert first.startswith("live view: http://127.0.0.1:") and "?token=" in first
        # the view answers with the token of the printed URL
        url = urllib.parse.urlparse(first.split()[-1])
        token = urllib.parse.parse_qs(url.query)["token"][0]
        req = urllib.request.Request(f"http://{url.netloc}/api/state",
                                     headers={TOKEN_HEADER: token})
        with urllib.request.urlopen(req, timeout=PROMPT_S) as r:
            assert r.status == 200
        lines = []    # the run's summary, then the view's line
        while not (lines and lines[-1].startswith("live view stays at http://")):
            lines.append(proc.stdout.readline())
            assert lines[-1], lines    # not at the end of the output
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        proc.communicate(timeout=30)
    assert json.loads((cwd / "r" / "run.json").read_text())["status"] == "complete"
    assert not marker.exists()
    # a run the editor starts
    s = Server(["edit", "c.json", "--out", "r2", "--no-browser", "--port", "0"], cwd, tmp_path)
    try:
        status, _, body = s.post("/api/run", {"config": TINY})
        assert status == 200 and json.loads(body)["out"] == str(cwd / "r2")
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            proc_state = json.loads(s.request("GET", "/api/state")[2]).get("process")
            if proc_state and proc_state["returncode"] is not None:
                break
            time.sleep(0.2)
        assert proc_state["returncode"] == 0, proc_state
    finally:
        s.stop()
    assert json.loads((cwd / "r2" / "run.json").read_text())["status"] == "complete"
    assert not marker.exists()


#: the header each CSV field reads
HEADERS = {"trajectory.source": "t,x,y", "topology.sites": "x,y,z"}


@pytest.mark.parametrize("field", ["trajectory.source", "topology.sites"])
@pytest.mark.parametrize("which", ["row", "header"])
def test_errors_name_the_field_never_the_files_content(editor, tmp_path, field, which):
    """A file whose first line (header) or a row is the secret."""
    s, cfg, out = editor
    path = tmp_path / "secret.csv"
    path.write_text((HEADERS[field] + "\n" + SECRET + ",1,2\n") if which == "row"
                    else SECRET + "\n")
    section, name = field.split(".")
    config = json.loads(json.dumps(TINY))
    config.setdefault(section, {})[name] = str(path)
    # the same config's terminal message quotes the file (what the page must not show)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(config))
    p = subprocess.run([str(ENTRY), "config", "check", str(bad)], capture_output=True,
                       text=True, timeout=START_TIMEOUT_S)
    assert p.returncode == 2 and "SECRET" in p.stderr
    before = cfg.read_bytes()
    for route in ("/api/validate", "/api/run"):
        status, _, body = s.post(route, {"config": config})
        res = json.loads(body)
        assert b"SECRET" not in body and res["ok"] is False and res["field"] == field, res
        assert res["error"].startswith(f"error: {field}: cannot be used as the ")
        assert status == (200 if route == "/api/validate" else 400)
    time.sleep(SETTLE_S)
    assert cfg.read_bytes() == before and not out.exists()


def test_keys_dir_does_not_probe_existence(editor, tmp_path):
    s, _cfg, _out = editor
    (tmp_path / "empty").mkdir()
    answers = set()
    for d in (tmp_path / "missing", tmp_path / "empty", Path("/root"), Path("/etc/shadow")):
        config = {**TINY, "security": {"keys_dir": str(d)}}
        res = json.loads(s.post("/api/validate", {"config": config})[2])
        assert res["field"] == "security.keys_dir"
        answers.add(res["error"].replace(str(d), "D"))
    assert len(answers) == 1, answers


@pytest.mark.parametrize("body, field", [
    ({"config": TINY, "path": 123}, "path"),
    ({"config": TINY, "out": ["a"]}, "out"),
    ({"config": TINY, "path": "c\x00.json"}, "path"),
    ({"config": "text"}, "config"),
    ({"config": TINY, "extra": 1}, "request"),
    ([1, 2], "request"),
])
def test_bad_request_fields_are_one_line_400(editor, body, field):
    s, cfg, out = editor
    before = cfg.read_bytes()
    for route in POST_ROUTES:
        status, _, raw = s.post(route, body)
        res = json.loads(raw)
        assert status == 400 and res["field"] == field and "\n" not in res["error"], res
    assert cfg.read_bytes() == before and not out.exists()


def test_deep_nesting_and_bad_bytes_are_400_and_the_server_lives(editor):
    s, _cfg, _out = editor
    for raw in (b"[" * 200_000 + b"]" * 200_000, b'{"config": ' * 50_000, b"\xff\xfe{",
                b"", b"NaN", b'{"config": {}, "config": {}}'):
        status, _, body = s.request("POST", "/api/validate", raw)
        res = json.loads(body)
        assert status == 400 and res["field"] == "request" and "\n" not in res["error"]
    assert s.request("GET", "/api/form")[0] == 200


def test_a_slow_client_neither_blocks_others_nor_keeps_its_thread(editor):
    s, _cfg, _out = editor
    slow = socket.create_connection(("127.0.0.1", s.port), timeout=TIMEOUT_S * 3)
    t0 = time.monotonic()
    # half a request: headers promising a body that never comes
    slow.sendall(f"POST /api/validate HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                 f"{TOKEN_HEADER}: {s.token}\r\nX-Veriloc: 1\r\n"
                 "Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n{\"con".encode())
    for _ in range(3):
        t = time.monotonic()
        assert s.request("GET", "/api/form", timeout=PROMPT_S)[0] == 200
        assert time.monotonic() - t < PROMPT_S
    # the server closes it after its timeout (recv returns b'' at the close)
    assert slow.recv(1024) == b""
    waited = time.monotonic() - t0
    assert TIMEOUT_S - 1.0 <= waited <= TIMEOUT_S + PROMPT_S, waited
    slow.close()


@pytest.mark.heavy   # 20-45 s of timeouts: CI's second step
def test_a_trickling_client_is_cut_off_at_the_request_deadline(editor):
    s, _cfg, _out = editor
    slow = socket.create_connection(("127.0.0.1", s.port), timeout=PROMPT_S)
    t0 = time.monotonic()
    slow.sendall(f"POST /api/validate HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                 f"{TOKEN_HEADER}: {s.token}\r\nX-Veriloc: 1\r\n"
                 "Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n".encode())
    closed = None
    # a byte of body well within the silence timeout, again and again
    while time.monotonic() - t0 < REQUEST_DEADLINE_S + 2 * PROMPT_S:
        try:
            slow.sendall(b" ")
        except OSError:
            closed = time.monotonic() - t0
            break
        slow.settimeout(TIMEOUT_S / 4)
        try:
            if slow.recv(1024) == b"":
                closed = time.monotonic() - t0
                break
        except socket.timeout:
            pass
    slow.close()
    assert closed is not None and REQUEST_DEADLINE_S - 1.0 <= closed <= REQUEST_DEADLINE_S + PROMPT_S
    assert s.request("GET", "/api/form", timeout=PROMPT_S)[0] == 200


def test_connections_beyond_the_limit_get_503_then_service_resumes(editor):
    s, _cfg, _out = editor
    idle = [socket.create_connection(("127.0.0.1", s.port), timeout=PROMPT_S)
            for _ in range(MAX_HANDLERS)]
    try:
        time.sleep(0.5)   # all accepted and each waiting in its handler
        status, headers, body = s.request("GET", "/api/form", timeout=PROMPT_S)
        assert status == 503 and headers["X-Frame-Options"] == "DENY"
    finally:
        for c in idle:
            c.close()
    deadline = time.monotonic() + PROMPT_S
    while s.request("GET", "/api/form", timeout=PROMPT_S)[0] != 200:
        assert time.monotonic() < deadline
        time.sleep(0.1)


def test_clients_that_hang_up_print_nothing(editor):
    s, _cfg, _out = editor
    request = (f"GET /api/form HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
               f"{TOKEN_HEADER}: {s.token}\r\n\r\n").encode()
    for _ in range(30):
        c = socket.create_connection(("127.0.0.1", s.port), timeout=PROMPT_S)
        c.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        c.sendall(request)
        c.close()    # RST: the server's write of the answer fails
    assert s.request("GET", "/api/form")[0] == 200
    time.sleep(0.5)
    assert s.stderr() == ""


def test_busy_port_and_missing_folder_are_one_line(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        (tmp_path / "d").mkdir()
        (tmp_path / "c.json").write_text(json.dumps(TINY))
        line = (f"error: --port: {port} is in use by another program; give another port, or "
                "--port 0 for any free one\n")
        for args in (["view", str(tmp_path / "d"), "--port", str(port), "--no-browser"],
                     ["edit", "--out", str(tmp_path / "e"), "--port", str(port), "--no-browser"],
                     ["run", str(tmp_path / "c.json"), "--out", str(tmp_path / "r"), "--live",
                      "--port", str(port), "--no-browser"]):
            p = subprocess.run([str(ENTRY), *args], capture_output=True, text=True,
                               timeout=START_TIMEOUT_S, stdin=subprocess.DEVNULL)
            assert (p.returncode, p.stderr) == (2, line), (args, p.stderr)
        assert not (tmp_path / "r" / "run.json").exists()
    p = subprocess.run([str(ENTRY), "view", str(tmp_path / "no" / "such"), "--no-browser"],
                       capture_output=True, text=True, timeout=START_TIMEOUT_S)
    assert (p.returncode, p.stderr) == (2, f"error: {tmp_path / 'no' / 'such'}: does not exist "
                                           "(give a run's --out folder)\n")


def test_fifos_in_the_viewed_folder_are_not_waited_on(tmp_path):
    d = tmp_path / "r"
    d.mkdir()
    # a finished run's config, so that the view looks for the scenario's CSV too
    os.mkfifo(d / "run.json")
    os.mkfifo(d / "none_results.csv")
    os.mkfifo(d / "metrics.json")
    s = Server(["view", str(d), "--no-browser", "--port", "0"], tmp_path, tmp_path)
    try:
        for _ in range(5):
            t = time.monotonic()
            status, _, body = s.request("GET", "/api/state", timeout=PROMPT_S)
            assert status == 200 and json.loads(body)["status"] == "waiting"
            assert time.monotonic() - t < PROMPT_S
        # a run.json whose config names the scenario, beside a FIFO CSV
        (d / "run.json").unlink()
        (d / "run.json").write_text(json.dumps({"status": "complete", "config": TINY}))
        for _ in range(3):
            status, _, body = s.request("GET", "/api/state", timeout=PROMPT_S)
            st_ = json.loads(body)
            assert status == 200 and st_["scenarios"][0]["done"] == 0
        assert s.request("GET", "/api/form", timeout=PROMPT_S)[0] == 200
    finally:
        s.stop()
    assert "Traceback" not in s.stderr()


# -- random requests -------------------------------------------------------------------------
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False)
                    | st.text(max_size=20),
                    lambda kids: st.lists(kids, max_size=4)
                    | st.dictionaries(st.text(max_size=10), kids, max_size=4),
                    max_leaves=12)
#: bodies shaped like the page's, with random values in the fields
SHAPED = st.fixed_dictionaries({}, optional={
    "config": st.dictionaries(st.sampled_from(["seed", "trajectory", "run", "scene", "nr", "x"]),
                              JSON, max_size=3),
    "path": JSON, "out": JSON})


@pytest.fixture(scope="module")
def fuzz_server(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fuzz")
    (tmp / "c.json").write_text(json.dumps(TINY))
    (tmp / "out-is-a-file").write_text("so that a run started here ends at once")
    s = Server(["edit", "c.json", "--out", "out-is-a-file", "--no-browser", "--port", "0"],
               tmp, tmp)
    yield s
    s.stop()
    err = s.stderr()
    assert "Traceback" not in err and " failed: " not in err and not s.needed_kill, err


@settings(max_examples=100, deadline=None)
@given(route=st.sampled_from(POST_ROUTES),
       body=st.one_of(JSON.map(lambda v: json.dumps(v).encode()),
                      SHAPED.map(lambda v: json.dumps(v).encode()),
                      st.binary(max_size=64)))
def test_random_posts_always_get_an_answer(fuzz_server, route, body):
    s = fuzz_server
    status, _, raw = s.request("POST", route, body)
    assert 200 <= status < 300 or 400 <= status < 500, (status, raw)
    res = json.loads(raw)
    if status >= 400:
        assert res["ok"] is False and res["error"].startswith("error: ")
        assert "\n" not in res["error"]
    assert s.proc.poll() is None


@settings(max_examples=60, deadline=None)
@given(route=st.sampled_from(GET_ROUTES), query=st.dictionaries(
    st.sampled_from(["from", "scenario", "token", "x"]), st.text(max_size=30), max_size=3))
def test_random_gets_always_get_an_answer(fuzz_server, route, query):
    s = fuzz_server
    status, _, raw = s.request("GET", route + "?" + urllib.parse.urlencode(query))
    assert status == 200, (status, raw)
    json.loads(raw)
    assert s.proc.poll() is None


def test_edit_without_config_writes_only_its_new_default_file(tmp_path):
    from veriloc_rt.live.server import LiveServer, Refused

    server = LiveServer(tmp_path / "r", port=0, edit=True)
    try:
        target = tmp_path / "r.json"
        assert server.editor_state()["path"] == str(target) and not target.exists()
        # written by another program after the start: not overwritten
        target.write_text("someone else's")
        with pytest.raises(Refused, match="appeared after the editor started") as e:
            server.save(TINY)
        assert e.value.status == 409 and target.read_text() == "someone else's"
        target.unlink()
        # the editor's own file: written, and written again
        assert server.save(TINY) == target and json.loads(target.read_text()) == TINY
        changed = {**TINY, "seed": 3}
        assert server.save(changed, str(target)) == target
        assert json.loads(target.read_text()) == changed
    finally:
        server.shutdown()


@pytest.mark.heavy   # 20-45 s of timeouts: CI's second step
def test_ctrl_c_stops_the_server_while_connections_arrive(tmp_path):
    """Ctrl-C lands at any point of the serving loop, also while it starts a handler thread
    (a KeyboardInterrupt there was once turned into a logged error and the server went on)."""
    (tmp_path / "r").mkdir()
    for _ in range(CTRL_C_TRIES):
        s = Server(["view", "r", "--no-browser", "--port", "0"], tmp_path, tmp_path)
        stop = threading.Event()

        def hammer():
            while not stop.is_set():
                try:
                    with socket.create_connection(("127.0.0.1", s.port), timeout=1) as c:
                        c.sendall(f"GET /static/common.js HTTP/1.1\r\nHost: 127.0.0.1:{s.port}"
                                  "\r\nConnection: close\r\n\r\n".encode())
                        c.recv(65536)
                except OSError:
                    pass

        threads = [threading.Thread(target=hammer, daemon=True) for _ in range(8)]
        for t in threads:
            t.start()
        time.sleep(0.3)
        s.stop()
        stop.set()
        for t in threads:
            t.join(5)
        assert not s.needed_kill and s.proc.returncode == 0, s.stderr()
        assert "Traceback" not in s.stderr() and " failed: " not in s.stderr()
