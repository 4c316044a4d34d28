"""The live view's HTTP server (standard library only) and the view process of ``run --live``.

:class:`LiveServer` serves, on 127.0.0.1 only:

* ``GET /`` the live view, ``GET /edit`` the config editor, ``GET /static/<file>`` their
  scripts and style sheet (package data: nothing is fetched from the network);
* ``GET /api/state?scenario=S&from=N`` the polled state
  (:meth:`~veriloc_rt.sim.live.state.RunFolderState.state`), ``GET /api/scene`` the map's layer;
* ``GET /api/form`` the editor's fields (:func:`~veriloc_rt.sim.live.editor.form_fields`),
  ``GET /api/config`` the config being edited, and ``POST /api/validate``, ``/api/save``,
  ``/api/run`` (validate; save the JSON; save and start ``veriloc-rt run CONFIG --out DIR``, whose
  folder the live view then follows).

POSTs must carry the header ``X-Veriloc: 1`` and ``Content-Type: application/json``: a page of
another origin cannot send those without a CORS preflight, which this server never grants, so
only its own pages can start runs; the ``Host`` header must name the loopback address, against
DNS rebinding.

:func:`start_view_process` runs ``veriloc-rt view`` in a separate process for ``run --live``: it
shares nothing with the run but the files, so it can neither slow the run's process nor stop it,
and it exits when the run's process does (its stdin closes).
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import threading
from collections import deque
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlparse

from ...errors import InputError
from .editor import check_config, editor_config, form_fields, save_config
from .state import RunFolderState

log = logging.getLogger(__name__)

__all__ = ["LiveServer", "RunProcess", "ViewProcess", "start_view_process", "DEFAULT_PORT",
           "HOST", "STATIC_FILES"]

#: the only address served
HOST = "127.0.0.1"
#: the port tried first (when it is taken, the system picks a free one)
DEFAULT_PORT = 8765
#: the page's files, shipped as package data in ``static/``, with their media types
STATIC_FILES = {"live.html": "text/html", "edit.html": "text/html", "live.js": "text/javascript",
                "edit.js": "text/javascript", "common.js": "text/javascript",
                "live.css": "text/css"}
#: largest request body accepted, bytes (a config is a few kB)
MAX_BODY_BYTES = 1_000_000
#: lines of a started run's stderr kept for the page (its last one is the error, if any)
KEEP_LINES = 20


def static_bytes(name: str) -> bytes:
    """A file of the page (one of :data:`STATIC_FILES`)."""
    return (resources.files(__package__) / "static" / name).read_bytes()


class RunProcess:
    """A ``veriloc-rt run`` started by the editor: the process and the last lines of its stderr."""

    def __init__(self, config: Path, out: Path):
        cmd = [sys.executable, "-m", "veriloc_rt.cli", "run", str(config), "--out", str(out)]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True, errors="replace")
        self.lines: deque = deque(maxlen=KEEP_LINES)
        self._reader = threading.Thread(target=self._read, daemon=True,
                                        name="veriloc-live-run-stderr")
        self._reader.start()

    def _read(self) -> None:
        with self.proc.stderr:
            for line in self.proc.stderr:
                # tqdm redraws with carriage returns: keep the last state of each line
                text = line.rstrip("\n").split("\r")[-1].strip()
                if text:
                    self.lines.append(text)

    def status(self) -> tuple[int | None, str]:
        """(return code or None while it runs, its last stderr line: on failure the error)."""
        code = self.proc.poll()
        if code is not None:
            self._reader.join(timeout=1.0)
        return code, (self.lines[-1] if self.lines else "")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class LiveServer:
    """The live view and the editor on ``http://127.0.0.1:PORT/``.

    :param folder: the run folder the live view follows (the editor's run replaces it)
    :param config_path: the config file the editor edits and saves (None: the built-in
        default, saved as ``<folder>.json`` beside the run folder)
    :param port: the port; 0 picks a free one; a taken :data:`DEFAULT_PORT` falls back to 0
    """

    def __init__(self, folder: str | Path, config_path: str | Path | None = None,
                 port: int = DEFAULT_PORT):
        self.view = RunFolderState(folder)
        self.config_path = Path(config_path) if config_path is not None else None
        self.run_process: RunProcess | None = None
        self._lock = threading.Lock()
        try:
            self.httpd = ThreadingHTTPServer((HOST, port), _handler(self))
        except OSError:
            if port != DEFAULT_PORT:
                raise
            log.info("port %d is taken; using a free one", port)
            self.httpd = ThreadingHTTPServer((HOST, 0), _handler(self))
        self.httpd.daemon_threads = True
        self._thread: threading.Thread | None = None
        self._serving = False

    @property
    def port(self) -> int:
        return self.httpd.server_address[1]

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/"

    def start(self) -> "LiveServer":
        """Serve in a background thread."""
        self._serving = True
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True,
                                        name="veriloc-live-http")
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        """Serve in this thread until :meth:`shutdown` (from another thread) or Ctrl-C."""
        self._serving = True
        self.httpd.serve_forever()

    def shutdown(self) -> None:
        """Stop serving and close the socket (a run the editor started goes on)."""
        if self._serving:   # http.server's shutdown waits for a loop that must be running
            self.httpd.shutdown()
            self._serving = False
        self.httpd.server_close()

    # -- the editor's actions -----------------------------------------------------------------
    def default_config_path(self) -> Path:
        return (self.config_path if self.config_path is not None
                else self.view.folder.parent / f"{self.view.folder.name}.json")

    def editor_state(self) -> dict:
        cfg_path = self.config_path
        info = None
        if cfg_path is None:
            try:
                info = json.loads((self.view.folder / "run.json").read_text())["config"]
            except (OSError, ValueError, KeyError, TypeError):
                info = None
        if isinstance(info, dict):
            config = info
        else:   # a config file not written yet starts from the built-in default
            config = editor_config(cfg_path if cfg_path is not None and cfg_path.exists()
                                   else None)
        return {"config": config, "path": str(self.default_config_path()),
                "out": str(self.view.folder)}

    def start_run(self, data, config_path: str, out: str) -> dict:
        """Save ``data`` to ``config_path`` and start ``veriloc-rt run`` into ``out``; the live
        view follows ``out`` from now on.

        :raises InputError: the config's error, or ``--out``/``--save`` problems
        """
        if not out or not str(out).strip():
            raise InputError("--out", "empty; give the run's output folder")
        with self._lock:
            if self.run_process is not None and self.run_process.status()[0] is None:
                raise InputError("--out", "a run started here is still running; wait for it")
            path = save_config(data, config_path)
            out_dir = Path(out).expanduser().resolve()
            self.run_process = RunProcess(path, out_dir)
            self.view = RunFolderState(out_dir)
            self.view.process_status = self.run_process.status
            return {"ok": True, "path": str(path), "out": str(out_dir), "view": "/"}

    def stop_run(self) -> None:
        if self.run_process is not None:
            self.run_process.stop()


def _error(exc: InputError) -> dict:
    return {"ok": False, "error": f"error: {exc}", "field": exc.field}


def _handler(server: LiveServer) -> type:
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"
        server_version = "veriloc-rt-live"

        def log_message(self, fmt, *args):   # requests to the debug log, not to stderr
            log.debug("%s " + fmt, self.address_string(), *args)

        def _send(self, body: bytes, ctype: str, status: int = 200) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype + ("; charset=utf-8" if ctype.startswith("text") or ctype.endswith("json") else ""))
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.end_headers()
            self.wfile.write(body)

        def _json(self, obj, status: int = 200) -> None:
            self._send(json.dumps(obj, allow_nan=False).encode(), "application/json", status)

        def _host_ok(self) -> bool:
            host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
            return host in (HOST, "localhost")

        def do_GET(self):  # noqa: N802 - http.server's name
            if not self._host_ok():
                return self._send(b"forbidden host", "text/plain", HTTPStatus.FORBIDDEN)
            url = urlparse(self.path)
            q = parse_qs(url.query)
            path = url.path
            if path in ("/", "/index.html"):
                return self._send(static_bytes("live.html"), "text/html")
            if path == "/favicon.ico":
                return self._send(b"", "image/x-icon", HTTPStatus.NO_CONTENT)
            if path == "/edit":
                return self._send(static_bytes("edit.html"), "text/html")
            if path.startswith("/static/") and path[len("/static/"):] in STATIC_FILES:
                name = path[len("/static/"):]
                return self._send(static_bytes(name), STATIC_FILES[name])
            if path == "/api/state":
                try:
                    start = int(q.get("from", ["0"])[0])
                except ValueError:
                    start = 0
                return self._json(server.view.state(q.get("scenario", [None])[0], start))
            if path == "/api/scene":
                return self._json(server.view.scene())
            if path == "/api/form":
                return self._json({"fields": form_fields()})
            if path == "/api/config":
                try:
                    return self._json(server.editor_state())
                except InputError as exc:
                    return self._json(_error(exc))
            return self._send(b"not found", "text/plain", HTTPStatus.NOT_FOUND)

        def do_POST(self):  # noqa: N802
            if (not self._host_ok() or self.headers.get("X-Veriloc") != "1"
                    or not (self.headers.get("Content-Type") or "").startswith("application/json")):
                return self._send(b"forbidden", "text/plain", HTTPStatus.FORBIDDEN)
            try:
                n = int(self.headers.get("Content-Length") or 0)
            except ValueError:
                n = -1
            if not 0 <= n <= MAX_BODY_BYTES:
                return self._send(b"bad length", "text/plain", HTTPStatus.BAD_REQUEST)
            try:
                body = json.loads(self.rfile.read(n) or b"{}")
            except ValueError:
                return self._json({"ok": False, "error": "error: request: not JSON"}, 400)
            if not isinstance(body, dict):
                return self._json({"ok": False, "error": "error: request: not an object"}, 400)
            data = body.get("config")
            try:
                if self.path == "/api/validate":
                    exc = check_config(data, inputs=True)
                    return self._json({"ok": True} if exc is None else _error(exc))
                if self.path == "/api/save":
                    path = save_config(data, body.get("path") or server.default_config_path())
                    return self._json({"ok": True, "path": str(path)})
                if self.path == "/api/run":
                    return self._json(server.start_run(
                        data, body.get("path") or str(server.default_config_path()),
                        body.get("out") or ""))
            except InputError as exc:
                return self._json(_error(exc))
            return self._send(b"not found", "text/plain", HTTPStatus.NOT_FOUND)

    return Handler


@dataclass
class ViewProcess:
    """``veriloc-rt view`` in its own process (:func:`start_view_process`)."""

    proc: subprocess.Popen
    url: str

    def stop(self) -> None:
        """Close its stdin (it exits) and wait; terminate it if it does not."""
        if self.proc.poll() is None:
            try:
                self.proc.stdin.close()
            except OSError:
                pass
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.terminate()
                self.proc.wait()

    def wait(self) -> int:
        return self.proc.wait()


def start_view_process(folder: str | Path, port: int = DEFAULT_PORT,
                       timeout_s: float = 60.0) -> ViewProcess:
    """Start ``veriloc-rt view FOLDER --no-browser --watch-stdin`` and return it with its URL
    (its first output line). It exits when its stdin closes: when this process ends, however.

    :raises RuntimeError: when it does not report a URL within ``timeout_s``
    """
    cmd = [sys.executable, "-m", "veriloc_rt.cli", "view", str(folder), "--port", str(port),
           "--no-browser", "--watch-stdin"]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    line = got[0].strip() if got else ""
    if not line.split() or not line.split()[-1].startswith("http://"):
        proc.kill()
        proc.wait()
        raise RuntimeError(f"the live view did not start (said {line!r})")
    return ViewProcess(proc, line.split()[-1])
