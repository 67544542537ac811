"""Transport of the connection threads: output flow control (a client that sends but does not read
makes the server stop reading from it, with bounded buffers, and it gets every answer, in order, once
it reads) and the frame checks on the one-frame-per-read fast path."""
from __future__ import annotations

import logging
import socket
import threading
import time

import pytest

from distctrl.ads import AdsServer
from distctrl.ads import protocol as P
from distctrl.ads import transport as S

from . import IG_DATA, MemoryDevice, RawClient, wait_for

MAX_FRAME = 4096
N_REQUESTS = 20000            # answers of 416 bytes each: ~8 MB, more than the socket buffers hold


@pytest.fixture(scope="module")
def server():
    srv = AdsServer({851: MemoryDevice()}, port=0, max_frame=MAX_FRAME)
    srv.start()
    try:
        yield srv
    finally:
        srv.stop()


def _upload_request(invoke_id: int) -> bytes:
    return P.read_request(P.ADSIGRP_SYM_UPLOAD, 0, MAX_FRAME, invoke_id=invoke_id)


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError(f"closed after {len(buf)} of {n} bytes")
        buf += chunk
    return bytes(buf)


def test_late_reader_bounded_backlog_and_every_answer_in_order(server):
    before = set(server._writers)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)     # before connect: a small window
    sock.settimeout(10.0)
    sock.connect(("127.0.0.1", server.port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    assert wait_for(lambda: len(set(server._writers) - before) == 1, timeout=5.0)
    (link,) = set(server._writers) - before
    try:
        requests = b"".join(_upload_request(i) for i in range(1, N_REQUESTS + 1))
        sent: list[BaseException | None] = []

        def send_all() -> None:
            try:
                sock.sendall(requests)
                sock.shutdown(socket.SHUT_WR)       # half-close: the answers must still come
                sent.append(None)
            except BaseException as e:  # noqa: BLE001
                sent.append(e)

        sender = threading.Thread(target=send_all, daemon=True)
        sender.start()

        # the server stops reading from this client once its answers are not read: the link's send
        # blocks (and stays blocked), everyone else is served meanwhile
        # (once the kernel's socket buffers are full: until then the sends return; on a loaded machine
        # that can take a few rounds of looking)
        worst_in = 0
        with RawClient(server.port) as good:
            deadline = time.monotonic() + 20.0
            while True:
                frames, t1 = link.conn.frames, time.monotonic()
                while time.monotonic() - t1 < 0.3:
                    assert good.read(IG_DATA, 8, 8).result == 0
                    worst_in = max(worst_in, len(link.buf))
                if link.conn.frames == frames and link.sending:
                    break                               # no request parsed in 0.3 s while blocked
                assert time.monotonic() < deadline, "the server never stopped reading this connection"
        assert frames < N_REQUESTS
        assert worst_in <= S._RECV_CHUNK + MAX_FRAME

        # now read: every answer arrives, in order, then the server closes (the client half-closed)
        # (the input buffer stays bounded during the pause/resume cycles this causes)
        for i in range(1, N_REQUESTS + 1):
            reserved, length = P.AMS_TCP_HEADER.unpack(_recv_exact(sock, P.AMS_TCP_HEADER_SIZE))
            r = P.parse_response(_recv_exact(sock, length))
            assert reserved == 0 and r.header.invoke_id == i and r.result == 0 and len(r.data) == 370
            worst_in = max(worst_in, len(link.buf))
        assert worst_in <= S._RECV_CHUNK + MAX_FRAME
        sender.join(5.0)
        assert sent == [None]
        assert sock.recv(1) == b""
        assert wait_for(lambda: link not in server._writers, timeout=5.0)
    finally:
        sock.close()


@pytest.mark.parametrize("length", [26, 31])
def test_short_frame_in_one_read_closes_like_a_split_one(server, length, caplog):
    """A whole too-short frame in one segment (the fast path) is refused like any other: the
    connection closes with the 'shorter than an AMS header' warning, not an internal error."""
    with caplog.at_level(logging.WARNING, logger="distctrl.ads"):
        with RawClient(server.port) as c:
            c.send(P.AMS_TCP_HEADER.pack(0, length) + b"\0" * length)
            assert c.is_closed_by_server()
        with RawClient(server.port) as c:                  # the server is fine
            assert c.read(IG_DATA, 8, 8).result == 0
    assert f"frame length {length} shorter than an AMS header" in caplog.text
    assert "unexpected error" not in caplog.text


def test_stop_ends_every_connection_thread_also_one_blocked_in_a_send():
    srv = AdsServer({851: MemoryDevice()}, port=0, max_frame=MAX_FRAME)
    srv.start()
    sock = socket.create_connection(("127.0.0.1", srv.port))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    try:
        assert wait_for(lambda: len(srv._writers) == 1, timeout=5.0)
        (link,) = srv._writers
        sock.settimeout(0.5)
        requests = b"".join(_upload_request(i) for i in range(1, N_REQUESTS + 1))
        try:
            sock.sendall(requests)          # the server blocks answering; so does this send
        except TimeoutError:
            pass
        assert wait_for(lambda: link.sending, timeout=20.0)
        t0 = time.monotonic()
        srv.stop()
        assert time.monotonic() - t0 < 5.0
        assert not link.thread.is_alive() and not srv._writers and srv.connections == 0
    finally:
        sock.close()
        srv.stop()
