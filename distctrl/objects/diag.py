"""Diagnosis dump of the distance control in the layout of FCT-M3 §12.10 (Fig. 54-56).

Fig. 56 "Diagnosis data for 3D distance control" shows the kernel's diagnosis text (DiagData,
channel > Diagnosedaten) with two sections, ``Distance Control:`` (``zstd``, ``tast_offset``,
``referenzwert``, ``sollw``, ``sollw_prog``, ``kp``, ``i_tn``, ``d_tv``, ``filter_type``,
``n_cycles``, ``smooth_fact``, ``sigma``, ``max_dist_change``, ``fg_f0``, ``order``, ``v_max``,
``a_max``, then ``logged events:``) and ``Dist-Ctrl Interface:`` (``cmd_offset``,
``cmd_offset_frozen``, ``act_offset``, ``delta_tool_length``, ``f_freeze``,
``f_wait_for_finished``, ``f_use_weighting``, ``active_mode``, ``new_mode``, ``active_ax_idx``,
``new_ax_idx``). Fig. 55 "Verification of activation" is an image only; it is rendered as a
``Configuration:`` section (P-CHAN-00500 with FCT_3D_DIST_CTRL).

Both dumps reproduce these sections and fields in the figure's order and spelling, then add
sections the figure does not have (``State:``, ``Values:``, ``Limits:``, and ``3D:`` for the 3D
variant). Every line is ``name: value [unit]``; values are in the internal units (mm, mm/s, mm/s²,
s, Hz, SPEC §1), not in the kernel's raw integers, so each line names its unit. Enumerations are
written as in the figure, ``NAME (code)``.

:func:`format_diag_axis` fills the layout from an :class:`~distctrl.control.AxisDistanceController`
and its last :class:`~distctrl.control.cycle_io.CycleOutput`; :func:`format_diag_3d` from a
:class:`~distctrl.objects.channel3d.Channel3DValues` and the channel parameters. The meaning chosen
for each field of the figure is in docs/diag.md.
"""
from __future__ import annotations

import math
from typing import Iterable

from ..base.states import CommandSource, HliState, InternalState, Mode
from ..control.commands3d import CompensationMode
from ..control.cycle_io import CycleOutput
from ..errors import ErrorEvent
from .channel3d import Channel3DValues
from .units import INT32_MAX, INT32_MIN, round_saturate

__all__ = ["format_diag_axis", "format_diag_3d", "state_name", "hli_state_name"]

_Line = tuple[str, str, str]          # name, value, unit


# ============================================================================ formatting helpers

def _f(x: float | None, digits: int = 6) -> str:
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    text = f"{x:.{digits}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text   # no "-0.000000"


def _i(x) -> str:
    return "-" if x is None else str(int(x))


def _flag(x) -> str:
    return "1" if x else "0"


def _enum(name: str, code: int) -> str:
    return f"{name} ({int(code)})"


def state_name(code: int) -> str:
    """``NAME (code)`` of a ``DIST_CTRL::state`` internal code."""
    try:
        return _enum(InternalState(int(code)).name, code)
    except ValueError:
        return _enum("UNKNOWN", code)


def hli_state_name(code: int) -> str:
    """``NAME (code)`` of an HLI state."""
    try:
        return _enum(HliState(int(code)).name, code)
    except ValueError:
        return _enum("UNKNOWN", code)


def _mode_name(code: int) -> str:
    try:
        return _enum(CompensationMode(int(code)).name, code)
    except ValueError:
        return _enum("UNKNOWN", code)


def _control_mode(code: int) -> str:
    try:
        return _enum(Mode(int(code)).name, code)
    except ValueError:
        return _enum("UNKNOWN", code)


def _source_name(code: int) -> str:
    try:
        return _enum(CommandSource(int(code)).name, code)
    except ValueError:
        return _enum("UNKNOWN", code)


def _event_text(ev: ErrorEvent) -> str:
    where = f", NC line {ev.line}" if ev.line is not None else ", NC line -"
    return f"{ev.severity} ID {ev.id}, cycle {ev.cycle}{where}: {ev.message}"


def _events_block(last_error: ErrorEvent | None, events: Iterable[ErrorEvent]) -> list[str]:
    seen: list[ErrorEvent] = []
    for ev in list(events) + ([last_error] if last_error is not None else []):
        if ev is not None and ev not in seen:
            seen.append(ev)
    if not seen:
        return ["(none)"]
    return [_event_text(ev) for ev in seen]


def _section(title: str, lines: list[_Line]) -> list[str]:
    out = [f"{title}:"]
    for name, value, unit in lines:
        out.append(f"{name}: {value} [{unit}]")
    return out


def _last_error_lines(ev: ErrorEvent | None) -> list[_Line]:
    if ev is None:
        return [("last_error", "none", "-")]
    return [("last_error", str(ev.id), "-"), ("last_error_severity", ev.severity, "-"),
            ("last_error_cycle", str(ev.cycle), "cycles"),
            ("last_error_line", _i(ev.line), "NC line"),
            ("last_error_text", ev.message, "-")]


class DiagBlock:
    """One diagnosis block: a title, header lines and sections of ``(name, value, unit)`` lines (the
    ``logged events`` section: formatted event lines). ``text()`` is the Fig. 56 layout,
    ``to_dict()`` what ``distctrl diag --json`` prints (numbers as numbers, units beside them)."""

    def __init__(self, title: str, header: list[_Line], blocks: list[tuple[str, list]]):
        self.title, self.header, self.blocks = title, header, blocks

    def text(self) -> str:
        text = [self.title]
        text += [f"{n}: {v} [{u}]" for n, v, u in self.header]
        for name, lines in self.blocks:
            text.append("")
            if name == "logged events":
                text.append("logged events:")
                text += list(lines)          # already formatted
            else:
                text += _section(name, lines)   # type: ignore[arg-type]
        return "\n".join(text) + "\n"

    @staticmethod
    def _value(v: str):
        try:
            x = float(v)
        except (TypeError, ValueError):
            return None if v == "-" else v
        return int(x) if x.is_integer() and "." not in v and "e" not in v.lower() else x

    def to_dict(self) -> dict:
        def fields(lines):
            return {n: {"value": self._value(v), "unit": u} for n, v, u in lines}
        out: dict = {"title": self.title, **fields(self.header), "sections": {}}
        for name, lines in self.blocks:
            if name == "logged events":
                out["logged_events"] = [] if list(lines) == ["(none)"] else list(lines)
            else:
                out["sections"][name] = fields(lines)
        return out


def _assemble(header: list[_Line], title: str, blocks: list[tuple[str, list[_Line] | list[str]]]) -> DiagBlock:
    return DiagBlock(title, header, blocks)


# ============================================================================ axis variant

def format_diag_axis(controller, output, axis_name: str, *, axis_index: int = 0,
                     events: Iterable[ErrorEvent] = ()) -> str:
    """The text of :func:`diag_axis`."""
    return diag_axis(controller, output, axis_name, axis_index=axis_index, events=events).text()


def diag_axis(controller, output, axis_name: str, *, axis_index: int = 0,
              events: Iterable[ErrorEvent] = ()) -> DiagBlock:
    """The diagnosis dump of one axis's distance control (Fig. 56 layout, axis variant).

    ``controller`` is the axis's :class:`~distctrl.control.AxisDistanceController`, ``output`` its
    last :class:`~distctrl.control.cycle_io.CycleOutput` (None before the first cycle).
    ``axis_index`` (0-based) fills ``active_ax_idx``/``new_ax_idx``; ``events`` are further logged
    events (e.g. a run's event log) listed under ``logged events:`` with this cycle's events and
    the error that holds the controller in ERROR.
    """
    out = output if output is not None else CycleOutput()
    p, t, st = controller.params, controller.tuning, controller.state
    f = t.filter
    const_dist = st.mode == Mode.CONST_DIST
    hli = HliState(int(st.hli_state))
    frozen = hli == HliState.FREEZE
    running = hli in (HliState.ACTIVE, HliState.ACTIVE_CONST_DIST, HliState.DRYRUN_SETPOS,
                      HliState.DRYRUN_CONST_DIST)
    state_code = out.state if output is not None else int(InternalState.IDLE)
    prog = st.programmed_set_dist if const_dist else st.programmed_set_pos
    weighting = p.v_weight_down > 0 or p.a_weight_down > 0

    header: list[_Line] = [
        ("axis", axis_name, "-"),
        ("variant", "axis-specific", "-"),
        ("cycle", str(out.cycle if output is not None else st.cycle), "cycles"),
        ("cycle_time", _f(controller.T), "s"),
    ]
    dc: list[_Line] = [
        ("zstd", state_name(state_code), "-"),
        ("tast_offset", _f(p.ref_offset), "mm"),
        ("referenzwert", _f(st.ref_shift), "mm"),
        ("sollw", _f(st.set_dist if const_dist else st.set_pos), "mm"),
        ("sollw_prog", _f(prog), "mm"),
        ("kp", _f(t.kp), "-"),
        ("i_tn", _f(t.i_tn), "s"),
        ("d_tv", _f(t.d_tv), "s"),
        ("filter_type", f.filter_type.name, "-"),
        ("n_cycles", _i(f.effective_n), "-"),          # the n the filter uses (4 under DEFAULT)
        ("smooth_fact", _f(f.smoothing_factor), "-"),
        ("sigma", _f(f.kalman_sigma), "-"),
        ("max_dist_change", _f(0.0), "mm"),
        ("fg_f0", _f(f.fg_f0), "Hz"),
        ("order", _i(f.order), "-"),
        ("v_max", _f(t.v_max), "mm/s"),
        ("a_max", _f(t.a_max), "mm/s²"),
    ]
    ifc: list[_Line] = [
        ("cmd_offset", _f(out.m_actual_offset), "mm"),
        ("cmd_offset_frozen", _f(out.offset if frozen else 0.0), "mm"),
        ("act_offset", _f(out.offset), "mm"),
        ("delta_tool_length", _f(0.0), "mm"),
        ("f_freeze", _flag(frozen), "-"),
        ("f_wait_for_finished", _flag((running and not out.target_reached) or hli == HliState.TURNING_OFF), "-"),
        ("f_use_weighting", _flag(weighting), "-"),
        ("active_mode", _mode_name(CompensationMode.ACS), "-"),
        ("new_mode", _mode_name(CompensationMode.ACS), "-"),
        ("active_ax_idx", _i(axis_index), "-"),
        ("new_ax_idx", _i(axis_index), "-"),
    ]
    state: list[_Line] = [
        ("hli_state", hli_state_name(int(hli)), "-"),
        ("dist_ctrl_state", state_name(state_code), "-"),
        ("mode", _control_mode(st.mode), "-"),
        ("command_source", _source_name(st.source), "-"),
        ("sensor_source", st.sensor_source.name, "-"),
        ("sensor_var", st.sensor_var or "-", "-"),
        ("target_reached", _flag(out.target_reached), "-"),
        ("sensor_valid", _flag(out.sensor_valid), "-"),
        ("pending_writes", ", ".join(f"{k}={v:g}" for k, v in st.pending.items()) or "none",
         "internal units"),
    ] + _last_error_lines(st.error)
    values: list[_Line] = [
        ("set_pos", _f(out.set_pos), "mm"),
        ("set_distance", _f(out.set_distance), "mm"),
        ("offset", _f(out.offset), "mm"),
        ("delta_offset", _f(out.delta_offset), "mm"),
        ("offset_velocity", _f(out.offset_velocity), "mm/s"),
        ("sensor_value", _f(out.sensor_value), "mm"),
        ("measured_distance", _f(out.measured_distance), "mm"),
        ("surface_position", _f(out.surface_position), "mm"),
        ("feedback_value", _f(out.feedback_value), "mm"),
        ("filtered_feedback", _f(out.filtered_feedback), "mm"),
        ("target_deviation", _f(out.target_deviation), "mm"),
        ("delta_deviation_pre_limiter", _f(out.delta_deviation_pre_limiter), "mm"),
        ("sloped_delta_deviation", _f(out.sloped_delta_deviation), "mm"),
        ("command_position", _f(out.command_position), "mm"),
        ("integral", _f(st.integral), "mm"),
    ]
    limits: list[_Line] = [
        ("v_max_int", _f(out.v_max_int), "mm/s"),
        ("a_max_int", _f(out.a_max_int), "mm/s²"),
        ("max_deviation", _f(p.max_deviation), "mm"),
        ("max_pos", _f(p.max_pos), "mm"),
        ("min_pos", _f(p.min_pos), "mm"),
        ("tolerance", _f(p.tolerance), "mm"),
        ("max_act_value_change", _f(p.max_act_value_change), "mm/s"),
        ("axis_a_max", _f(p.axis_a_max), "mm/s²"),
        ("v_weight_down", _f(p.v_weight_down * 100.0, 1), "%"),
        ("a_weight_down", _f(p.a_weight_down * 100.0, 1), "%"),
        ("use_adaptive_acceleration", _flag(p.use_adaptive_acceleration), "-"),
        ("a_min", _f(p.a_min), "mm/s²"),
        ("dist_error_a_min", _f(p.dist_error_a_min), "mm"),
        ("dist_error_a_max", _f(p.dist_error_a_max), "mm"),
        ("use_both_encoders", _flag(p.use_both_encoders), "-"),
        ("check_sw_limit_switch", _flag(p.check_sw_limit_switch), "-"),
        ("sw_limit_min", _f(p.sw_limit_min), "mm"),
        ("sw_limit_max", _f(p.sw_limit_max), "mm"),
    ]
    logged = _events_block(st.error, list(events) + list(out.events if output is not None else []))
    sections = [("Distance Control", dc), ("logged events", logged), ("Dist-Ctrl Interface", ifc),
                ("State", state), ("Values", values), ("Limits", limits)]
    if p.rotary:                        # a rotary axis (P-AXIS-00018): its lengths are degrees
        sections = [(title, [(n, v, _ROTARY_UNIT.get(u, u)) for n, v, u in lines]) for title, lines in sections]
    return _assemble(header, f"DiagData distance control: axis {axis_name}", sections)


_ROTARY_UNIT = {"mm": "°", "mm/s": "°/s", "mm/s²": "°/s²"}


# ============================================================================ 3D variant

def format_diag_3d(values: Channel3DValues, params=None, *, channel: int = 1,
                   events: Iterable[ErrorEvent] = ()) -> str:
    """The text of :func:`diag_3d`."""
    return diag_3d(values, params, channel=channel, events=events).text()


def diag_3d(values: Channel3DValues, params=None, *, channel: int = 1,
            events: Iterable[ErrorEvent] = ()) -> DiagBlock:
    """The diagnosis dump of a channel's 3D distance control (Fig. 55/56 layout).

    ``values`` is the channel's :class:`Channel3DValues` (or any object with its attributes);
    ``params`` the :class:`~distctrl.params.channel.ChannelParameters` (None: the lines that need
    them show ``-``). ``channel`` (from 1) names the channel as the kernel does ("Kanal 1").
    """
    v = values
    p = params
    const_dist = int(getattr(v, "control_mode", 0)) == int(Mode.CONST_DIST)
    prog = v.programmed_set_dist if const_dist else v.programmed_set_pos
    fg = v.fg_f0 if v.fg_f0 is not None else (p.low_pass_filter_fg_f0 if p is not None else None)
    order = v.order if v.order is not None else (p.low_pass_filter_order if p is not None else None)
    weighting = p is not None and (p.v_weight_down > 0 or p.a_weight_down > 0)

    def par(name: str, digits: int = 6) -> str:
        return _f(getattr(p, name), digits) if p is not None else "-"

    header: list[_Line] = [
        ("channel", f"Kanal {int(channel)}", "-"),
        ("variant", "channel-specific (3D)", "-"),
        ("cycle", _i(v.cycle), "cycles"),
    ]
    config: list[_Line] = [
        ("configuration.decoder.function",
         ("FCT_3D_DIST_CTRL" if p.fct_3d_dist_ctrl else "-") if p is not None else "-", "-"),
        ("fct_3d_dist_ctrl", _flag(p.fct_3d_dist_ctrl) if p is not None else "-", "-"),
        ("dist_ctrl_active", _flag(int(v.hli_state) != int(HliState.INACTIVE)), "-"),
    ]
    dc: list[_Line] = [
        ("zstd", state_name(v.state), "-"),
        ("tast_offset", par("ref_offset"), "mm"),
        ("referenzwert", _f(v.ref_shift), "mm"),
        ("sollw", _f(v.set_distance if const_dist else v.set_pos), "mm"),
        ("sollw_prog", _f(prog), "mm"),
        ("kp", _f(v.kp), "-"),
        ("i_tn", _f(v.i_tn), "s"),
        ("d_tv", _f(v.d_tv), "s"),
        ("filter_type", str(v.filter_type), "-"),
        ("n_cycles", _i(v.n_cycles), "-"),
        ("smooth_fact", _f(v.smoothing_fact), "-"),
        ("sigma", _f(v.kalman_sigma), "-"),
        ("max_dist_change", _f(0.0), "mm"),
        ("fg_f0", _f(fg), "Hz"),
        ("order", _i(order), "-"),
        ("v_max", _f(v.v_max_param), "mm/s"),
        ("a_max", _f(v.a_max_param), "mm/s²"),
    ]
    ifc: list[_Line] = [
        ("cmd_offset", _f(v.cmd_offset), "mm"),
        ("cmd_offset_frozen", _f(v.cmd_offset_frozen), "mm"),
        ("act_offset", _f(v.offset), "mm"),
        ("delta_tool_length", _f(v.delta_tool_length), "mm"),
        ("f_freeze", _flag(v.freeze), "-"),
        ("f_wait_for_finished", _flag(v.wait_for_finished), "-"),
        ("f_use_weighting", _flag(weighting) if p is not None else "-", "-"),
        ("active_mode", _mode_name(v.compensation_mode), "-"),
        ("new_mode", _mode_name(v.new_compensation_mode), "-"),
        ("active_ax_idx", _i(v.active_axis_index), "-"),
        ("new_ax_idx", _i(v.new_axis_index), "-"),
    ]
    state: list[_Line] = [
        ("hli_state", hli_state_name(v.hli_state), "-"),
        ("dist_ctrl_state", state_name(v.state), "-"),
        ("mode", _control_mode(getattr(v, "control_mode", 0)), "-"),
        ("command_source", _source_name(v.command_source), "-"),
        ("sensor_source", str(v.sensor_source), "-"),
        ("sensor_var", v.sensor_var or "-", "-"),
        ("sensor_valid", _flag(v.sensor_valid), "-"),
        ("target_reached", _flag(v.target_reached), "-"),
        ("pending_writes", ", ".join(f"{k}={val:g}" for k, val in dict(v.pending).items()) or "none",
         "internal units"),
    ] + _last_error_lines(v.error)
    vals: list[_Line] = [
        ("set_pos", _f(v.set_pos), "mm"),
        ("set_distance", _f(v.set_distance), "mm"),
        ("orthogonal_set_distance", _f(v.orthogonal_set_distance), "mm"),
        ("offset", _f(v.offset), "mm"),
        ("m_actual_offset", _f(v.m_actual_offset), "mm"),
        ("delta_offset", _f(v.delta_offset), "mm"),
        ("offset_velocity", _f(v.offset_velocity), "mm/s"),
        ("sensor_value", _f(v.sensor_value), "mm"),
        ("measured_distance", _f(v.measured_distance), "mm"),
        ("feedback_value", _f(v.feedback_value), "mm"),
        ("filtered_feedback", _f(v.filtered_feedback), "mm"),
        ("target_deviation", _f(v.target_deviation), "mm"),
        ("delta_deviation_pre_limiter", _f(v.delta_deviation_pre_limiter), "mm"),
        ("sloped_delta_deviation", _f(v.sloped_delta_deviation), "mm"),
    ]
    three_d: list[_Line] = [
        ("direction", v.direction or "-", "-"),
        ("compensation_x", _f(v.compensation_x), "mm"),
        ("compensation_y", _f(v.compensation_y), "mm"),
        ("compensation_z", _f(v.compensation_z), "mm"),
        ("inclination", _f(math.degrees(v.inclination_rad), 4), "°"),
        ("inclination_rad", _f(v.inclination_rad, 9), "rad"),
        ("tool_length", _f(v.tool_length), "mm"),
        ("virtual_tool_length", _f(v.virtual_tool_length), "mm"),
        ("virt_tool_length_r", str(_round(v.virtual_tool_length * 1e4)), "0.1 µm"),
        ("inclination_r", str(_round(math.degrees(v.inclination_rad) * 1e4)), "0.0001°"),
        ("filter_time", _i(v.filter_time), "cycles"),
        ("blend_active", _flag(v.blend_active), "-"),
    ]
    limits: list[_Line] = [
        ("v_max_int", _f(v.v_max_int), "mm/s"),
        ("a_max_int", _f(v.a_max_int), "mm/s²"),
        ("max_deviation", par("max_deviation"), "mm"),
        ("max_pos", par("max_pos"), "mm"),
        ("min_pos", par("min_pos"), "mm"),
        ("tolerance", par("tolerance"), "mm"),
        ("max_act_value_change", par("max_act_value_change"), "mm/s"),
        ("v_weight_down", _f(p.v_weight_down * 100.0, 1) if p is not None else "-", "%"),
        ("a_weight_down", _f(p.a_weight_down * 100.0, 1) if p is not None else "-", "%"),
        ("use_adaptive_acceleration", _flag(p.use_adaptive_acceleration) if p is not None else "-", "-"),
        ("a_min", par("a_min"), "mm/s²"),
        ("dist_error_a_min", par("dist_error_a_min"), "mm"),
        ("dist_error_a_max", par("dist_error_a_max"), "mm"),
        ("use_both_encoders", _flag(p.use_both_encoders) if p is not None else "-", "-"),
    ]
    logged = _events_block(v.error, list(events) + list(getattr(v, "events", []) or []))
    return _assemble(header, f"DiagData 3D distance control: Kanal {int(channel)}", [
        ("Configuration", config), ("Distance Control", dc), ("logged events", logged),
        ("Dist-Ctrl Interface", ifc), ("State", state), ("Values", vals), ("3D", three_d),
        ("Limits", limits)])


def _round(x: float) -> int:
    return round_saturate(x, INT32_MIN, INT32_MAX)
