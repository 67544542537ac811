"""Fuzzing the ADS server with random and malformed AMS/TCP frames (reliability suite).

Hypothesis generates valid requests with corrupted fields (AMS/TCP reserved/length, AMS header
length, command id, state flags, invoke id, target port, index group/offset, read/write lengths),
truncated frames, oversized lengths, frames split over several sends, pure random bytes and
clients that vanish mid-frame. A small model of the server's framing rules (:func:`predict`, taken
from ``docs/ads.md`` / ``distctrl/ads/transport.py``) says, for every byte stream, which frames must
be answered, which are silently ignored and whether the connection must be closed; the test checks
the server does exactly that within a socket timeout of about 1 s (never hangs).

After every fuzz input a separate well-behaved client must get correct answers to valid reads, the
simulated cycle (a thread incrementing ``MAIN.counter`` under the server lock) must keep advancing,
and the read-only object ``GVL.version`` must keep its value.

Figures: ``tally("ads_fuzz", frames=..., answered=..., closed=..., ignored=..., survived=...)``.
"""
from __future__ import annotations

import random
import socket
import struct
import threading
import time
from dataclasses import dataclass, field

import pytest
from hypothesis import given
from hypothesis import settings as _settings
from hypothesis import strategies as st

from distctrl.ads import AdsServer
from distctrl.ads import errors as E
from distctrl.ads import protocol as P
from tests.ads import IG_DATA, IG_RO, MemoryDevice, RawClient, wait_for

from .conftest import RELIABILITY as _RELIABILITY
from .conftest import stress_scale, tally

#: every example waits on real sockets (up to 0.1 s of required silence, 1 s timeouts), so the long
#: profile is capped at 500 examples per test (~1 min each) to keep `make stress` under half an hour
RELIABILITY = _settings(_RELIABILITY, max_examples=min(_RELIABILITY.max_examples, 500))

MAX_FRAME = 4096
TIMEOUT = 1.0          # longest wait for an answer / a close (no hang beyond this)
SILENT_WAIT = 0.1      # how long "no answer" is watched for when the model expects silence
RO_VALUE = 0x01020304
SUITE = "ads_fuzz"


# ---------------------------------------------------------------------------------------------
# the server under test, with a running "simulation cycle"
# ---------------------------------------------------------------------------------------------
@dataclass
class Rig:
    server: AdsServer
    device: MemoryDevice
    lock: threading.Lock
    cycles: int = 0
    stop: threading.Event = field(default_factory=threading.Event)


@pytest.fixture(scope="module")
def rig():
    lock = threading.Lock()
    device = MemoryDevice(lock=lock)   # every device call asserts the server holds the lock
    srv = AdsServer({851: device}, port=0, max_frame=MAX_FRAME, lock=lock, max_connections=256)
    r = Rig(srv, device, lock)

    def cycle() -> None:
        while not r.stop.is_set():
            with lock:
                obj = device.objects[(IG_DATA, 0)].value
                obj[:] = struct.pack("<I", (struct.unpack("<I", obj)[0] + 1) & 0xFFFFFFFF)
                r.cycles += 1
            time.sleep(0.002)

    srv.start()
    t = threading.Thread(target=cycle, name="fuzz-cycle", daemon=True)
    t.start()
    try:
        yield r
    finally:
        r.stop.set()
        t.join(2.0)
        srv.stop()


def assert_survived(rig: Rig) -> None:
    """A fresh, well-behaved client gets correct answers; the cycle advances; RO is unchanged."""
    assert rig.server.running
    with RawClient(rig.server.port, timeout=TIMEOUT) as c:
        r = c.read(IG_RO, 0, 4)
        assert r.result == 0 and struct.unpack("<I", r.data)[0] == RO_VALUE
        r = c.read(IG_DATA, 48, 2)
        assert r.result == 0 and len(r.data) == 2
        first = c.read(IG_DATA, 0, 4)
        assert first.result == 0 and len(first.data) == 4
        cycles = rig.cycles
        end = time.monotonic() + TIMEOUT
        while True:                                    # the cycle (and the server's view of it) moves
            now = c.read(IG_DATA, 0, 4)
            assert now.result == 0
            if now.data != first.data and rig.cycles > cycles:
                break
            assert time.monotonic() < end, "simulation cycle stopped advancing"
            time.sleep(0.003)
    assert rig.device.udint(0, IG_RO) == RO_VALUE
    tally(SUITE, survived=1)


# ---------------------------------------------------------------------------------------------
# model of the framing rules
# ---------------------------------------------------------------------------------------------
@dataclass
class Expect:
    answers: list[tuple[int, int, int]]   # (reserved, command, invoke id) of each expected answer
    ignored: int                          # complete frames that must get no answer
    end: str                              # "closed" or "open" (waiting for more bytes / idle)
    frames: int                           # complete frames in the stream


def predict(data: bytes) -> Expect:
    answers: list[tuple[int, int, int]] = []
    pos, ignored, frames = 0, 0, 0
    while len(data) - pos >= P.AMS_TCP_HEADER_SIZE:
        reserved, length = P.AMS_TCP_HEADER.unpack_from(data, pos)
        if length > MAX_FRAME or (reserved == 0 and length < P.AMS_HEADER_SIZE):
            return Expect(answers, ignored, "closed", frames)
        end = pos + P.AMS_TCP_HEADER_SIZE + length
        if end > len(data):
            break
        body = data[pos + P.AMS_TCP_HEADER_SIZE:end]
        pos = end
        frames += 1
        if reserved != 0:
            if reserved == P.AMS_TCP_PORT_CONNECT:
                answers.append((reserved, -1, -1))
            else:
                ignored += 1
            continue
        hdr = P.AmsHeader.unpack(body)
        if hdr.length != length - P.AMS_HEADER_SIZE:
            return Expect(answers, ignored, "closed", frames)
        if hdr.state_flags & P.SF_RESPONSE or hdr.command == P.CMD_DEVICE_NOTIFICATION:
            ignored += 1
            continue
        answers.append((0, hdr.command, hdr.invoke_id))
    return Expect(answers, ignored, "open", frames)


# ---------------------------------------------------------------------------------------------
# sending and observing
# ---------------------------------------------------------------------------------------------
def send_chunks(sock: socket.socket, chunks: list[bytes], pause: float = 0.0) -> bool:
    """Send the chunks; False if the server closed/reset the connection meanwhile."""
    try:
        for i, chunk in enumerate(chunks):
            if chunk:
                sock.sendall(chunk)
            if pause and i + 1 < len(chunks):
                time.sleep(pause)
    except (BrokenPipeError, ConnectionResetError):
        return False
    return True


def recv_exact(sock: socket.socket, n: int) -> bytes | None:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


def observe(sock: socket.socket, n_answers: int, expect_close: bool):
    """Read up to ``n_answers`` answer frames (notification frames are skipped), then watch for a
    close (``TIMEOUT``) or for silence (``SILENT_WAIT``). Returns (answers, end, reset) with end in
    "closed" / "open"."""
    answers: list[tuple[int, bytes]] = []
    sock.settimeout(TIMEOUT)
    until = None              # once the answers are in: when the watch ends, however many
    try:                      # notifications (a valid AddDeviceNotification's samples) keep coming
        while True:
            if len(answers) >= n_answers:
                if until is None:
                    until = time.monotonic() + (TIMEOUT if expect_close else SILENT_WAIT)
                left = until - time.monotonic()
                if left <= 0:
                    raise TimeoutError
                sock.settimeout(left)
            head = recv_exact(sock, P.AMS_TCP_HEADER_SIZE)
            if head is None:
                return answers, "closed", False
            reserved, length = P.AMS_TCP_HEADER.unpack(head)
            body = recv_exact(sock, length)
            if body is None:
                return answers, "closed", False
            if reserved == 0:
                hdr = P.AmsHeader.unpack(body)
                if hdr.command == P.CMD_DEVICE_NOTIFICATION and not hdr.is_response:
                    continue
            answers.append((reserved, body))
    except (ConnectionResetError, BrokenPipeError):
        return answers, "closed", True
    except TimeoutError:
        return answers, "open", False


def run_stream(rig: Rig, chunks: list[bytes], pause: float = 0.0, then: str = "close") -> Expect:
    """Send one fuzz client's byte stream (in ``chunks``) and check the server's reaction against
    :func:`predict`; then close the client (or half-close if ``then == "shutdown"``) and check the
    server drops the connection and still serves everybody else."""
    data = b"".join(chunks)
    exp = predict(data)
    # no other client is connected between examples (the previous ones may still be closing)
    assert wait_for(lambda: rig.server.connections == 0, TIMEOUT * 2), "stale connections"
    base = 0
    sock = socket.create_connection(("127.0.0.1", rig.server.port), timeout=TIMEOUT)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    try:
        assert wait_for(lambda: rig.server.connections == base + 1)
        sent_all = send_chunks(sock, chunks, pause)
        answers, end, reset = observe(sock, len(exp.answers), exp.end == "closed")
        if exp.end == "closed":
            assert end == "closed", f"server did not close within {TIMEOUT} s: {data[:64].hex()}"
        else:
            assert sent_all and end == "open", f"unexpected close: {data[:64].hex()}"
        if end == "closed" and (reset or not sent_all):
            # an RST may drop answers still in flight: only a prefix can be checked
            assert len(answers) <= len(exp.answers)
        else:
            assert len(answers) == len(exp.answers), (len(answers), exp, data[:64].hex())
        for (reserved, body), (e_res, e_cmd, e_inv) in zip(answers, exp.answers):
            assert reserved == e_res
            if reserved == P.AMS_TCP_PORT_CONNECT:
                assert len(body) == 8
                continue
            hdr = P.AmsHeader.unpack(body)
            assert hdr.command == e_cmd and hdr.invoke_id == e_inv
            assert hdr.state_flags & P.SF_RESPONSE and hdr.length == len(body) - P.AMS_HEADER_SIZE
        if then == "shutdown" and end == "open":
            sock.shutdown(socket.SHUT_WR)              # EOF (possibly mid-frame): server closes
            _, end2, _ = observe(sock, 0, True)
            assert end2 == "closed", "server kept a half-closed connection open"
            end = "closed"
    finally:
        sock.close()
    assert wait_for(lambda: rig.server.connections == base, TIMEOUT * 2), "connection not dropped"
    tally(SUITE, inputs=1, frames=exp.frames, answered=len(exp.answers), ignored=exp.ignored)
    tally(SUITE, **({"closed": 1} if exp.end == "closed" else {"left_open": 1}))
    assert_survived(rig)
    return exp


# ---------------------------------------------------------------------------------------------
# strategies
# ---------------------------------------------------------------------------------------------
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)
lengths = st.one_of(st.sampled_from([0, 1, 2, 4, 8, 21, 31, 32, 33, MAX_FRAME - 38, MAX_FRAME,
                                     MAX_FRAME + 1, 0x7FFFFFFF, 0xFFFFFFFF]), u32, st.integers(0, 64))
groups = st.one_of(st.sampled_from([IG_DATA, IG_RO, 0x4030, P.ADSIGRP_SYM_HNDBYNAME,
                                    P.ADSIGRP_SYM_VALBYNAME, P.ADSIGRP_SYM_VALBYHND,
                                    P.ADSIGRP_SYM_RELEASEHND, P.ADSIGRP_SYM_UPLOAD,
                                    P.ADSIGRP_SYM_UPLOADINFO2, P.ADSIGRP_SYM_INFOBYNAMEEX,
                                    P.ADSIGRP_SUMUP_READ, P.ADSIGRP_SUMUP_WRITE,
                                    P.ADSIGRP_SUMUP_READWRITE]), u32)
offsets = st.one_of(st.sampled_from([0, 8, 16, 20, 48, 1, 2, 3]), u32)
payload = st.binary(max_size=64)


@st.composite
def valid_requests(draw) -> bytes:
    kind = draw(st.sampled_from(["read", "write", "rw", "state", "info", "ctrl", "addnote",
                                 "delnote", "raw"]))
    kw = {"invoke_id": draw(u32)}
    ig, io = draw(groups), draw(offsets)
    if kind == "read":
        return P.read_request(ig, io, draw(lengths), **kw)
    if kind == "write":
        return P.write_request(ig, io, draw(payload), **kw)
    if kind == "rw":
        return P.read_write_request(ig, io, draw(lengths), draw(payload), **kw)
    if kind == "state":
        return P.request(P.CMD_READ_STATE, b"", **kw)
    if kind == "info":
        return P.request(P.CMD_READ_DEVICE_INFO, b"", **kw)
    if kind == "ctrl":
        return P.request(P.CMD_WRITE_CONTROL, P.WRITE_CONTROL_REQ.pack(draw(u16), draw(u16), 0), **kw)
    if kind == "addnote":
        data = P.ADD_NOTIFICATION_REQ.pack(ig, io, draw(lengths), draw(st.integers(0, 5)), 0,
                                           draw(st.integers(0, 10_000_000)), b"")
        return P.request(P.CMD_ADD_DEVICE_NOTIFICATION, data, **kw)
    if kind == "delnote":
        return P.request(P.CMD_DEL_DEVICE_NOTIFICATION, struct.pack("<I", draw(u32)), **kw)
    return P.request(draw(u16), draw(payload), **kw)


#: (offset in the frame, struct format) of the fields that get corrupted
FIELDS = {
    "tcp_reserved": (0, "<H"),
    "tcp_length": (2, "<I"),
    "target_port": (12, "<H"),
    "command": (22, "<H"),
    "state_flags": (24, "<H"),
    "ams_length": (26, "<I"),
    "error_code": (30, "<I"),
    "invoke_id": (34, "<I"),
    "index_group": (38, "<I"),
    "index_offset": (42, "<I"),
    "rw_length": (46, "<I"),       # read length (Read/ReadWrite) or write length (Write)
    "write_length": (50, "<I"),    # ReadWrite write length
}
FIELD_VALUES = {
    "<H": st.one_of(st.sampled_from([0, 1, 2, 3, 4, 5, 8, 9, 0x1000, 0x0001, 0x0005, 0x0004, 0xFFFF]), u16),
    "<I": lengths,
}


@st.composite
def corrupted_frames(draw) -> bytes:
    frame = bytearray(draw(valid_requests()))
    names = draw(st.lists(st.sampled_from(sorted(FIELDS)), min_size=1, max_size=3, unique=True))
    for name in names:
        off, fmt = FIELDS[name]
        if off + struct.calcsize(fmt) <= len(frame):
            struct.pack_into(fmt, frame, off, draw(FIELD_VALUES[fmt]))
    how = draw(st.sampled_from(["as is", "as is", "truncate", "append"]))
    if how == "truncate":
        frame = frame[:draw(st.integers(0, len(frame) - 1))]
    elif how == "append":
        frame += draw(st.binary(min_size=1, max_size=64))
    return bytes(frame)


def split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts} | {0, len(data)})
    return [data[a:b] for a, b in zip(points, points[1:])]


# ---------------------------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------------------------
@RELIABILITY
@given(frame=corrupted_frames())
def test_corrupted_frames(rig, frame):
    run_stream(rig, [frame])


@RELIABILITY
@given(data=st.binary(max_size=200))
def test_random_bytes(rig, data):
    run_stream(rig, [data])


@RELIABILITY
@given(frames=st.lists(st.one_of(valid_requests(), corrupted_frames()), min_size=1, max_size=4),
       cuts=st.lists(st.integers(0, 10_000), min_size=1, max_size=6))
def test_frames_split_across_sends(rig, frames, cuts):
    run_stream(rig, split(b"".join(frames), cuts), pause=0.002)


@RELIABILITY
@given(reserved=st.sampled_from([0, 0, 1, 0x1000, 0x4242]),
       length=st.one_of(st.integers(MAX_FRAME + 1, 0xFFFFFFFF), st.sampled_from([MAX_FRAME + 1, 0xFFFFFFFF])),
       tail=st.binary(max_size=100))
def test_oversized_lengths(rig, reserved, length, tail):
    exp = run_stream(rig, [P.AMS_TCP_HEADER.pack(reserved, length) + tail])
    assert exp.end == "closed"


@RELIABILITY
@given(frame=st.one_of(valid_requests(), corrupted_frames()), cut=st.integers(0, 10_000),
       how=st.sampled_from(["close", "shutdown"]))
def test_disconnect_mid_frame(rig, frame, cut, how):
    """A client sends part of a frame and then closes (or half-closes) its socket."""
    run_stream(rig, [frame[:cut % max(len(frame), 1)]], then=how)


@pytest.mark.parametrize("mode", [3, 4])            # cyclic, on change
def test_a_valid_notification_stream_does_not_stall_the_watch(rig, mode):
    """A valid AddDeviceNotification makes the server send samples every 10 ms: the fuzz harness's
    'silence' watch must still end (it once restarted its timeout at every sample and hung)."""
    data = P.ADD_NOTIFICATION_REQ.pack(IG_DATA, 0, 4, mode, 0, 100_000, b"")   # 10 ms in 100 ns
    done: list[Expect] = []
    t = threading.Thread(target=lambda: done.append(run_stream(rig, [P.request(
        P.CMD_ADD_DEVICE_NOTIFICATION, data, invoke_id=7)])), daemon=True)
    t.start()
    t.join(30.0)
    assert not t.is_alive(), "the watch never ended"
    assert done and done[0].end == "open" and len(done[0].answers) == 1


@st.composite
def read_only_writes(draw, handle: int):
    value = draw(st.binary(min_size=0, max_size=8))
    kind = draw(st.sampled_from(["raw", "rw", "handle", "sum"]))
    io = draw(st.one_of(st.just(0), offsets))
    if kind == "raw":
        return kind, P.write_request(IG_RO, io, value)
    if kind == "rw":
        return kind, P.read_write_request(IG_RO, io, 0, value)
    if kind == "handle":
        return kind, P.write_request(P.ADSIGRP_SYM_VALBYHND, handle, value)
    n = draw(st.integers(1, 3))
    subs = b"".join(P.SUM_REQ.pack(IG_RO, io, len(value)) for _ in range(n))
    return kind, P.read_write_request(P.ADSIGRP_SUMUP_WRITE, n, 4 * n, subs + value * n)


@RELIABILITY
@given(data=st.data())
def test_writes_to_read_only_are_refused(rig, data):
    with RawClient(rig.server.port, timeout=TIMEOUT) as c:
        handle = c.handle("GVL.version")
        kind, frame = data.draw(read_only_writes(handle))
        c.send(frame)
        r = c.recv_response()
        if kind == "sum":
            assert r.result != 0 or any(struct.unpack_from("<I", r.data, 4 * i)[0] != 0
                                        for i in range(len(r.data) // 4))
        else:
            assert r.result != 0, f"write to a read-only object accepted: {frame.hex()}"
        assert c.read(IG_RO, 0, 4).data == struct.pack("<I", RO_VALUE)
    assert rig.device.udint(0, IG_RO) == RO_VALUE
    tally(SUITE, ro_writes=1, ro_refused=1)


def test_concurrent_clients_some_sending_garbage(rig):
    """Good clients keep getting correct answers while others send garbage at the same time."""
    n_good, n_bad = 12, 8
    reads = stress_scale(40, 400)
    errors: list[str] = []
    counts = {"good_reads": 0, "garbage_streams": 0}
    count_lock = threading.Lock()
    start = threading.Barrier(n_good + n_bad)

    def good(k: int) -> None:
        try:
            with RawClient(rig.server.port, timeout=TIMEOUT * 2) as c:
                start.wait(5)
                for i in range(reads):
                    r = c.read(IG_RO, 0, 4) if i % 2 else c.read(IG_DATA, 8, 8)
                    if r.result != 0 or (i % 2 and r.data != struct.pack("<I", RO_VALUE)):
                        errors.append(f"good {k}: result 0x{r.result:X} data {r.data.hex()}")
                    with count_lock:
                        counts["good_reads"] += 1
        except Exception as e:  # noqa: BLE001
            errors.append(f"good {k}: {e!r}")

    def bad(k: int) -> None:
        rnd = random.Random(1000 + k)
        try:
            start.wait(5)
        except threading.BrokenBarrierError:
            return
        for _ in range(stress_scale(15, 150)):
            frame = bytearray(P.read_request(IG_DATA, 0, 4, invoke_id=rnd.getrandbits(32)))
            choice = rnd.randrange(4)
            if choice == 0:
                data = rnd.randbytes(rnd.randrange(1, 300))
            elif choice == 1:
                struct.pack_into("<I", frame, 2, rnd.getrandbits(32))
                data = bytes(frame)
            elif choice == 2:
                struct.pack_into("<I", frame, 26, rnd.getrandbits(32))
                data = bytes(frame)
            else:
                data = bytes(frame[:rnd.randrange(len(frame))])
            try:
                with socket.create_connection(("127.0.0.1", rig.server.port), timeout=TIMEOUT) as s:
                    s.sendall(data)
                    s.settimeout(0.05)
                    try:
                        s.recv(4096)
                    except (TimeoutError, ConnectionResetError):
                        pass
            except OSError as e:
                errors.append(f"bad {k}: could not connect/send: {e!r}")
            with count_lock:
                counts["garbage_streams"] += 1

    threads = [threading.Thread(target=good, args=(k,)) for k in range(n_good)]
    threads += [threading.Thread(target=bad, args=(k,)) for k in range(n_bad)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not any(t.is_alive() for t in threads), "a client thread hung"
    assert not errors, errors[:5]
    assert counts["good_reads"] == n_good * reads
    tally(SUITE, concurrent_good_reads=counts["good_reads"],
          concurrent_garbage_streams=counts["garbage_streams"])
    assert_survived(rig)


def test_model_sanity():
    """The framing model itself, on the hand-written cases of tests/ads/test_robustness.py."""
    ok = P.read_request(IG_DATA, 0, 4, invoke_id=7)
    assert predict(ok) == Expect([(0, P.CMD_READ, 7)], 0, "open", 1)
    assert predict(ok * 3).answers == [(0, P.CMD_READ, 7)] * 3
    assert predict(ok[:20]).end == "open" and predict(ok[:20]).frames == 0
    assert predict(P.AMS_TCP_HEADER.pack(0, 10) + b"\0" * 10).end == "closed"
    assert predict(P.AMS_TCP_HEADER.pack(0, MAX_FRAME + 1)).end == "closed"
    assert predict(P.AMS_TCP_HEADER.pack(0x4242, 5) + b"abcde" + ok).answers == [(0, P.CMD_READ, 7)]
    bad = bytearray(ok)
    struct.pack_into("<I", bad, 26, 99)
    assert predict(bytes(bad)).end == "closed"
    assert E.ADSERR_DEVICE_INVALIDACCESS == 0x704
