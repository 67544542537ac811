"""``machine write``: the writable distance-control objects of one axis (or 3D channel) set from a
parameter list, safely: the plan first (old -> new, nothing written), a backup of the old values
before the first write, every value read back and verified, and on any failure half way the values
already written restored from the backup and verified -- never a half-written set.

The adoption rule (FCT-M3 §9.4, §12.6 remarks; TF5200 §7.5): a value written to kp, i_tn, d_tv,
v_max or a_max becomes effective only on the next INACTIVE→ACTIVE or FREEZE→ACTIVE transition; until
then it is *pending*. While distance control is active that means the running process keeps the old
values, so a write then is refused unless ``pending=True``. The objects DIST_CTRL_PARAM[0]::v_max /
a_max read the pending value (distctrl's target); DIST_CTRL::kp / i_tn / d_tv read the working value
(the one in effect) until the activation adopts the written one: a read-back equal to the old value
is pending there, any other value than old or new fails the verification. Every written value is
*pending* after the write; what is in effect and what is pending later is the write journal's
business (:mod:`.journal`), which ``machine show`` and the next plan read.

The filter (type, n_cycles, smoothing factor, Kalman sigma, low-pass order and cut-off) cannot be
written over the CNC objects: a list that would change it is refused (:func:`check_filter`), since
the machine would run its kp / d_tv with its old filter, a set nobody evaluated.
"""
from __future__ import annotations

import datetime
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..base.kinds import FilterType
from ..control.controller import check_object_value
from ..control.filters import FILTER_KINDS
from ..errors import ExitCode, ParameterError
from ..params.channel import load_channel_list
from ..params.listfile import canonical_key, list_entries, load_list
from .axes import (ACTIVE_STATES, PARAMETERS, WRITABLE, Unit, format_list_text, read_object, read_state, state_name,
                   write_object)
from .journal import WriteJournal
from .target import AMS_TCP_PORT, MachineError, Target

#: the write order: the limits first, then the gains (a restore goes the same way)
ORDER = ("v_max", "a_max", "d_tv", "i_tn", "kp")


@dataclass
class Change:
    field: str
    key: str
    object: str
    unit: str
    old: object                  # the value in effect
    new: object
    status: str = "planned"      # planned, pending, in effect, restored, failed, not written
    pending: object = None       # a value the journal has pending from a write of distctrl (None: none)
    read_back: str | None = None  # after the write: "written" or "in_effect" (what the object read)
    pending_since: str | None = None   # when distctrl wrote ``pending`` (the journal's time)

    @property
    def again(self) -> bool:
        """The journal has this very value pending: written again, since a CNC restart (or anything
        else the objects do not show) may have dropped it."""
        return self.pending is not None and _same(self.pending, self.new)

    def as_dict(self) -> dict:
        return {"parameter": self.field, "key": self.key, "object": self.object, "unit": self.unit,
                "old": self.old, "new": self.new, "status": self.status, "pending_before": self.pending,
                "journal_pending_since": self.pending_since, "read_back": self.read_back}


@dataclass
class Plan:
    unit: Unit
    state: int
    changes: list[Change]
    unchanged: list[str]
    ignored: list[dict] = field(default_factory=list)   # keys in the list that are not writable over ADS
    values: dict = field(default_factory=dict)      # field -> {read, in_effect, pending, written_at}
    unverifiable: list[str] = field(default_factory=list)      # filter values the objects cannot read

    @property
    def active(self) -> bool:
        return self.state in ACTIVE_STATES


def explicit_keys(path: str | Path) -> list[str]:
    """The keys a list file sets itself (canonical), in file order."""
    keys = []
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise MachineError(f"{path}: cannot read ({exc.strerror})") from None
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if line:
            keys.append(canonical_key(line.split()[0]))
    return keys


def wanted_values(unit: Unit, path: str | Path) -> tuple[dict, list[dict]]:
    """{field: value in the list's unit} of the writable parameters the list sets, and the other keys it
    sets (not writable over ADS; ``value`` in the list's unit). The list is loaded and checked as
    ``distctrl params`` does."""
    try:
        pl = load_list(path) if unit.kind == "axis" else load_channel_list(path)
    except ParameterError as exc:
        raise MachineError(str(exc)) from None
    fmt = unit.list_format
    entries = {e["key"]: e for e in list_entries(pl.params, fmt=fmt)}
    by_field = {unit.key(f): f for f in PARAMETERS}
    wanted, ignored = {}, []
    for key in explicit_keys(path):
        e = entries.get(key)
        f = by_field.get(key)
        if e is not None and f in WRITABLE:
            wanted[f] = e["value"]
        elif key not in {i["key"] for i in ignored}:
            ignored.append({"key": key, "value": None if e is None else e["value"],
                            "reason": "not writable over the CNC objects (set in the CNC's parameter list; "
                                      "adopted when the CNC starts)"})
    return wanted, ignored


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=1e-15)
    return a == b


def _object_value(unit: Unit, f: str, value):
    """The value as the object takes it (SGN32 objects: whole numbers), checked against the range."""
    spec = unit.spec(PARAMETERS[f])
    if spec.type == "SGN32":
        if not float(value).is_integer():
            raise MachineError(f"{unit.key(f)} = {value} {spec.unit}: {spec.name} is SGN32 (whole {spec.unit})")
        value = int(value)
    else:
        value = float(value)
    problem = check_object_value(spec.write_name, float(value) * spec.write_scale)
    if problem:
        raise MachineError(f"{unit.key(f)} = {value} {spec.unit}: out of range for {spec.name}: {problem}")
    return value


#: the filter's values in a list: list field -> the object that reads it (None: no object does)
FILTER_FIELDS = {"filter_type": "filter_type", "n_cycles": "n_cycles", "smoothing_factor": "smoothing_fact",
                 "kalman_sigma": "kalman_sigma", "low_pass_filter_order": None, "low_pass_filter_fg_f0": None}
#: FilterKind.params names -> list fields
_KIND_PARAM_FIELD = {"n_cycles": "n_cycles", "smoothing_factor": "smoothing_factor",
                     "kalman_sigma": "kalman_sigma", "order": "low_pass_filter_order",
                     "fg_f0": "low_pass_filter_fg_f0"}


def _filter_kind(name) -> tuple[FilterType, int | None]:
    """The filter type and the n it forces: DEFAULT is MOVING_AVERAGE with n = 4 (P-AXIS-00782)."""
    try:
        ft = FilterType.parse(str(name))
    except (ValueError, KeyError, ParameterError):
        return FilterType.DEFAULT, None
    return (FilterType.MOVING_AVERAGE, 4) if ft == FilterType.DEFAULT else (ft, None)


def check_filter(target: Target, unit: Unit, path: str | Path, ignored: list[dict]) -> list[str]:
    """Refuse (MachineError) a list whose filter differs from the machine's: the filter cannot be
    written over the CNC objects, so the machine would run the list's kp / d_tv with its old filter.
    Only the values the list sets and its filter type uses are compared. Returns the keys that
    cannot be compared (no object reads them: the low-pass order and cut-off)."""
    listed = {i["key"]: i["value"] for i in ignored}
    fields = {f: listed[unit.key(f)] for f in FILTER_FIELDS if _has_key(unit, f) and unit.key(f) in listed}
    if not fields:
        return []
    machine = {f: read_object(target, unit, unit.spec(obj)) for f, obj in FILTER_FIELDS.items()
               if obj and _has_key(unit, f)}
    m_type, m_n = _filter_kind(machine["filter_type"])
    l_type, l_n = _filter_kind(fields["filter_type"]) if "filter_type" in fields else (m_type, m_n)
    differ, unknown, same = [], [], []
    if l_type != m_type:
        differ.append(f"filter_type {machine['filter_type']} -> {fields['filter_type']}")
    elif "filter_type" in fields:
        same.append("filter_type")
    for p in FILTER_KINDS[l_type].params:
        f = _KIND_PARAM_FIELD[p]
        if f == "n_cycles" and l_n is not None:
            want = l_n
        elif f in fields:
            want = fields[f]
        else:
            continue
        if FILTER_FIELDS[f] is None:
            unknown.append(f"{unit.key(f)} {want:g}")
            continue
        have = m_n if (f == "n_cycles" and m_n is not None) else machine[f]
        if not _same(have, want):
            differ.append(f"{f} {have:g} -> {want:g}")
        elif f in fields:
            same.append(f)
    if differ:
        ids = ", ".join(unit.list_spec(d.split()[0]).id for d in differ)
        raise MachineError(
            f"{path} changes the filter, which the CNC objects cannot write: {', '.join(differ)} "
            f"({ids}); the machine would run the list's "
            f"gains with its old filter, a set nobody evaluated: nothing written. Put these values into the "
            f"CNC's parameter list (adopted when the CNC starts) and write the list then, or write "
            f"tuned/tuned-objects.lis instead (`distctrl tune --out tuned/` writes it: the best evaluated "
            f"set that keeps the scenario's filter)")
    for i in ignored:
        if i["key"] in {unit.key(f) for f in same}:
            i["reason"] = "not writable over the CNC objects; the machine has the same (read over them)"
    return unknown


def _has_key(unit: Unit, f: str) -> bool:
    return any(s.field == f for s in unit.list_format.specs)


def plan_write(target: Target, unit: Unit, path: str | Path, journal: WriteJournal | None = None) -> Plan:
    """The changes ``path`` asks for against what the machine has in effect. Every value that differs
    from the one in effect is written, also when the journal has it pending: the journal's "pending" is
    a claim the objects cannot confirm (a CNC restart drops pending values and the objects read as
    before), so it never saves a write. A value in effect with another one pending is written too (the
    pending one is not adopted then)."""
    wanted, ignored = wanted_values(unit, path)
    unverifiable = check_filter(target, unit, path, ignored)
    state, values = current_values(target, unit, journal)
    changes, unchanged = [], []
    for f in ORDER:
        if f not in wanted:
            continue
        new = _object_value(unit, f, wanted[f])
        spec = unit.spec(PARAMETERS[f])
        v = values[f]
        if _same(v["in_effect"], new) and v["pending"] is None:
            unchanged.append(f)
        else:
            changes.append(Change(f, unit.key(f), spec.name, spec.unit, v["in_effect"], new,
                                  pending=v["pending"], pending_since=v["written_at"]))
    return Plan(unit, state, changes, unchanged, ignored, values, unverifiable)


def current_values(target: Target, unit: Unit, journal: WriteJournal | None = None) -> tuple[int, dict]:
    """The axis's state and {field: {read, in_effect, pending, written_at}}: the objects read now,
    joined with the journal (:meth:`WriteJournal.resolve`)."""
    state = read_state(target, unit)
    readings = {f: read_object(target, unit, unit.spec(PARAMETERS[f])) for f in ORDER}
    return state, (journal or WriteJournal()).resolve(target, unit, readings, state)


def default_backup_path(path: str | Path, unit: Unit) -> Path:
    """``<list>.backup-<axis>.lis`` beside the list; ``-2``, ``-3``... when that exists (a backup is
    never overwritten)."""
    p = Path(path)
    base = f"{p.stem}.backup-{unit.kind}-{unit.name}"
    cand, n = p.with_name(base + ".lis"), 1
    while cand.exists():
        n += 1
        cand = p.with_name(f"{base}-{n}.lis")
    return cand


def write_backup(target: Target, unit: Unit, backup: Path, plan: Plan) -> dict:
    """The current values of every writable parameter, written to ``backup`` (a parameter list that
    ``machine write BACKUP --yes`` restores)."""
    values = {f: plan.values[f]["in_effect"] if f in plan.values
              else read_object(target, unit, unit.spec(PARAMETERS[f])) for f in ORDER}
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    port = "" if target.tcp_port == AMS_TCP_PORT else f" --port {target.tcp_port}"
    header = (f"backup of {unit.label} on {target.address}, {now}, before writing {len(plan.changes)} value(s)\n"
              f"(the values in effect; a value written before and still pending is not in it)\n"
              f"restore: distctrl machine write --ads {target.net_id}:{target.port} --ip {target.ip}{port} "
              f"--axis {unit.name}={unit.number} {backup} --yes")
    if unit.kind == "channel":
        header = header.replace(f"--axis {unit.name}={unit.number}", f"--channel {unit.number}")
    text = format_list_text(unit, values, header)
    backup.parent.mkdir(parents=True, exist_ok=True)
    tmp = backup.with_name(backup.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(backup)
    return values


#: seconds a written value may take to show in its object (the CNC takes a write in its next cycle)
SETTLE = 0.5


def _verify(target: Target, unit: Unit, changes: list[Change], settle: float = SETTLE) -> None:
    """Read every written value back until it shows (``verified``), or -- kp, i_tn, d_tv, whose objects
    read the working value -- still shows the old value once the others have settled (``pending``);
    any other value, or a value that does not show within ``settle`` s, fails."""
    deadline = time.monotonic() + settle
    while True:
        got = {c.field: read_object(target, unit, unit.spec(PARAMETERS[c.field])) for c in changes}
        waiting = [c for c in changes if not _same(got[c.field], c.new)
                   and not (c.field in WORKING_VALUE and _same(got[c.field], c.old))]
        if not waiting or time.monotonic() >= deadline:
            break
        time.sleep(0.01)
    for c in changes:
        v = got[c.field]
        # every written value waits for the next activation (FCT-M3 §9.4), whatever its object reads
        c.status = "in effect" if _same(c.new, c.old) else "pending"
        if _same(v, c.new):
            c.read_back = "written"
        elif c.field in WORKING_VALUE and _same(v, c.old):
            c.read_back = "in_effect"  # the object shows the working value until the next activation
        else:
            raise MachineError(f"{c.object} of {unit.label} reads back {v} {c.unit} after writing {c.new} "
                               f"(waited {settle:g} s)")


#: the objects that read the working value (not a pending write)
WORKING_VALUE = ("kp", "i_tn", "d_tv")


def execute(plan: Plan, target: Target, backup: Path, *, pending: bool = False, reconnect=None,
            journal: WriteJournal | None = None) -> dict:
    """Write the plan: backup, writes, read back; on failure restore and verify. Returns the result
    for the report; raises :class:`MachineError` (exit code 4 when rolled back, 1 when refused)."""
    unit = plan.unit
    if plan.active and not pending and plan.changes:
        raise MachineError(
            f"{unit.label} is {state_name(plan.state)}: distance control is active, and a written value is "
            f"adopted only on the next activation (FCT-M3 §9.4): the running process would keep the old "
            f"values. Write when it is inactive, or give --pending to write now and have "
            f"{', '.join(c.field for c in plan.changes)} pending until the next activation")
    result = {"backup": str(backup), "written": [], "pending": []}
    if not plan.changes:
        return result
    old_values = write_backup(target, unit, backup, plan)
    done: list[Change] = []
    try:
        for c in plan.changes:
            done.append(c)            # counted before the request: a write whose answer is lost may be done
            write_object(target, unit, unit.spec(PARAMETERS[c.field]), c.new)
        _verify(target, unit, plan.changes)
    except MachineError as exc:
        for c in plan.changes:
            c.status = "failed" if c in done else "not written"
        restored = _rollback(target, unit, done, old_values, reconnect)
        names = ", ".join(c.field for c in done) or "nothing"
        if restored is True:
            msg = (f"{exc}; the values written before it ({names}) were restored from the backup {backup} "
                   f"and verified: the axis has its old set")
        else:
            msg = (f"{exc}; RESTORE INCOMPLETE ({restored}): restore with distctrl machine write --ads "
                   f"{target.net_id}:{target.port} --ip {target.ip} {backup} --yes")
        raise MachineError(msg, exit_code=ExitCode.CHECK_FAILED) from None
    (journal or WriteJournal()).record(target, unit, {c.field: c.new for c in plan.changes},
                                       {c.field: c.old for c in plan.changes},
                                       {c.field: c.read_back for c in plan.changes}, plan.state)
    result["written"] = [c.field for c in plan.changes]
    result["pending"] = [c.field for c in plan.changes if c.status == "pending"]   # wait for the next ON
    result["values"] = current_values(target, unit, journal)[1]                     # after the write
    return result


def _rollback(target: Target, unit: Unit, done: list[Change], old_values: dict, reconnect) -> bool | str:
    """Write the backup's values of ``done`` back and verify them: True, or why not."""
    if not done:
        return True
    return _restore(target, unit, done, old_values, reconnect)


def _restore(target: Target, unit: Unit, done: list[Change], old_values: dict, reconnect) -> bool | str:
    original = target
    for attempt in range(2):
        try:
            if attempt and reconnect is not None:
                target.close()            # the broken connection and its route go first
                target = reconnect()
            for c in reversed(done):
                write_object(target, unit, unit.spec(PARAMETERS[c.field]), old_values[c.field])
            deadline = time.monotonic() + SETTLE
            while True:
                # kp/i_tn/d_tv read the working value, which the (pending) writes never changed
                bad = [(c, got) for c in done
                       for got in [read_object(target, unit, unit.spec(PARAMETERS[c.field]))]
                       if not _same(got, old_values[c.field])]
                if not bad or time.monotonic() >= deadline:
                    break
                time.sleep(0.01)
            if bad:
                c, got = bad[0]
                return f"{c.object} reads {got} after restoring {old_values[c.field]}"
            for c in done:
                c.status = "restored"
            return True
        except MachineError as exc:
            why = str(exc)
            if reconnect is None:
                return why
        finally:
            if target is not original:
                target.close()
    return why
