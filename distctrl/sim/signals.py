"""The trace signals: the one catalogue of what a run records every cycle, with units and how each is read.

A trace row (``distctrl run --trace``, the live page's scope) is, in this order:

* ``t`` (s) and ``line`` (the NC line, -1 without one);
* per axis (:data:`AXIS_SIGNALS`): ``<ax>.prog``, ``<ax>.cmd``, ``<ax>.act`` and, for a drive with a
  mechanical resonance only, ``<ax>.nozzle`` (mm; deg on a rotary axis A, B, C);
* per distance-controlled axis (:data:`DC_SIGNALS`): ``<ax>.dc.state`` .. ``<ax>.dc.set_dist``;
* per distance-controlled axis, the extra values asked for with ``record=`` (:data:`RECORDABLE`):
  ``<ax>.dc.<name>``;
* the ground truth (:data:`TRUE_SIGNALS`): ``true.surface``, ``true.distance``;
* with 3D distance control (:data:`DC3D_SIGNALS`): ``dc3d.*``, ``true.clamp_*``, ``tcp.*``.

Each entry is ``(name, unit, how to read it)``: a new trace signal is one line in its list. "How to
read it" is an expression the row builder compiles into one tuple expression (:func:`row_builder`):
for :data:`DC_SIGNALS` an attribute of the axis's :class:`~distctrl.control.CycleOutput`, for
:data:`AXIS_SIGNALS` an expression on the axis's input ``i``, output ``o``, drive ``d`` and (with
kinematics) the NC value ``p``; for :data:`TRUE_SIGNALS` and :data:`DC3D_SIGNALS` an expression on
the machine ``m`` and its 3D output ``q``.
"""
from __future__ import annotations

from ..errors.config import ConfigError

__all__ = ["AXIS_SIGNALS", "DC_SIGNALS", "DC_COLUMNS", "TRUE_SIGNALS", "DC3D_SIGNALS", "DC3D_COLUMNS",
           "RECORDABLE", "RECORD_COLUMN", "PLOT_3D", "SCOPE_DEFAULT", "check_record", "trace_columns", "row_builder"]

#: per axis: (column suffix, unit, expression on ``i`` (CycleInput), ``o`` (CycleOutput), ``d`` (Drive),
#: ``p`` (the NC's programmed value; with kinematics the axis's CycleInput holds the machine setpoint))
AXIS_SIGNALS: tuple[tuple[str, str, str], ...] = (
    ("prog", "mm", "p"),
    ("cmd", "mm", "o.command_position"),
    ("act", "mm", "d.actual"),
)
#: per axis with a drive resonance (``resonance_hz``): the nozzle is then not the motor ``act`` reports
NOZZLE_SIGNAL = ("nozzle", "mm", "d.nozzle")
#: axes whose positions are angles: their axis signals are in degrees
ROTARY_AXES = ("A", "B", "C")

#: per distance-controlled axis: (column suffix, unit, attribute of its CycleOutput)
DC_SIGNALS: tuple[tuple[str, str, str], ...] = (
    ("dc.state", "-", "hli_state"),
    ("dc.offset", "mm", "offset"),
    ("dc.sensor", "mm", "sensor_value"),
    ("dc.feedback", "mm", "feedback_value"),
    ("dc.filtered", "mm", "filtered_feedback"),
    ("dc.target_deviation", "mm", "target_deviation"),
    ("dc.pre_limiter", "mm", "delta_deviation_pre_limiter"),
    ("dc.sloped_delta", "mm", "sloped_delta_deviation"),
    ("dc.set_pos", "mm", "set_pos"),
    ("dc.set_dist", "mm", "set_distance"),
)
DC_COLUMNS = tuple(name for name, _, _ in DC_SIGNALS)

#: the values behind the CNC objects (CycleOutput fields) that ``record=`` may add per distance-controlled
#: axis as ``<ax>.dc.<name>`` (the name is the field, read as ``float(...)``), with their units
RECORDABLE = {"m_actual_offset": "mm", "delta_offset": "mm", "offset_velocity": "mm/s", "v_max_int": "mm/s",
              "a_max_int": "mm/s²", "v_max_param": "mm/s", "a_max_param": "mm/s²", "kp": "-", "i_tn": "s",
              "d_tv": "s", "smoothing_fact": "-", "kalman_sigma": "-", "n_cycles": "-", "state": "-",
              "surface_position": "mm", "measured_distance": "mm", "command_source": "-", "absorbed_offset": "mm",
              "target_reached": "-", "sensor_valid": "-"}
#: a recordable value whose column is not ``<ax>.dc.<name>``: the CycleOutput's ``state`` is the internal
#: state (InternalState), and ``<ax>.dc.state`` is already the HLI state (DC_SIGNALS)
RECORD_COLUMN = {"state": "internal_state"}

#: the ground truth of the simulated geometry: (column, unit, expression on the machine ``m``)
TRUE_SIGNALS: tuple[tuple[str, str, str], ...] = (
    ("true.surface", "mm", "m.true_surface"),
    ("true.distance", "mm", "m.true_distance"),
)

#: the channel's 3D distance control (only with FCT_3D_DIST_CTRL): (column, unit, expression on the
#: machine ``m`` and its 3D output ``q``)
DC3D_SIGNALS: tuple[tuple[str, str, str], ...] = (
    ("dc3d.state", "-", "q.core.hli_state"),
    ("dc3d.offset", "mm", "q.core.offset"),
    ("dc3d.mode", "-", "q.mode"),
    ("dc3d.delta", "mm", "q.delta"),
    ("dc3d.comp_x", "mm", "q.compensation[0]"),
    ("dc3d.comp_y", "mm", "q.compensation[1]"),
    ("dc3d.comp_z", "mm", "q.compensation[2]"),
    ("dc3d.inclination", "deg", "m.inclination_deg"),
    ("dc3d.virt_tool_length", "mm", "m.virt_tool_length"),
    ("dc3d.set_dist_orth", "mm", "q.orthogonal_set_distance"),
    ("dc3d.sensor", "mm", "q.core.sensor_value"),
    ("dc3d.filtered", "mm", "q.core.filtered_feedback"),
    ("dc3d.set_pos", "mm", "q.core.set_pos"),
    ("true.clamp_x", "mm", "m.true_clamp[0]"),
    ("true.clamp_y", "mm", "m.true_clamp[1]"),
    ("true.clamp_z", "mm", "m.true_clamp[2]"),
    ("true.distance_orth", "mm", "m.true_distance_orth"),
    ("tcp.x", "mm", "m.tcp_cmd[0]"),
    ("tcp.y", "mm", "m.tcp_cmd[1]"),
    ("tcp.z", "mm", "m.tcp_cmd[2]"),
)
#: column -> (unit, expression), the form the 3D columns had in ``sim/machine.py``
DC3D_COLUMNS: dict[str, tuple[str, str]] = {name: (unit, expr) for name, unit, expr in DC3D_SIGNALS}

#: default plot signals of a 3D run (one panel per unit): ``RunResult.plot`` and the HTML report
PLOT_3D = ("dc3d.offset", "dc3d.delta", "dc3d.comp_x", "dc3d.comp_y", "dc3d.comp_z", "dc3d.inclination")
#: the live page scope's default signals; ``{ax}`` is the (first) distance-controlled axis
SCOPE_DEFAULT = ("true.distance", "{ax}.dc.sensor", "{ax}.dc.offset", "{ax}.dc.state")


def check_record(record) -> tuple[str, ...]:
    """The extra per-cycle values asked for (``distctrl run --record``), validated."""
    fields = tuple(dict.fromkeys(f.strip() for f in record if f.strip()))   # asked twice: recorded once
    for f in fields:
        if f not in RECORDABLE:
            raise ConfigError("record", f, "one of " + ", ".join(sorted(RECORDABLE)),
                              "not a recordable distance-control value")
    return fields


def _axis_signals(machine, axis: str) -> tuple[tuple[str, str, str], ...]:
    """:data:`AXIS_SIGNALS`, plus the nozzle for an axis whose drive has a mechanical resonance (a rigid
    axis's trace is unchanged)."""
    return AXIS_SIGNALS + (NOZZLE_SIGNAL,) if machine.drives[axis].resonance_hz else AXIS_SIGNALS


def _has_3d(machine) -> bool:
    return getattr(machine, "ch3d", None) is not None


def trace_columns(machine, record: tuple[str, ...] = ()) -> tuple[list[str], dict[str, str]]:
    """The trace's column names of ``machine`` (a :class:`~distctrl.sim.machine.Machine`) in row order,
    and each column's unit."""
    cols, units = ["t", "line"], {"t": "s", "line": "-"}
    for n in machine.axis_names:
        rotary = n in ROTARY_AXES
        for c, unit, _ in _axis_signals(machine, n):
            cols.append(f"{n}.{c}")
            units[f"{n}.{c}"] = "deg" if rotary else unit
    for n in machine.dc_axes:
        for c, unit, _ in DC_SIGNALS:
            cols.append(f"{n}.{c}")
            units[f"{n}.{c}"] = unit
    for n in machine.dc_axes:
        for f in record:
            col = f"{n}.dc.{RECORD_COLUMN.get(f, f)}"
            cols.append(col)
            units[col] = RECORDABLE[f]
    for c, unit, _ in TRUE_SIGNALS:
        cols.append(c)
        units[c] = unit
    if _has_3d(machine):
        for c, unit, _ in DC3D_SIGNALS:
            cols.append(c)
            units[c] = unit
    return cols, units


def row_builder(machine, record: tuple[str, ...] = (), pack=None):
    """A function ``(t, line) -> tuple`` giving one trace row in the order of :func:`trace_columns`
    (with ``pack``, e.g. ``TraceRecorder.pack``: ``(t, line) -> pack(*row)``, the packed row).

    It is generated once per machine layout as a single tuple expression (the way
    ``collections.namedtuple`` builds its code): the row is assembled 10^5 times a second, and one
    expression avoids the intermediate lists and tuples of a generic loop. The expressions come only
    from the lists of this module and the field names of :data:`RECORDABLE`."""
    env = {"m": machine, "pack": pack}
    parts = ["t", "line"]
    kinematic = getattr(machine, "kinematic_path", False)
    for j, n in enumerate(machine.axis_names):
        env[f"i{j}"], env[f"o{j}"], env[f"d{j}"] = machine.inputs[n], machine.outputs[n], machine.drives[n]
        # with kinematics the axis's CycleInput holds the machine setpoint; the NC's value is kept apart
        names = {"i": f"i{j}", "o": f"o{j}", "d": f"d{j}",
                 "p": f"m.prog_values[{j}]" if kinematic else f"i{j}.programmed_position"}
        for _, _, expr in _axis_signals(machine, n):
            head, _, rest = expr.partition(".")
            parts.append(names[head] + ("." + rest if rest else ""))
    for j, n in enumerate(machine.dc_axes):
        env[f"c{j}"] = machine.outputs[n]
        parts += [f"c{j}.{attr}" for _, _, attr in DC_SIGNALS]
    for j, n in enumerate(machine.dc_axes):
        parts += [f"float(c{j}.{f})" for f in record]            # names checked by check_record
    parts += [expr for _, _, expr in TRUE_SIGNALS]
    if _has_3d(machine):
        env["q"] = machine.out3d
        parts += [expr for _, _, expr in DC3D_SIGNALS]
    if pack is None:
        src = "def build_row(t, line):\n    return (" + ", ".join(parts) + ",)\n"
    else:
        src = "def build_row(t, line):\n    return pack(" + ", ".join(parts) + ")\n"
    exec(compile(src, "<trace row builder>", "exec"), env)       # names only from the lists above
    return env["build_row"]
