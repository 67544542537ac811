"""The live page's server against malformed requests (issue 30): Bokeh raises ProtocolError for a
session id or a websocket subprotocol it cannot use; Tornado logged that as an "Uncaught exception"
with a traceback on serve's console and answered the page request with 500. Found by
bench/stress_serve.py page."""
from __future__ import annotations

import logging
import re
import socket
from pathlib import Path

from .conftest import serve_with_page_server

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "serve_z.toml"


def exchange(port: int, request: bytes) -> bytes:
    """Send a request (no half-close, which Tornado takes for a client that left) and read its answer:
    until the server closes, or the headers and Content-Length bytes of body are in (a websocket
    upgrade refused with 400 keeps the connection)."""
    with socket.create_connection(("127.0.0.1", port), timeout=60) as s:
        s.sendall(request)
        buf = bytearray()
        while chunk := s.recv(65536):
            buf += chunk
            head, sep, body = bytes(buf).partition(b"\r\n\r\n")
            m = re.search(rb"(?im)^content-length:\s*(\d+)", head)
            if sep and m and len(body) >= int(m.group(1)):
                break
    return bytes(buf)


def test_malformed_session_ids_and_subprotocols_are_refused_without_a_traceback(caplog):
    caplog.set_level(logging.INFO)
    with serve_with_page_server(SCN) as (_served, ui):
        host = f"Host: 127.0.0.1:{ui.port}\r\nConnection: close\r\n".encode()
        bad_id = exchange(ui.port, b"GET /?bokeh-session-id=%00 HTTP/1.1\r\n" + host + b"\r\n")
        ws_host = f"Host: 127.0.0.1:{ui.port}\r\n".encode()
        bad_ws = [exchange(ui.port, b"GET /ws HTTP/1.1\r\n" + ws_host + b"Upgrade: websocket\r\nConnection: Upgrade\r\n"
                           b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                           b"Origin: http://127.0.0.1:" + str(ui.port).encode() + b"\r\n" + proto + b"\r\n")
                  for proto in (b"", b"Sec-WebSocket-Protocol: chat\r\n", b"Sec-WebSocket-Protocol: bokeh\r\n",
                                b"Sec-WebSocket-Protocol: bokeh, nonsense\r\n")]
        good = exchange(ui.port, b"GET / HTTP/1.1\r\n" + host + b"\r\n")
    assert bad_id.startswith(b"HTTP/1.1 400 "), bad_id[:200]
    for answer in bad_ws:
        assert answer.startswith(b"HTTP/1.1 400 ") or answer.startswith(b"HTTP/1.1 403 "), answer[:200]
    assert good.startswith(b"HTTP/1.1 200 ")
    tracebacks = [r for r in caplog.records if r.exc_info or "Traceback" in r.getMessage()]
    assert not tracebacks, [r.getMessage() for r in tracebacks]
    refused = [r.getMessage() for r in caplog.records if r.name == "distctrl.ui" and "malformed" in r.getMessage()]
    assert len(refused) == 1 + len(bad_ws), refused


def masked_text_frame(payload: bytes) -> bytes:
    key = b"\x01\x02\x03\x04"
    return bytes([0x81, 0x80 | len(payload)]) + key + bytes(b ^ key[i % 4] for i, b in enumerate(payload))


def test_a_message_before_the_session_opened_closes_without_a_traceback(caplog):
    """A client that sends right after the upgrade (before Bokeh's session is set up) made Bokeh log
    "Unhandled exception receiving a message: AttributeError ... 'consume'" with a traceback."""
    caplog.set_level(logging.INFO)
    with serve_with_page_server(SCN) as (_served, ui):
        host = f"Host: 127.0.0.1:{ui.port}\r\nConnection: close\r\n".encode()
        answers = []
        for _ in range(3):
            page = exchange(ui.port, b"GET / HTTP/1.1\r\n" + host + b"\r\n")
            token = re.search(rb'"token":"([^"]+)"', page).group(1)
            upgrade = (b"GET /ws HTTP/1.1\r\n" + f"Host: 127.0.0.1:{ui.port}\r\n".encode() + b"Upgrade: websocket\r\nConnection: Upgrade\r\n"
                       b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                       b"Origin: http://127.0.0.1:" + str(ui.port).encode() + b"\r\n"
                       b"Sec-WebSocket-Protocol: bokeh, " + token + b"\r\n\r\n")
            with socket.create_connection(("127.0.0.1", ui.port), timeout=60) as s:
                s.sendall(upgrade + masked_text_frame(b'{"msgid":"1","msgtype":"PULL-DOC-REQ"}'))
                buf = bytearray()
                # until the server's close frame (0x88): it has taken the message (and closes)
                while b"\r\n\r\n" not in buf or b"\x88" not in bytes(buf).partition(b"\r\n\r\n")[2]:
                    chunk = s.recv(65536)
                    if not chunk:
                        break
                    buf += chunk
            answers.append(bytes(buf))
    assert all(a.startswith(b"HTTP/1.1 101 ") for a in answers), [a[:100] for a in answers]
    tracebacks = [r for r in caplog.records if r.exc_info or "Traceback" in r.getMessage()]
    assert not tracebacks, [r.getMessage()[:300] for r in tracebacks]


def _session_socket(port: int) -> socket.socket:
    """A real page session's websocket, open (Bokeh's ACK received)."""
    host = f"Host: 127.0.0.1:{port}\r\nConnection: close\r\n".encode()
    page = exchange(port, b"GET / HTTP/1.1\r\n" + host + b"\r\n")
    token = re.search(rb'"token":"([^"]+)"', page).group(1)
    s = socket.create_connection(("127.0.0.1", port), timeout=60)
    s.sendall(b"GET /ws HTTP/1.1\r\n" + f"Host: 127.0.0.1:{port}\r\n".encode()
              + b"Upgrade: websocket\r\nConnection: Upgrade\r\n"
              b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
              b"Sec-WebSocket-Version: 13\r\nOrigin: http://127.0.0.1:" + str(port).encode() + b"\r\n"
              b"Sec-WebSocket-Protocol: bokeh, " + token + b"\r\n\r\n")
    buf = bytearray()
    while b'"ACK"' not in buf:
        chunk = s.recv(65536)
        assert chunk, bytes(buf)[:200]
        buf += chunk
    return s


def test_a_malformed_bokeh_message_on_a_session_is_refused_without_a_traceback(caplog):
    """A PATCH-DOC without events and a request without a message id, on an open session's
    websocket: Bokeh logged "error handling message" with a KeyError traceback ('events'; 'msgid' in
    its own error answer). Found by bench/stress_serve.py page (issue 39)."""
    caplog.set_level(logging.INFO)
    messages = [(b'{"msgid":"2","msgtype":"PATCH-DOC"}', b"{}", b"{}"),
                (b'{"msgtype":"SERVER-INFO-REQ"}', b"{}", b"{}"),
                (b'{"msgid":"3","msgtype":"PATCH-DOC"}', b"{}",
                 b'{"events":[{"kind":"ModelChanged","model":{"id":"p1"},"attr":"value","new":1}]}')]
    with serve_with_page_server(SCN) as (_served, ui):
        for header, metadata, content in messages:
            with _session_socket(ui.port) as s:
                s.sendall(b"".join(masked_text_frame(m) for m in (header, metadata, content)))
                buf = bytearray()
                s.settimeout(10)
                while b"\x88" not in buf:              # the server closes the connection
                    try:
                        chunk = s.recv(65536)
                    except TimeoutError:
                        break
                    if not chunk:
                        break
                    buf += chunk
    tracebacks = [r for r in caplog.records if r.exc_info or "Traceback" in r.getMessage()]
    assert not tracebacks, [r.getMessage()[:300] for r in tracebacks]
    refused = [r.getMessage() for r in caplog.records if "refused a malformed request" in r.getMessage()]
    assert len(refused) == 3 and all("websocket message" in m for m in refused), refused
