"""A stand-in CNC target and a faulty line to it, for the client-side fault tests (issue 30).

* :class:`MemoryCnc`: the distance-control objects of one axis (axis_id 3) in memory; a write takes
  effect at once (every object reads what was last written), checked as the served objects check it.
* :class:`FaultyLine`: a TCP relay on ``host:48898`` (where pyads' AdsLib connects) to an
  :class:`~distctrl.ads.AdsServer` elsewhere, that on command stays silent, answers garbage, answers
  late, or cuts the connection at the n-th Write request (before it reaches the target).
"""
from __future__ import annotations

import socket
import struct
import threading
import time

from distctrl.ads import AdsError
from distctrl.ads import errors as E
from distctrl.control.controller import check_object_value
from distctrl.objects.registry import BY_NAME, INDEX_GROUP, ObjectValueError, decode, encode

AXIS = 3
CMD_WRITE = 3
INITIAL = {"DIST_CTRL::state": 0, "DIST_CTRL::kp": 0.5, "DIST_CTRL::i_tn": 0.0, "DIST_CTRL::d_tv": 0.002,
           "DIST_CTRL_PARAM[0]::v_max": 200000, "DIST_CTRL_PARAM[0]::a_max": 20000, "DIST_CTRL::n_cycles": 4,
           "DIST_CTRL::filter_type": "MOVING_AVERAGE", "DIST_CTRL::kalman_sigma": 4.0,
           "DIST_CTRL::smoothing_fact": 0.7}


class MemoryCnc:
    name = "memory CNC"
    version = (1, 0, 0)

    def __init__(self):
        self.values = dict(INITIAL)
        self.by_offset = {(AXIS << 16) | BY_NAME[n].low_offset: BY_NAME[n] for n in self.values}
        self.writes: list[tuple[str, object]] = []

    def _spec(self, ig: int, io: int):
        if ig != INDEX_GROUP:
            raise AdsError(E.ADSERR_DEVICE_INVALIDGRP)
        spec = self.by_offset.get(io)
        if spec is None:
            raise AdsError(E.ADSERR_DEVICE_INVALIDOFFSET)
        return spec

    def read(self, ig: int, io: int, length: int) -> bytes:
        if ig == 0xF100:
            return struct.pack("<HH", 5, 0)[:length]
        spec = self._spec(ig, io)
        if length != spec.length:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE)
        return encode(spec, self.values[spec.name])

    def write(self, ig: int, io: int, data: bytes) -> None:
        spec = self._spec(ig, io)
        if not spec.writable:
            raise AdsError(E.ADSERR_DEVICE_INVALIDACCESS)
        try:
            value = decode(spec, data)
        except ObjectValueError:
            raise AdsError(E.ADSERR_DEVICE_INVALIDSIZE) from None
        if check_object_value(spec.write_name, float(value) * spec.write_scale):
            raise AdsError(E.ADSERR_DEVICE_INVALIDDATA)
        self.values[spec.name] = value
        self.writes.append((spec.short_name, value))

    def symbols(self) -> dict:
        return {}

    def state(self) -> tuple[int, int]:
        return 5, 0


def _recv_frame(sock: socket.socket) -> bytes | None:
    head = b""
    while len(head) < 6:
        chunk = sock.recv(6 - len(head))
        if not chunk:
            return None
        head += chunk
    length = struct.unpack_from("<I", head, 2)[0]
    body = b""
    while len(body) < length:
        chunk = sock.recv(length - len(body))
        if not chunk:
            return None
        body += chunk
    return head + body


class FaultyLine:
    """The relay. ``mode``: "pass", "silent" (requests swallowed), "garbage" (every request answered
    with bytes that are no AMS answer), "slow" (answers held ``delay`` s), "cut_at_write" (the
    connection closed when Write number ``cut_after + 1`` arrives; later connections pass)."""

    def __init__(self, host: str, target_port: int, mode: str = "pass", delay: float = 3.0, cut_after: int = 1):
        self.host, self.target_port = host, target_port
        self.mode, self.delay, self.cut_after = mode, delay, cut_after
        self.writes_seen = 0
        self.cuts = 0
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, 48898))
        self.listener.listen(8)
        self.closed = False
        self.threads: list[threading.Thread] = []
        self.socks: list[socket.socket] = []
        t = threading.Thread(target=self._accept, daemon=True, name="faulty-line accept")
        t.start()
        self.threads.append(t)

    def _accept(self) -> None:
        while not self.closed:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            upstream = socket.create_connection(("127.0.0.1", self.target_port))
            self.socks += [client, upstream]
            for a, b, up in ((client, upstream, True), (upstream, client, False)):
                t = threading.Thread(target=self._pump, args=(a, b, up), daemon=True, name="faulty-line pump")
                t.start()
                self.threads.append(t)

    def _pump(self, src: socket.socket, dst: socket.socket, upstream: bool) -> None:
        try:
            while True:
                frame = _recv_frame(src)
                if frame is None:
                    break
                if upstream:
                    if self.mode == "silent":
                        continue
                    if self.mode == "garbage":
                        src.sendall(b"\x00\x00" + struct.pack("<I", 40) + bytes(range(40)))
                        continue
                    if self.mode == "cut_at_write" and len(frame) >= 24 and \
                            struct.unpack_from("<H", frame, 6 + 16)[0] == CMD_WRITE:
                        self.writes_seen += 1
                        if self.writes_seen > self.cut_after and not self.cuts:
                            self.cuts += 1
                            break
                elif self.mode == "slow":
                    time.sleep(self.delay)
                dst.sendall(frame)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                s.close()

    def close(self) -> None:
        self.closed = True
        self.listener.close()
        for s in self.socks:
            try:
                s.close()
            except OSError:
                pass
