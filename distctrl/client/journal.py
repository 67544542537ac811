"""What distctrl wrote to a machine and what of it is still pending: the write journal.

The CNC objects cannot say whether a written value is in effect. FCT-M3 §9.4 / §12.6 and TF5200 §7.5
say only that a value written to kp, i_tn, d_tv, v_max or a_max "only becomes effective" on the next
INACTIVE→ACTIVE or FREEZE→ACTIVE transition; they name no object that reads the pending value, nor
what a read returns meanwhile. distctrl's target (``distctrl serve``) answers kp / i_tn / d_tv with the
value in effect and ``DIST_CTRL_PARAM[0]::v_max`` / ``a_max`` with the pending value when one waits
(docs/objects.md); a real CNC may answer either way. So ``machine write`` notes every write here
(old value, written value, time, the axis's state), and ``machine show`` / ``write`` join what the
objects read with it:

* no entry for the value: the object's value is **in effect** (no write of distctrl waits);
* an entry whose object read the **value in effect** right after the write (kp / i_tn / d_tv on
  distctrl's target) and reads it still: in effect the old value, **pending** the written one; it reads
  the **written** value: the activation adopted it, and with it **every** pending value of the axis
  (the CNC adopts them together), the entries are done;
* an entry whose object read the **written** value right after the write (v_max / a_max on
  distctrl's target, or any object of a CNC that shows pending values) and reads it still: in effect
  the old value (the journal's), pending the written one, until an activation is seen;
* an activation is also seen when the axis was in a state without active distance control (IDLE,
  OFF, ...) after the write and is ACTIVE or FREEZE now, or was in FREEZE and is ACTIVE now (DRYRUN
  adopts nothing, SPEC §8);
* any other value: the machine was changed otherwise (another tool, the NC program's DIST_CTRL
  block, a CNC restart): the entry is dropped and the object's value shown.

A CNC restart that leaves the objects reading as before (kp / i_tn / d_tv on distctrl's target: the
value in effect) is not seen: the entry stays, though the CNC has dropped the pending value. So what
the journal says pending is a claim, shown as such ("pending unless the CNC restarted since"), and
``machine write`` never skips a value because the journal has it pending.

The journal is a JSON file, ``$DISTCTRL_MACHINE_JOURNAL`` or ``$XDG_STATE_HOME/distctrl/machine-writes.json``
(``~/.local/state/...``). It knows only the writes of this PC's distctrl.
"""
from __future__ import annotations

import datetime
import json
import math
import os
from pathlib import Path

from ..base.states import InternalState

_ACTIVE, _FREEZE, _DRYRUN = int(InternalState.ACTIVE), int(InternalState.FREEZE), int(InternalState.DRYRUN)


def _arming(state: int, armed: str | None) -> str | None:
    """What an observed state says about the next activation: "inactive" (IDLE, OFF, ERROR ...: the next
    ACTIVE or FREEZE comes through INACTIVE→ACTIVE), "freeze" (the next ACTIVE is FREEZE→ACTIVE)."""
    if state not in (_ACTIVE, _FREEZE, _DRYRUN):
        return "inactive"
    if state == _FREEZE and armed is None:
        return "freeze"
    return armed


def _adopted(state: int, armed: str | None) -> bool:
    return (armed == "inactive" and state in (_ACTIVE, _FREEZE)) or (armed == "freeze" and state == _ACTIVE)


def journal_path() -> Path:
    env = os.environ.get("DISTCTRL_MACHINE_JOURNAL")
    if env:
        return Path(env)
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "distctrl" / "machine-writes.json"


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        try:
            return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=1e-15)
        except (TypeError, ValueError):
            return False
    return a == b


class WriteJournal:
    """The pending writes of every target and axis (key: ``NETID:PORT@IP:TCP/axis/ID``)."""

    def __init__(self, path: Path | None = None):
        self.path = Path(path) if path is not None else journal_path()
        try:
            self.data = json.loads(self.path.read_text(encoding="utf-8"))
            if not isinstance(self.data, dict):
                self.data = {}
        except (OSError, ValueError):
            self.data = {}        # no journal yet, or unreadable: nothing known to be pending

    @staticmethod
    def key(target, unit) -> str:
        tcp = getattr(target, "tcp_port", 48898)
        return f"{target.net_id}:{target.port}@{target.ip}:{tcp}/{unit.kind}/{unit.number}"

    def save(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_name(self.path.name + ".tmp")
            tmp.write_text(json.dumps(self.data, indent=1, sort_keys=True), encoding="utf-8")
            tmp.replace(self.path)
        except OSError:
            pass          # a journal that cannot be written: the write itself stands; show says "in effect"

    def record(self, target, unit, written: dict, old: dict, reads: dict, state: int) -> None:
        """After a write: ``written`` {field: value}, ``old`` {field: the value in effect before},
        ``reads`` {field: "written" or "in_effect"}: what its object read back right after the write."""
        entry = self.data.setdefault(self.key(target, unit), {"pending": {}, "armed": False})
        now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
        for f, value in written.items():
            before = entry["pending"].get(f, {}).get("in_effect", old.get(f))
            if _same(value, before):
                entry["pending"].pop(f, None)      # the value in effect written again: nothing waits
            else:
                entry["pending"][f] = {"written": value, "in_effect": before, "written_at": now,
                                       "reads": reads.get(f, "written")}
        entry["armed"] = _arming(int(state), None)
        if not entry["pending"]:
            del self.data[self.key(target, unit)]
        self.save()

    def resolve(self, target, unit, readings: dict, state: int) -> dict:
        """{field: {"read", "in_effect", "pending", "written_at"}} for the writable ``readings`` (what the
        objects read now); updates the journal (adopted or stale entries go)."""
        key = self.key(target, unit)
        entry = self.data.get(key)
        out = {f: {"read": v, "in_effect": v, "pending": None, "written_at": None}
               for f, v in readings.items()}
        if not entry or not entry.get("pending"):
            return out
        pending = entry["pending"]
        armed = entry.get("armed") if entry.get("armed") in ("inactive", "freeze") else None
        adopted = _adopted(int(state), armed)
        for f, e in pending.items():
            if e.get("reads") == "in_effect" and f in readings and _same(readings[f], e["written"]):
                adopted = True            # the object reads the written value: the activation took them all
        changed = False
        if adopted:
            del self.data[key]
            changed = True
        else:
            now_armed = _arming(int(state), armed)
            if now_armed != armed:
                entry["armed"], changed = now_armed, True
            for f in list(pending):
                e = pending[f]
                if f not in readings:
                    continue
                r = readings[f]
                expected = e["in_effect"] if e.get("reads") == "in_effect" else e["written"]
                if not _same(r, expected):
                    del pending[f]        # changed otherwise since distctrl wrote it
                    changed = True
                    continue
                out[f].update(in_effect=e["in_effect"], pending=e["written"], written_at=e["written_at"])
            if not pending:
                del self.data[key]
        if changed:
            self.save()
        return out
