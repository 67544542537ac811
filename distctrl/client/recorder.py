"""``machine record``: CNC objects of one axis recorded at the CNC cycle by cyclic device
notifications (ADSTRANS_SERVERCYCLE with the cycle time, TF5200 ADS), with the target's timestamps.

Every signal is one notification on its object; the target sends each cycle's sample with the
cycle's timestamp, batched up to ``max_delay`` (fewer frames, the same samples). The samples are
put together by timestamp. A cycle whose timestamp is missing for a signal is *lost* for it: its row
is written with NaN there (a gap is never filled with data); a sample that arrives with a timestamp
not after the last one of its signal is *late* (out of order, or repeated) and not used.

A target that stops sending before the recording's time is up (the CNC or the connection went away,
the notifications were deleted) leaves no stamps to count as lost: that *cut* is measured in wall
time (nothing arrived for :data:`STALL_S` or more up to the end) and makes the recording incomplete.
"""
from __future__ import annotations

import ctypes
import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from ..objects.registry import BY_NAME, ObjectSpec, decode, find_spec
from ..trace import TraceRecorder
from .axes import Unit
from .target import MachineError, Target

#: FILETIME ticks (100 ns) per second
TICKS = 10_000_000
#: seconds without a new sample at the end of a recording after which the target counts as having
#: stopped sending (the samples come every ``max_delay`` at the latest, 50 ms by default)
STALL_S = 1.5


@dataclass(frozen=True)
class Signal:
    name: str            # the column's suffix: Z.command
    spec: ObjectSpec
    scale: float         # object unit -> column unit
    unit: str


#: short names -> (object, column unit); mm values converted from 0.01 nm (SGN64) objects
SIGNALS = {
    "command": ("sollw_absolut", "mm"),
    "program": ("m_sollw_absolut", "mm"),
    "actual": ("dig act pos", "mm"),
    "sensor": ("DIST_CTRL::sensor_value", "mm"),
    "offset": ("DIST_CTRL::m_actual_offset", "mm"),
    "feedback": ("DIST_CTRL::feedback_value", "mm"),
    "deviation": ("DIST_CTRL::target_deviation", "mm"),
    "state": ("DIST_CTRL::state", "-"),
}
DEFAULT_SIGNALS = ("command", "actual", "sensor", "offset", "state")


def make_signal(name: str, resolution_mm: float) -> Signal:
    """A signal by short name (:data:`SIGNALS`) or CNC object name (DIST_CTRL::kp)."""
    obj, unit = SIGNALS.get(name, (None, None))
    try:
        spec = BY_NAME[obj] if obj else find_spec(name)
    except KeyError as exc:
        raise MachineError(f"--signals: {exc.args[0]}; short names: {', '.join(SIGNALS)}") from None
    if spec.type in ("STRING",):
        raise MachineError(f"--signals: {spec.name} is a STRING, not a signal to record")
    if spec.unit == "0.01 nm":
        scale, unit = 1e-8, "mm"
    elif spec.unit == "Incr.":
        scale, unit = float(resolution_mm), "mm"
    else:
        scale, unit = 1.0, spec.unit
    return Signal(name if obj else spec.name.replace("::", "."), spec, scale, unit)


@dataclass
class Recording:
    columns: list[str]
    units: list[str]
    data: np.ndarray          # rows x columns (t first), NaN where a sample was lost
    samples: int              # samples received and used
    lost: dict                # signal -> cycles missing between the first and last stamp
    late: int                 # samples out of order or repeated (not used)
    cycle_s: float
    interrupted: bool
    first_stamp: int | None
    requested_s: float | None = None      # the recording's length asked for (wall time)
    stopped_after_s: float | None = None  # wall time from the start to the last sample that arrived
    cut_s: float = 0.0                    # wall time at the end in which nothing arrived (0: no cut)

    @property
    def rows(self) -> int:
        return int(self.data.shape[0])

    @property
    def lost_total(self) -> int:
        return int(sum(self.lost.values()))


_DATA_OFFSET = None
#: the C callbacks of deleted notifications, kept alive (see :meth:`Recorder.stop`); a few hundred
#: bytes each, the last thousand kept
_KEEP_ALIVE: list = []
_KEEP_ALIVE_MAX = 1000


def _data_offset(pyads) -> int:
    global _DATA_OFFSET
    if _DATA_OFFSET is None:
        _DATA_OFFSET = pyads.structs.SAdsNotificationHeader.data.offset
    return _DATA_OFFSET


class Recorder:
    """Cyclic notifications on ``signals`` of ``unit``; :meth:`start`, then :meth:`stop` and
    :meth:`result`. The callback only appends (handle, stamp, bytes) to a list: the decoding happens
    once at the end, with numpy."""

    def __init__(self, target: Target, unit: Unit, signals: list[Signal], cycle_s: float = 0.001,
                 max_delay_s: float = 0.05):
        self.target, self.unit, self.signals = target, unit, list(signals)
        self.cycle_s, self.max_delay_s = float(cycle_s), float(max_delay_s)
        self.raw: list = []
        self.handles: list = []
        self.by_handle: dict[int, int] = {}
        self.interrupted = False
        self.requested_s = None
        self.stopped_after_s = None
        self.cut_s = 0.0
        self._lock = threading.Lock()

    def start(self) -> None:
        # pyads (the [ads] extra): loaded only when a target is reached
        import pyads

        conn = self.target.conn
        raw_append = self.raw.append
        off = _data_offset(pyads)
        string_at, addressof = ctypes.string_at, ctypes.addressof

        def callback(notification, _name, raw_append=raw_append, off=off):
            h = notification.contents
            raw_append((h.hNotification, h.nTimeStamp, string_at(addressof(h) + off, h.cbSampleSize)))

        self._callback = callback
        for i, s in enumerate(self.signals):
            ig, io = self.unit.address(s.spec)
            attr = pyads.NotificationAttrib(s.spec.length, pyads.ADSTRANS_SERVERCYCLE,
                                            self.max_delay_s * 1e3, self.cycle_s * 1e3)
            what = f"adding a cyclic notification on {s.spec.name} of {self.unit.label} (0x{ig:X}:0x{io:X})"
            handles = self.target._call(what, conn.add_device_notification, (ig, io), attr, callback)
            self.handles.append(handles)
            self.by_handle[handles[0]] = i

    def stop(self) -> None:
        # pyads (the [ads] extra): loaded only when a target is reached
        import pyads

        conn = self.target.conn
        store = getattr(pyads.pyads_ex, "callback_store", {})
        for h in self.handles:
            # pyads drops its reference to the C callback right after the delete, while AdsLib's
            # dispatcher thread may still be calling it with a sample that was already queued: keep
            # the callback alive (a segmentation fault otherwise, seen under load)
            thunk = store.get((getattr(conn, "_adr", None), h[0]))
            if thunk is not None:
                _KEEP_ALIVE.append(thunk)
            try:
                conn.del_device_notification(*h)
            except Exception:        # noqa: BLE001 - a broken connection: the samples so far are kept
                pass
        del _KEEP_ALIVE[:-_KEEP_ALIVE_MAX]
        self.handles = []

    def result(self) -> Recording:
        raw = list(self.raw)
        n = len(self.signals)
        per: list[dict[int, bytes]] = [dict() for _ in range(n)]
        last = [-1] * n
        late = 0
        for handle, stamp, data in raw:
            i = self.by_handle.get(handle)
            if i is None:
                continue
            if stamp <= last[i]:
                late += 1
                continue
            last[i] = stamp
            per[i][stamp] = data
        stamps = sorted(set().union(*[set(p) for p in per])) if n else []
        cols = ["t"] + [f"{self.unit.name}.{s.name}" for s in self.signals]
        units = ["s"] + [s.unit for s in self.signals]
        if not stamps:
            return Recording(cols, units, np.zeros((0, n + 1)), 0, {s.name: 0 for s in self.signals}, late,
                             self.cycle_s, self.interrupted, None, self.requested_s, self.stopped_after_s,
                             self.cut_s)
        t0 = stamps[0]
        tick = self.cycle_s * TICKS
        k = np.rint((np.asarray(stamps, dtype=np.float64) - t0) / tick).astype(np.int64)
        rows = int(k[-1]) + 1
        data = np.full((rows, n + 1), np.nan)
        data[:, 0] = np.arange(rows) * self.cycle_s
        index = dict(zip(stamps, k.tolist()))
        firsts, lasts = [], []
        for i, s in enumerate(self.signals):
            col = data[:, i + 1]
            for stamp, d in per[i].items():
                col[index[stamp]] = float(decode(s.spec, d)) * s.scale
            got = np.flatnonzero(~np.isnan(col))
            firsts.append(int(got[0]) if len(got) else rows)
            lasts.append(int(got[-1]) if len(got) else -1)
        # the notifications start (and end) one after the other: the rows where every signal runs
        lo, hi = max(firsts), min(lasts)
        if hi < lo:
            data = data[:0]
        else:
            data = data[lo:hi + 1].copy()
            data[:, 0] -= data[0, 0]
        lost = {s.name: int(np.isnan(data[:, i + 1]).sum()) for i, s in enumerate(self.signals)}
        used = int((~np.isnan(data[:, 1:])).sum())
        first = t0 + int(round(lo * tick)) if hi >= lo else None
        return Recording(cols, units, data, used, lost, late, self.cycle_s, self.interrupted, first,
                         self.requested_s, self.stopped_after_s, self.cut_s)


def record(target: Target, unit: Unit, signals: list[Signal], seconds: float, cycle_s: float = 0.001,
           max_delay_s: float = 0.05, on_progress=None) -> Recording:
    """Record for ``seconds`` (wall time); Ctrl-C ends early and keeps what arrived. A target that stops
    sending before the end is measured (``stopped_after_s``, ``cut_s``)."""
    rec = Recorder(target, unit, signals, cycle_s, max_delay_s)
    rec.requested_s = float(seconds)
    rec.start()
    start = time.monotonic()
    last_growth, seen = None, 0
    try:
        deadline = start + seconds
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            time.sleep(min(0.1, left))
            n = len(rec.raw)
            if n != seen:
                seen, last_growth = n, time.monotonic()
            if on_progress is not None:
                on_progress(n)
    except KeyboardInterrupt:
        rec.interrupted = True
    finally:
        end = time.monotonic()          # before the deletes, which wait on a target that went away
        try:
            rec.stop()
        except KeyboardInterrupt:          # a second Ctrl-C while deleting: keep the samples anyway
            rec.interrupted = True
        time.sleep(0)
    if last_growth is not None:
        rec.stopped_after_s = last_growth - start
        quiet = end - last_growth
        if quiet >= max(STALL_S, 4 * max_delay_s) and not rec.interrupted:
            rec.cut_s = quiet
    return rec.result()


def write_trace(recording: Recording, path, meta: dict) -> None:
    """The recording as a distctrl trace (CSV + ``.meta.json`` sidecar, docs/trace.md)."""
    m = dict(meta)
    s = summary(recording)
    m.update({"cycle_s": recording.cycle_s, "source": "machine record (ADS cyclic notifications)",
              "samples": recording.samples, "lost": recording.lost, "late": recording.late,
              "interrupted": recording.interrupted,
              "first_stamp_filetime": recording.first_stamp, "complete": s["complete"],
              "requested_s": s["requested_s"], "stopped_after_s": s["stopped_after_s"], "cut_s": s["cut_s"],
              "cut_cycles": s["cut_cycles"]})
    rec = TraceRecorder(recording.columns, dict(zip(recording.columns, recording.units)), csv_path=str(path), keep=False, meta=m)
    try:
        for row in recording.data:
            rec.append(tuple(float(v) for v in row))
    finally:
        # the sidecar's "complete": false when the recording ended before its time (cut, Ctrl-C)
        rec.close(complete=not (s["cut_s"] or recording.interrupted))


def summary(recording: Recording) -> dict:
    """The figures of a recording; ``complete`` only when nothing was lost, late, cut or interrupted.
    ``cut_cycles``: the cycles the cut would have held at the nominal cycle (an estimate)."""
    seconds = recording.rows * recording.cycle_s
    cut = float(recording.cut_s or 0.0)
    return {"rows": recording.rows, "seconds": seconds, "samples": recording.samples,
            "lost": recording.lost, "lost_total": recording.lost_total, "late": recording.late,
            "interrupted": recording.interrupted, "cycle_s": recording.cycle_s,
            "requested_s": recording.requested_s, "stopped_after_s": recording.stopped_after_s,
            "cut_s": cut, "cut_cycles": int(round(cut / recording.cycle_s)) if cut else 0,
            "complete": (recording.lost_total == 0 and recording.late == 0 and not math.isnan(seconds)
                         and cut == 0.0 and not recording.interrupted)}


def cut_message(recording: Recording) -> str | None:
    """One line for a recording the target stopped sending to before its end, else None."""
    s = summary(recording)
    if not s["cut_s"]:
        return None
    return (f"the target stopped sending after {s['stopped_after_s']:.1f} s of {s['requested_s']:g} s: "
            f"nothing "
            f"arrived in the last {s['cut_s']:.1f} s (about {s['cut_cycles']} cycles of "
            f"{recording.cycle_s * 1e3:g} ms missing at the end); the trace holds the {s['rows']} cycles "
            f"({s['seconds']:.3f} s) that arrived")


#: a tracking figure leaves out the approach: the first cycles after each activation
APPROACH_S = 0.3


def tracking_figures(rec) -> dict | None:
    """RMS and max of DIST_CTRL::target_deviation while ACTIVE (state 2), over the activations that
    *start* inside the recording (an activation under way when it began may still run with values
    from before a write), each without its first :data:`APPROACH_S` (the approach). None without
    the deviation and state signals."""
    cols = rec.columns
    dev = next((i for i, c in enumerate(cols)
                if c.endswith(".deviation") or c.endswith(".DIST_CTRL.target_deviation")), None)
    st = next((i for i, c in enumerate(cols) if c.endswith(".state") or c.endswith(".DIST_CTRL.state")), None)
    if dev is None or st is None or rec.rows == 0:
        return None
    d, state = rec.data[:, dev], rec.data[:, st]
    active = state == 2
    skip = int(round(APPROACH_S / rec.cycle_s))
    keep = np.zeros(len(d), dtype=bool)
    starts = np.flatnonzero(active[1:] & ~active[:-1]) + 1
    for a in starts:
        b = a
        while b < len(d) and active[b]:
            b += 1
        keep[a + skip:b] = True
    keep &= ~np.isnan(d)
    n = int(keep.sum())
    if not n:
        return {"rms_mm": None, "max_abs_mm": None, "activations": int(len(starts)), "cycles": 0,
                "skip_s": APPROACH_S}
    x = d[keep]
    return {"rms_mm": float(np.sqrt(np.mean(x ** 2))), "max_abs_mm": float(np.max(np.abs(x))),
            "activations": int(len(starts)), "cycles": n, "skip_s": APPROACH_S}
