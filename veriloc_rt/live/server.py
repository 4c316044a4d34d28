"""The live view's HTTP server (standard library only) and the view process of ``run --live``.

:class:`LiveServer` serves, on 127.0.0.1 only:

* ``GET /`` the live view, ``GET /edit`` the config editor, ``GET /static/<file>`` their
  scripts and style sheet (package data: nothing is fetched from the network); these hold no
  data and are served to any local client;
* ``GET /api/state?scenario=S&from=N`` the polled state
  (:meth:`~veriloc_rt.live.state.RunFolderState.state`), ``GET /api/scene`` the map's layer;
* ``GET /api/form`` the editor's fields (:func:`~veriloc_rt.live.editor.form_fields`),
  ``GET /api/config`` the config being edited, and ``POST /api/validate``, ``/api/save``,
  ``/api/run`` (validate; save the JSON; save and start ``veriloc-rt run --out DIR -- CONFIG``,
  whose folder the live view then follows).

Who may ask, and what:

* every ``/api/`` request carries the server's session token (:attr:`LiveServer.token`, 256
  random bits made at start) in the header ``X-Veriloc-Token``; the URL the command prints and
  opens holds it (``?token=...``, as Jupyter does) and the page's scripts send it; a missing or
  wrong token is 403 and nothing is read, written or started (compared with
  :func:`hmac.compare_digest`);
* the ``Host`` header must be ``127.0.0.1:PORT`` or ``localhost:PORT`` (against DNS rebinding)
  and an ``Origin`` header, when sent, the same origin; POSTs must also carry ``X-Veriloc: 1``
  and ``Content-Type: application/json``, which a page of another origin cannot send without a
  CORS preflight, never granted here;
* every response forbids framing (``Content-Security-Policy: frame-ancestors 'none'`` and
  ``X-Frame-Options: DENY``) and loads scripts and styles from this server only;
* the editor (``veriloc-rt edit``, ``edit=True``) saves only to the config file it was started
  on (or, without one, to the new file ``<out>.json`` decided at start) and starts runs only
  into its ``--out``; a request naming another ``path`` or ``out`` is refused (403) and
  nothing is written or started; ``veriloc-rt view`` saves and starts nothing;
* a request body is JSON of at most :data:`MAX_BODY_BYTES`, parsed with the package's depth
  limit, each field type-checked: a bad one is 400 with one line, never a dropped connection;
* each connection times out after :data:`TIMEOUT_S` of silence, a request must arrive whole
  within :data:`REQUEST_DEADLINE_S`, and at most :data:`MAX_HANDLERS` connections are handled
  at once (more get 503), so slow clients cannot hold the server; clients that hang up are
  logged at debug level, not printed;
* messages from checking the files a config names only name the field
  (:func:`~veriloc_rt.live.editor.check_config` with ``file_details=False``).

Child processes (the editor's runs, :func:`start_view_process`) are started as
:func:`cli_command`: ``python -I -m veriloc_rt.cli``, so that nothing is imported from the current
folder, with every path after ``--``, so that none is read as a flag.

:func:`start_view_process` runs ``veriloc-rt view`` in a separate process for ``run --live``: it
shares nothing with the run but the files, so it can neither slow the run's process nor stop it,
and it exits when the run's process does (its stdin closes).
"""

from __future__ import annotations

import errno
import hmac
import json
import logging
import os
import secrets
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, urlparse

from ..errors import InputError, short_repr
from ..inputs import parse_json
from .editor import check_config, editor_config, form_fields, save_config
from .state import RunFolderState

log = logging.getLogger(__name__)

__all__ = ["LiveServer", "RunProcess", "ViewProcess", "start_view_process", "cli_command",
           "Refused", "DEFAULT_PORT", "HOST", "STATIC_FILES", "TOKEN_HEADER", "TIMEOUT_S",
           "REQUEST_DEADLINE_S",
           "MAX_HANDLERS", "SECURITY_HEADERS"]

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
#: the request header that carries the session token
TOKEN_HEADER = "X-Veriloc-Token"
#: random bytes of the session token (256 bits)
TOKEN_BYTES = 32
#: seconds a connection may stay silent (mid-request or idle between requests) before it is
#: closed: a slow or short body holds a thread this long at most
TIMEOUT_S = 10.0
#: seconds from a request's first byte to the end of its body: a client that trickles a byte
#: now and then (each within :data:`TIMEOUT_S`) is cut off here
REQUEST_DEADLINE_S = 20.0
#: connections handled at once; more are answered 503 at once (a browser opens about six)
MAX_HANDLERS = 32
#: headers of every response: no framing (clickjacking of the Save-and-run button), scripts,
#: styles and requests to this server only, no referrer, no type sniffing, no caching
SECURITY_HEADERS = {
    "Content-Security-Policy": ("default-src 'self'; img-src 'self' data:; base-uri 'none'; "
                                "form-action 'none'; frame-ancestors 'none'"),
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}
#: the fields a POST body may hold
BODY_FIELDS = ("config", "path", "out")


def static_bytes(name: str) -> bytes:
    """A file of the page (one of :data:`STATIC_FILES`)."""
    return (resources.files(__package__) / "static" / name).read_bytes()


def cli_command(*args: str) -> list[str]:
    """The command line of ``veriloc-rt ARGS`` in a child process: this interpreter in isolated
    mode (``-I``: neither the current folder nor ``PYTHON*`` variables reach ``sys.path``, so a
    ``tqdm.py`` in the folder a user starts it from is never imported)."""
    return [sys.executable, "-I", "-m", "veriloc_rt.cli", *args]


class Refused(InputError):
    """A request the server refuses, with its HTTP status (403: not allowed, 409: busy)."""

    def __init__(self, field: str, problem: str, status: int = HTTPStatus.FORBIDDEN):
        super().__init__(field, problem)
        self.status = int(status)


class RunProcess:
    """A ``veriloc-rt run`` started by the editor: the process and the last lines of its stderr."""

    def __init__(self, config: Path, out: Path):
        cmd = cli_command("run", "--out", str(out), "--", str(config))
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


def _same_path(a: Path, b: Path) -> bool:
    return os.path.normpath(os.path.abspath(a)) == os.path.normpath(os.path.abspath(b))


class _HTTPServer(ThreadingHTTPServer):
    """http.server's threading server with at most :data:`MAX_HANDLERS` handler threads (a
    connection beyond them is answered 503 and closed) and errors of connections that went
    away logged at debug level instead of printed."""

    daemon_threads = True
    #: the answer to a connection over the limit
    BUSY = (b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\n"
            b"Content-Length: 5\r\nRetry-After: 1\r\nConnection: close\r\n"
            + "".join(f"{k}: {v}\r\n" for k, v in SECURITY_HEADERS.items()).encode()
            + b"\r\nbusy\n")

    def __init__(self, address, handler, max_handlers: int = MAX_HANDLERS):
        self._slots = threading.BoundedSemaphore(max_handlers)
        #: connection -> monotonic time by which its request must have been read
        self._deadlines: dict = {}
        self._deadline_lock = threading.Lock()
        self._closed = threading.Event()
        super().__init__(address, handler)
        threading.Thread(target=self._watch_deadlines, daemon=True,
                         name="veriloc-live-deadlines").start()

    def arm(self, conn, seconds: float) -> None:
        """Shut ``conn`` down unless :meth:`disarm` comes within ``seconds``."""
        with self._deadline_lock:
            self._deadlines[conn] = time.monotonic() + seconds

    def disarm(self, conn) -> None:
        with self._deadline_lock:
            self._deadlines.pop(conn, None)

    def _watch_deadlines(self) -> None:
        while not self._closed.wait(0.5):
            now = time.monotonic()
            with self._deadline_lock:
                late = [c for c, t in self._deadlines.items() if t < now]
                for c in late:
                    del self._deadlines[c]
            for c in late:   # the handler's blocked read returns; it ends the connection
                log.debug("a request took over %g s to arrive; connection closed",
                          REQUEST_DEADLINE_S)
                try:
                    c.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def server_close(self):
        self._closed.set()
        super().server_close()

    def process_request(self, request, client_address):
        if not self._slots.acquire(blocking=False):
            log.debug("%s: %d connections already; answered 503", client_address[0],
                      MAX_HANDLERS)
            try:
                request.settimeout(1.0)
                request.sendall(self.BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        t = threading.Thread(target=self.process_request_thread, args=(request, client_address),
                             daemon=True, name="veriloc-live-request")
        try:
            t.start()
        except RuntimeError:   # no thread could be made, so none will release the slot
            self._slots.release()
            raise
        # (a Ctrl-C while the thread starts is not caught here: the started thread releases
        # its slot, and the KeyboardInterrupt must reach serve_forever's caller)

    def process_request_thread(self, request, client_address):
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request, client_address):
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):   # the client hung up or went silent
            log.debug("connection from %s ended: %s", client_address[0], exc)
        else:
            log.error("request from %s failed: %s: %s", client_address[0],
                      type(exc).__name__, exc, exc_info=log.isEnabledFor(logging.DEBUG))


class LiveServer:
    """The live view (and with ``edit``, the editor) on ``http://127.0.0.1:PORT/``.

    :param folder: the run folder the live view follows; the editor's runs go there (``--out``)
    :param config_path: the config file the editor edits and saves (None: the built-in
        default or the folder's run's config, saved to the new file ``<folder>.json`` beside
        the run folder, which must not exist yet)
    :param port: the port given (``--port``; 0 picks a free one), or None: :data:`DEFAULT_PORT`,
        or a free one when it is taken
    :param edit: serve the editor's saves and runs (``veriloc-rt edit``); False: the view and
        the editor's checks only (``veriloc-rt view``)
    :raises InputError: ``--port`` in use or not usable; without ``config_path``, ``edit`` and
        ``<folder>.json`` already there
    """

    def __init__(self, folder: str | Path, config_path: str | Path | None = None,
                 port: int | None = None, edit: bool = False):
        self.view = RunFolderState(folder)
        self.config_path = Path(config_path) if config_path is not None else None
        self.edit = edit
        #: where runs go: the folder given, absolute (the child may run elsewhere)
        self.out = Path(os.path.abspath(Path(folder).expanduser()))
        #: the only file the editor writes
        self.save_path = Path(os.path.abspath(
            self.config_path.expanduser() if self.config_path is not None
            else self.out.parent / f"{self.out.name}.json"))
        if edit and self.config_path is None and os.path.lexists(self.save_path):
            raise InputError(str(self.save_path), "exists and was not given as CONFIG, so the "
                             "editor would overwrite it: give it as CONFIG to edit it, or "
                             "choose another --out")
        self._wrote_default = False
        #: the session's secret: every /api/ request carries it (:data:`TOKEN_HEADER`)
        self.token = secrets.token_urlsafe(TOKEN_BYTES)
        self.run_process: RunProcess | None = None
        self._lock = threading.Lock()
        try:
            self.httpd = _HTTPServer((HOST, DEFAULT_PORT if port is None else port),
                                     _handler(self))
        except OSError as exc:
            if port is not None:
                raise _port_error(port, exc) from None
            log.info("port %d is taken; using a free one", DEFAULT_PORT)
            try:
                self.httpd = _HTTPServer((HOST, 0), _handler(self))
            except OSError as exc2:
                raise _port_error(0, exc2) from None
        self._thread: threading.Thread | None = None
        self._serving = False

    @property
    def port(self) -> int:
        return self.httpd.server_address[1]

    @property
    def origins(self) -> tuple[str, ...]:
        """The ``Origin`` values of this server's own pages."""
        return (f"http://{HOST}:{self.port}", f"http://localhost:{self.port}")

    def page_url(self, page: str = "") -> str:
        """The URL of ``page`` ('' the live view, 'edit' the editor) with the session token."""
        return f"http://{HOST}:{self.port}/{page}?token={self.token}"

    @property
    def url(self) -> str:
        """The live view's URL, with the session token (what the command prints and opens)."""
        return self.page_url()

    def token_ok(self, given: str | None) -> bool:
        if not given:
            return False
        return hmac.compare_digest(given.encode("utf-8", "surrogateescape"),
                                   self.token.encode("ascii"))

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
        """The only file the editor saves to."""
        return self.save_path

    def editor_state(self) -> dict:
        cfg_path = self.config_path
        info = None
        if cfg_path is None:
            info = self.view.run_config()
        if isinstance(info, dict):
            config = info
        else:   # a config file not written yet starts from the built-in default
            config = editor_config(cfg_path if cfg_path is not None and cfg_path.exists()
                                   else None)
        return {"config": config, "path": str(self.save_path) if self.edit else "",
                "out": str(self.out), "editable": self.edit}

    def _confine(self, path, out=None, running: bool = False) -> None:
        """Refuse a request that is not this editor's to make (:class:`Refused`)."""
        if not self.edit:
            raise Refused("edit", "this server only views a run folder; it saves and starts "
                          "nothing (start `veriloc-rt edit CONFIG --out DIR` for that)")
        if path is not None and not _same_path(Path(path).expanduser(), self.save_path):
            raise Refused("path", f"the editor saves only to {self.save_path} (the config "
                          f"it was started on), not {short_repr(path)}")
        if running and out is not None and not _same_path(Path(out).expanduser(), self.out):
            raise Refused("out", f"the editor runs only into {self.out} (its --out), not "
                          f"{short_repr(out)}")
        if (self.config_path is None and not self._wrote_default
                and os.path.lexists(self.save_path)):
            raise Refused("path", f"{self.save_path} appeared after the editor started; it "
                          "is not overwritten (give it as CONFIG to edit it)",
                          HTTPStatus.CONFLICT)

    def save(self, data, path: str | None = None) -> Path:
        """Save ``data`` to the editor's config file; ``path``, when given, must name it.

        :raises InputError: the config's error; :class:`Refused` for another path
        """
        with self._lock:
            self._confine(path)
            written = save_config(data, self.save_path)
            self._wrote_default = True
            return written

    def start_run(self, data, config_path: str | None = None, out: str | None = None) -> dict:
        """Save ``data`` to the editor's config file and start ``veriloc-rt run`` into its
        ``--out``; ``config_path`` and ``out``, when given, must name these. The config's
        input files are checked first (the page then gets the field, not the run's message).

        :raises InputError: the config's error; :class:`Refused` for another path or folder,
            or while a run started here still runs
        """
        with self._lock:
            self._confine(config_path, out, running=True)
            if self.run_process is not None and self.run_process.status()[0] is None:
                raise Refused("out", "a run started here is still running; wait for it",
                              HTTPStatus.CONFLICT)
            exc = check_config(data, inputs=True, file_details=False)
            if exc is not None:
                raise exc
            path = save_config(data, self.save_path)
            self._wrote_default = True
            self.run_process = RunProcess(path, self.out)
            self.view = RunFolderState(self.out)
            self.view.process_status = self.run_process.status
            return {"ok": True, "path": str(path), "out": str(self.out), "view": "/"}

    def stop_run(self) -> None:
        if self.run_process is not None:
            self.run_process.stop()


def _port_error(port: int, exc: OSError) -> InputError:
    if exc.errno == errno.EADDRINUSE:
        return InputError("--port", f"{port} is in use by another program; give another port, "
                          "or --port 0 for any free one")
    return InputError("--port", f"cannot listen on {HOST}:{port} ({exc.strerror or exc})")


def _error(exc: InputError) -> dict:
    return {"ok": False, "error": f"error: {exc}", "field": exc.field}


def _body_fields(body) -> tuple:
    """(config, path, out) of a POST body, type-checked (:class:`InputError` naming the field)."""
    if not isinstance(body, dict):
        raise InputError("request", f"got {type(body).__name__}, expected a JSON object with "
                         "'config' (and 'path', 'out')")
    extra = [k for k in body if k not in BODY_FIELDS]
    if extra:
        raise InputError("request", f"unknown field {short_repr(extra[0])}; expected "
                         + ", ".join(BODY_FIELDS))
    data = body.get("config")
    if not isinstance(data, dict):
        raise InputError("config", f"got {short_repr(data)}, expected a JSON object (the config)")
    out = []
    for name in ("path", "out"):
        v = body.get(name)
        if v is not None and (not isinstance(v, str) or "\x00" in v or not v.strip()):
            raise InputError(name, f"got {short_repr(v)}, expected a path (text without NUL "
                             "bytes) or null")
        out.append(v)
    return data, out[0], out[1]


def _handler(server: LiveServer) -> type:
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"
        server_version = "veriloc-rt-live"
        timeout = TIMEOUT_S       # StreamRequestHandler sets it on the socket

        def log_message(self, fmt, *args):   # requests to the debug log, not to stderr
            log.debug("%s " + fmt, self.address_string(), *args)

        def handle_one_request(self):
            # from the request's first byte to its body's last: REQUEST_DEADLINE_S at most
            self.server.arm(self.connection, REQUEST_DEADLINE_S)
            try:
                super().handle_one_request()
            finally:
                self.server.disarm(self.connection)

        def handle(self):
            try:
                super().handle()
            except OSError as exc:   # timed out, or the client hung up: nothing to answer
                log.debug("connection from %s ended: %s", self.address_string(), exc)
                self.close_connection = True

        def end_headers(self):
            for k, v in SECURITY_HEADERS.items():
                self.send_header(k, v)
            super().end_headers()

        def _send(self, body: bytes, ctype: str, status: int = 200) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype + ("; charset=utf-8" if ctype.startswith("text") or ctype.endswith("json") else ""))
            self.send_header("Content-Length", str(len(body)))
            if self.close_connection:
                self.send_header("Connection", "close")
            self.end_headers()
            self.wfile.write(body)

        def _json(self, obj, status: int = 200) -> None:
            self._send(json.dumps(obj, allow_nan=False).encode(), "application/json", status)

        def _refuse(self, status: int, field: str, problem: str) -> None:
            self._json(_error(InputError(field, problem)), status)

        def _gate(self, api: bool) -> bool:
            """True when the request may go on; else answered (403) already."""
            host = self.headers.get("Host") or ""
            if host not in (f"{HOST}:{server.port}", f"localhost:{server.port}"):
                self.close_connection = True
                self._refuse(HTTPStatus.FORBIDDEN, "Host", "not this server's address "
                             f"({HOST}:{server.port})")
                return False
            origin = self.headers.get("Origin")
            if origin is not None and origin not in server.origins:
                self.close_connection = True
                self._refuse(HTTPStatus.FORBIDDEN, "Origin", "a page of another origin may "
                             "not use this server")
                return False
            if api and not server.token_ok(self.headers.get(TOKEN_HEADER)):
                self.close_connection = True
                self._refuse(HTTPStatus.FORBIDDEN, "token", "missing or wrong: open the URL "
                             "with ?token=... that the command printed")
                return False
            return True

        def do_GET(self):  # noqa: N802 - http.server's name
            self._safely(self._get)

        def do_POST(self):  # noqa: N802
            self._safely(self._post)

        def _safely(self, method) -> None:
            """``method()``; an unexpected error is answered 500 with one line (and logged),
            not a dropped connection."""
            try:
                method()
            except OSError:
                raise   # the connection itself failed: handle() closes it quietly
            except Exception as exc:  # noqa: BLE001 - a bug: one line, details with -vv
                log.error("%s %s failed: %s: %s", self.command, urlparse(self.path).path,
                          type(exc).__name__, exc, exc_info=log.isEnabledFor(logging.DEBUG))
                self.close_connection = True
                self._refuse(HTTPStatus.INTERNAL_SERVER_ERROR, "server",
                             f"internal error ({type(exc).__name__}); the server's log has it")

        def _get(self) -> None:
            self.server.disarm(self.connection)   # read; answering may take its time
            url = urlparse(self.path)
            path = url.path
            if not self._gate(api=path.startswith("/api/")):
                return
            q = parse_qs(url.query)
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
                layer = server.view.scene()
                if "error" in layer:   # may quote the files the run's config names
                    layer["error"] = ("the map could not be built from this run's config (the "
                                      "terminal of this server logs why)")
                return self._json(layer)
            if path == "/api/form":
                return self._json({"fields": form_fields()})
            if path == "/api/config":
                try:
                    return self._json(server.editor_state())
                except InputError as exc:
                    return self._json(_error(exc))
            return self._send(b"not found", "text/plain", HTTPStatus.NOT_FOUND)

        def _post(self) -> None:
            route = urlparse(self.path).path
            if not self._gate(api=True):
                return
            if (self.headers.get("X-Veriloc") != "1"
                    or not (self.headers.get("Content-Type") or "").startswith("application/json")):
                self.close_connection = True
                return self._refuse(HTTPStatus.FORBIDDEN, "request", "needs the headers "
                                    "X-Veriloc: 1 and Content-Type: application/json")
            if route not in ("/api/validate", "/api/save", "/api/run"):
                self.close_connection = True
                return self._send(b"not found", "text/plain", HTTPStatus.NOT_FOUND)
            try:
                n = int(self.headers.get("Content-Length") or "")
            except ValueError:
                n = -1
            if not 0 <= n <= MAX_BODY_BYTES:
                self.close_connection = True   # the body, if any, is not read
                return self._refuse(HTTPStatus.BAD_REQUEST, "Content-Length", "expected the "
                                    f"body's length, 0 .. {MAX_BODY_BYTES} bytes")
            raw = self.rfile.read(n)
            self.server.disarm(self.connection)   # read; answering may take its time
            if len(raw) < n:
                self.close_connection = True
                return self._refuse(HTTPStatus.BAD_REQUEST, "request", "body shorter than "
                                    "its Content-Length")
            try:
                try:
                    text = raw.decode("utf-8")
                except UnicodeDecodeError:
                    raise InputError("request", "not UTF-8 text") from None
                data, path, out = _body_fields(parse_json(text, "request"))
            except InputError as exc:
                return self._json(_error(exc), HTTPStatus.BAD_REQUEST)
            try:
                if route == "/api/validate":
                    exc = check_config(data, inputs=True, file_details=False)
                    return self._json({"ok": True} if exc is None else _error(exc))
                if route == "/api/save":
                    return self._json({"ok": True, "path": str(server.save(data, path))})
                return self._json(server.start_run(data, path, out))
            except Refused as exc:
                return self._json(_error(exc), exc.status)
            except InputError as exc:
                return self._json(_error(exc), HTTPStatus.BAD_REQUEST)

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


def start_view_process(folder: str | Path, port: int | None = None,
                       timeout_s: float = 60.0) -> ViewProcess:
    """Start ``veriloc-rt view --no-browser --watch-stdin -- FOLDER`` (:func:`cli_command`) and
    return it with its URL, session token included (the last word of its first output line).
    It exits when its stdin closes: when this process ends, however.

    :raises InputError: the error line it printed instead (e.g. ``--port`` in use)
    :raises RuntimeError: when it does not report a URL within ``timeout_s``
    """
    flags = [] if port is None else ["--port", str(port)]   # None: as LiveServer's
    cmd = cli_command("view", *flags, "--no-browser", "--watch-stdin", "--", str(folder))
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    line = got[0].strip() if got else ""
    words = line.split()
    if not words or not words[-1].startswith("http://"):
        proc.kill()
        proc.wait()
        if line.startswith("error: ") and ": " in line[len("error: "):]:
            field, problem = line[len("error: "):].split(": ", 1)
            raise InputError(field, problem)
        raise RuntimeError(f"the live view did not start (said {line!r})")
    return ViewProcess(proc, words[-1])
