"""The live page's web server: a Bokeh server embedded in ``distctrl serve`` (docs/ui.md).

It runs in its own thread with its own event loop (Tornado's IOLoop on a new asyncio loop), beside the
ADS server's thread and the 1 ms cycle thread; it never takes the machine's lock except for the few
microseconds of a page's write (:mod:`distctrl.ui.hub`).

* Bokeh's JavaScript and CSS come from the installed bokeh package (``/static/`` of this server); the
  page makes no outside request, and a Content-Security-Policy allows scripts and styles from this
  server (and the inline document bootstrap) only, connections to this server only.
* Listening on ``host`` (default 127.0.0.1); a client outside the ``allowed`` networks is closed at once
  and logged (``refused <ip> (UI)``), as the ADS server does; the websocket accepts only pages from
  this server's own address (Origin check), so a page of another web site cannot drive the machine.
* Several pages at once: every page (a Bokeh session) reads the same :class:`~distctrl.ui.hub.MachineHub`.
"""
from __future__ import annotations

import asyncio
import gc
import logging
import socket
import sys
import threading
import time
from pathlib import Path

from ..serve.net import address_allowed, networks
from ..serve.realtime import sched_fifo
from .hub import MachineHub

log = logging.getLogger("distctrl.ui")

#: what the page may load and connect to: this server only ('self' also covers its websocket)
CSP = ("default-src 'none'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data: blob:; font-src 'self' data:; connect-src 'self'; base-uri 'none'; "
       "form-action 'none'")
#: Python's thread switch interval while the page is served (default 5 ms): a thread holding the GIL
#: gives it up after this long when another (the 1 ms cycle) waits for it
SWITCH_INTERVAL = 0.00003
#: frames per second of every page (the scope's stream, the panels' values)
FRAME_MS = 50
#: the status line's check of every page (ms): it changes seldom, and then should show at once (a
#: state change, the override, an error, the answer to a click)
STATUS_MS = 20


class _ClosedPageFilter(logging.Filter):
    """Bokeh warns "Failed sending message as connection was closed" for every frame that was on its
    way when a page was closed: normal for a live page, so not a warning on the console."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "connection was closed" not in record.getMessage()


_CLOSED_PAGE_FILTER = _ClosedPageFilter()


def free_port(host: str) -> int:
    """A free TCP port on ``host`` (for ``--ui-port 0``)."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


class UiServer:
    """The Bokeh server of the live page over one served machine.

    :param served: a started or not yet started :class:`~distctrl.serve.machine.ServedMachine`.
    :param host: address to listen on; ``port`` 0 picks a free port (:attr:`port` tells which).
    :param allowed: networks (CIDR) whose clients may connect, like the ADS server's ``--allow``.
    :param export_dir: where the scope's "Export CSV" writes its trace files.
    """

    def __init__(self, served, *, host: str = "127.0.0.1", port: int = 8050, allowed=("127.0.0.0/8",),
                 export_dir: str | Path = ".", buffer_s: float = 60.0):
        self.served = served
        self.host = host
        self.port = int(port) or free_port(host)
        self.allowed = networks(allowed)
        self.export_dir = Path(export_dir)
        self.hub = MachineHub(served, buffer_s=buffer_s)
        self.refused = 0
        self.sessions = 0
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._server = None
        self._io_loop = None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        if self.host in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        return f"http://{host}:{self.port}/"

    def is_allowed(self, ip: str) -> bool:
        return address_allowed(ip, self.allowed)

    # ------------------------------------------------------------------ life cycle
    def start(self) -> None:
        """Start the server thread; returns once it listens (raises OSError if it cannot bind)."""
        ws_log = logging.getLogger("bokeh.server.views.ws")
        if _CLOSED_PAGE_FILTER not in ws_log.filters:
            ws_log.addFilter(_CLOSED_PAGE_FILTER)
        self._switch_interval = sys.getswitchinterval()
        if getattr(self.served.loop, "rt_priority", 0) > 0:
            # the cycle thread waits at most this long for Python's GIL while the page's thread works
            sys.setswitchinterval(SWITCH_INTERVAL)
        self._thread = threading.Thread(target=self._run, name="distctrl-ui", daemon=True)
        self._thread.start()
        self._ready.wait(30.0)
        if self._error is not None:
            raise self._error
        log.info("live page on %s (Bokeh server, allowed %s)", self.url, ", ".join(map(str, self.allowed)))
        gc.freeze()

    # What is set up once (the served machine, the Bokeh server) lives as long as the process: it is
    # moved out of the garbage collector's generations (gc.freeze), so that a full collection does not
    # traverse it while the cycle waits for the GIL. The pages are not frozen: a closed page's objects
    # must be collected.

    def stop(self) -> None:
        with self.served.lock:                     # the machine serves on without this page's recorder
            if self.hub._after_cycle in self.served.observers:
                self.served.observers.remove(self.hub._after_cycle)
        if getattr(self, "_switch_interval", None) is not None:
            sys.setswitchinterval(self._switch_interval)
        io, server = self._io_loop, self._server
        if io is None:
            return

        def _stop():
            try:
                server.stop()
            finally:
                io.stop()
        io.add_callback(_stop)
        if self._thread is not None:
            self._thread.join(10.0)
        self._io_loop = self._server = None

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()

    def _run(self) -> None:
        try:
            # Bokeh (the [ui] extra) loads here, in the page's thread; without it start() raises the
            # ModuleNotFoundError, which the command line turns into one line naming the extra
            from bokeh.application import Application
            from bokeh.application.handlers.function import FunctionHandler
            from bokeh.server.server import Server
            from tornado.ioloop import IOLoop, PeriodicCallback
        except BaseException as exc:   # noqa: BLE001 - handed to start()
            self._error = exc
            self._ready.set()
            return
        asyncio.set_event_loop(asyncio.new_event_loop())
        self._set_scheduling()
        io = IOLoop.current()
        try:
            origins = [f"127.0.0.1:{self.port}", f"localhost:{self.port}"]
            if self.host not in ("127.0.0.1", "localhost", "0.0.0.0", "::"):
                origins.append(f"{self.host}:{self.port}")
            if self.host in ("0.0.0.0", "::"):
                origins.append(f"*:{self.port}")
            server = Server({"/": Application(FunctionHandler(self._make_document))}, io_loop=io,
                            address=self.host, port=self.port, allow_websocket_origin=origins,
                            extra_patterns=[(r"/export/([^/]+)", _export_handler(), {"hub": self.hub})],
                            check_unused_sessions_milliseconds=2000, unused_session_lifetime_milliseconds=5000)
            self._guard(server)
            _harden(server._tornado)
            server.start()
        except BaseException as exc:   # noqa: BLE001 - handed to start()
            self._error = exc
            self._ready.set()
            return
        self._server, self._io_loop = server, io
        PeriodicCallback(self.hub.pump, FRAME_MS // 2).start()
        PeriodicCallback(self.hub.check_pages, STATUS_MS).start()
        self._ready.set()
        io.start()

    def _set_scheduling(self) -> None:
        """With the cycle thread on SCHED_FIFO, this thread too (one priority level below): it holds
        Python's GIL while it serialises a frame, and preempted then by another process (the browser
        drawing the page) it would keep the cycle thread waiting for the GIL (priority inversion)."""
        prio = self.served.loop.rt_priority
        if prio > 1:
            sched_fifo(prio - 1)

    def _guard(self, server) -> None:
        """Close connections from outside the allowed networks at once (as an ADS route does)."""
        http = server._http
        handle = http.handle_stream

        def handle_stream(stream, address):
            ip = address[0] if isinstance(address, tuple) else str(address)
            if not self.is_allowed(ip):
                self.refused += 1
                log.warning("refused %s (UI)", ip)
                stream.close()
                return None
            return handle(stream, address)
        http.handle_stream = handle_stream

    # ------------------------------------------------------------------ one page
    def _make_document(self, doc) -> None:
        from .page import build_page      # Bokeh (the [ui] extra): loaded when the first page opens

        self.sessions += 1
        build_page(doc, self.hub, self.export_dir, FRAME_MS)
        doc.template = _template()


class _ClientMessageError(Exception):
    """A websocket message of a client that Bokeh's handler could not take."""


def _client_error(exc: BaseException | None) -> bool:
    """An exception Bokeh raises for a request it cannot use (a malformed session id or token, a
    websocket without the "bokeh, <token>" subprotocol): the client's fault, not the server's."""
    from bokeh.protocol.exceptions import ProtocolError  # Bokeh: loaded in the page's thread (see _run)

    return isinstance(exc, (ValueError, ProtocolError))


def _ws_problem(header: str, app) -> str | None:
    """What is wrong with a websocket upgrade's subprotocol header for Bokeh (None: nothing). Bokeh's
    own checks (in its handler's open, after the 101 answer) raise for each of these, which Tornado
    logs with a traceback; here they are answered 400 before the upgrade."""
    from bokeh.util.token import check_token_signature, get_token_payload  # Bokeh: as in _run

    parts = [p.strip() for p in header.split(",")] if header else []
    if len(parts) != 2 or parts[0] != "bokeh" or not parts[1]:
        return "subprotocol is not 'bokeh, <token>'"
    token = parts[1]
    try:                                       # untrusted text: any failure to decode it is a bad token
        signed = check_token_signature(token, signed=app.sign_sessions, secret_key=app.secret_key)
        payload = get_token_payload(token)
    except Exception:  # noqa: BLE001
        return "malformed token"
    if not signed:
        return "token with an invalid signature"
    expiry = payload.get("session_expiry") if isinstance(payload, dict) else None
    if not isinstance(expiry, (int, float)) or time.time() >= expiry:
        return "token without a valid expiry"
    return None


def _harden(app) -> None:
    """Every handler of the Bokeh application (page, websocket, static files, export) answers a
    malformed request with 400 and one console line (``refused a malformed request from <ip>``)
    instead of a traceback and 500 (found by bench/stress_serve.py, issue 30). Other exceptions keep
    Tornado's handling: a real fault still shows its traceback."""
    # Tornado comes with Bokeh (the [ui] extra): loaded with it in the page's thread, as in _run
    from tornado.web import RequestHandler
    from tornado.websocket import WebSocketHandler

    class Hardened:
        def log_exception(self, typ, value, tb):
            if _client_error(value):
                log.warning("refused a malformed request from %s (UI): %s %s: %s", self.request.remote_ip,
                            self.request.method, self.request.uri[:120], value)
                return
            super().log_exception(typ, value, tb)

        def send_error(self, status_code: int = 500, **kwargs):
            exc = kwargs.get("exc_info")
            if status_code == 500 and exc is not None and _client_error(exc[1]):
                status_code = 400
            super().send_error(status_code, **kwargs)

    class HardenedWs(Hardened):
        async def get(self, *args, **kwargs):
            problem = _ws_problem(self.request.headers.get("Sec-WebSocket-Protocol", ""), self.application)
            if problem is not None:
                log.warning("refused a malformed request from %s (UI): websocket %s: %s", self.request.remote_ip,
                            self.request.uri[:120], problem)
                self.set_status(400)
                self.finish(problem)
                return
            await super().get(*args, **kwargs)

        def _refuse(self, what: str) -> None:
            log.warning("refused a malformed request from %s (UI): websocket message %s",
                        self.request.remote_ip, what)
            self.close()

        async def _handle(self, message):
            # a message a page of this server never sends: without a message id (Bokeh's answer to it
            # raised KeyError), or whose handling raises (a patch without events, of a model that is
            # not in the page): Bokeh logged each with a traceback; refused in one line, closed
            header = message.header if isinstance(getattr(message, "header", None), dict) else {}
            if not isinstance(header.get("msgid"), str):
                self._refuse(f"{header.get('msgtype', '?')!s:.40} without a message id")
                return None
            try:
                return await self.handler.handle_checked(message, self.connection)
            except _ClientMessageError as exc:
                self._refuse(f"{message.msgtype}: {exc}")
                return None

        async def on_message(self, fragment):
            # Bokeh sets up the session's receiver in a callback after the upgrade; a page waits for
            # its ACK before it sends, a client that does not is closed (Bokeh's own reaction to a
            # message it cannot take, without its traceback)
            if getattr(self, "receiver", None) is None:
                log.warning("refused a malformed request from %s (UI): websocket message before the session "
                            "opened", self.request.remote_ip)
                self.close()
                return None
            return await super().on_message(fragment)

    from bokeh.server.protocol_handler import ProtocolHandler  # Bokeh: loaded in the page thread, as in _run

    if not hasattr(ProtocolHandler, "handle_checked"):
        async def handle_checked(self, message, connection):
            """:meth:`handle` with the handler's exception raised as a client error instead of logged
            with a traceback and answered (the messages of a page of this server never raise)."""
            handler = self._handlers.get(message.msgtype)
            if handler is None:
                return await self.handle(message, connection)       # Bokeh's ProtocolError
            try:
                return await handler(message, connection)
            except Exception as exc:  # noqa: BLE001 - the client's message, see HardenedWs._handle
                raise _ClientMessageError(f"{type(exc).__name__}: {str(exc)[:120]}") from None
        ProtocolHandler.handle_checked = handle_checked

    for rule in app.wildcard_router.rules:
        target = rule.target
        if isinstance(target, type) and issubclass(target, RequestHandler):
            mixin = HardenedWs if issubclass(target, WebSocketHandler) else Hardened
            rule.target = type(f"Hardened{target.__name__}", (mixin, target), {})


_TEMPLATE = None


def _template():
    global _TEMPLATE
    if _TEMPLATE is None:
        from bokeh.core.templates import get_env

        from .live import PAGE_JS         # Bokeh, as above

        # the page's own script (distctrl.ui.live) is inline, as the CSP allows; it is no template
        # text (raw), so Jinja leaves its braces alone
        _TEMPLATE = get_env().from_string(
            '{% extends "file.html.jinja" %}{% block preamble %}'
            f'<meta http-equiv="Content-Security-Policy" content="{CSP}">'
            '<meta name="referrer" content="no-referrer">{% endblock %}'
            '{% block postamble %}<script>{% raw %}' + PAGE_JS + '{% endraw %}</script>{% endblock %}')
    return _TEMPLATE


def _export_handler():
    from tornado.web import HTTPError, RequestHandler  # Tornado (Bokeh's): as in _run

    class ExportHandler(RequestHandler):
        """The files the scope exported, by name only (nothing else on disk is reachable)."""

        def initialize(self, hub: MachineHub) -> None:
            self.hub = hub

        def get(self, name: str) -> None:
            path = self.hub.exports.get(name)
            if path is None or not path.is_file():
                raise HTTPError(404)
            self.set_header("Content-Type", "text/csv; charset=utf-8" if name.endswith(".csv")
                            else "application/json")
            self.set_header("Content-Disposition", f'attachment; filename="{name}"')
            self.set_header("Content-Security-Policy", "default-src 'none'")
            self.write(path.read_bytes())

    return ExportHandler
