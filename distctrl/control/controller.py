"""The axis-specific distance controller: one ``update(inp, out)`` per GEO cycle.

Pure: no clock, no I/O, no global state; the cycle time is a constructor parameter. Parameters
(:class:`~distctrl.params.AxisParameters`), state (:class:`ControllerState`) and per-cycle
input/output (:class:`~distctrl.control.cycle_io.CycleInput` / ``CycleOutput``) are separate types.
The numbers are computed by the functions of :mod:`distctrl.control.law` (the only copy of the
law); this module is the state machine around them (SPEC §7, §8).

Order of one cycle:
 1. inputs are made safe (a non-finite value is replaced by the last finite one and flagged);
 2. the sensor pipeline gives the encoder reading ``s`` and the distance ``d = -s`` (SPEC §2);
 3. the queued commands are applied in order (state transitions, set values, tuning);
 4. monitoring in the running states (70329, 70330/70576, non-finite input);
 5. feedback, filter, error and PID (SPEC §3-§5); 6. slope limiter and bounds (SPEC §6);
 7. every output value is written into ``out``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..base.kinds import FilterType, SensorSource
from ..base.states import (ERROR_CODE_BY_ID, MONITORED_STATES, CommandSource, HliState, InternalState, Mode,
                          running_state)
from ..errors import ErrorEvent, ErrorId, ParameterError, make_event
from ..params.axis import AxisParameters
from ..params.table import BY_FIELD
from . import law
from .commands import WRITABLE_OBJECTS, Action, Command, ObjectWrite
from .cycle_io import CycleInput, CycleOutput, Result
from .filters import FilterConfig, design_coefficients

_INACTIVE, _ACTIVE, _FREEZE, _TURNING_OFF = HliState.INACTIVE, HliState.ACTIVE, HliState.FREEZE, \
    HliState.TURNING_OFF
_ACTIVE_CD, _ERROR, _DRY_CD, _DRY_SP = HliState.ACTIVE_CONST_DIST, HliState.ERROR, \
    HliState.DRYRUN_CONST_DIST, HliState.DRYRUN_SETPOS
_TRACKING = frozenset({_ACTIVE, _ACTIVE_CD})          # the offset follows the surface
_FILTERING = MONITORED_STATES | {_FREEZE}              # the filter keeps running
_WAIT_WINDOW_MIN = 1e-3                                # mm: WAIT window is max(tolerance, 1 µm)
_LAND = 1e-9                                           # mm: "at the bound" / "offset run out"


@dataclass
class Tuning:
    """The working values that NC blocks and CNC-object writes may change at run time."""

    kp: float
    i_tn: float          # s
    d_tv: float          # s
    v_max: float         # mm/s
    a_max: float         # mm/s², 0 = axis acceleration
    filter: FilterConfig

    @staticmethod
    def from_params(p: AxisParameters) -> "Tuning":
        return Tuning(p.kp, p.i_tn, p.d_tv, p.v_max, p.a_max,
                      FilterConfig(p.filter_type, p.n_cycles, p.smoothing_factor, p.kalman_sigma,
                                   p.low_pass_filter_order, p.low_pass_filter_fg_f0))


@dataclass(slots=True)
class ControllerState:
    """Everything the controller remembers between cycles (public, inspectable)."""

    cycle: int = 0
    hli_state: HliState = HliState.INACTIVE
    error_code: InternalState = InternalState.IDLE     # which ERROR (6..12) while in ERROR
    no_move_this_cycle: bool = False
    mode: Mode = Mode.SET_POS
    source: CommandSource = CommandSource.NC
    programmed_set_pos: float | None = None            # given since the last reset / program end
    programmed_set_dist: float | None = None
    set_pos: float = 0.0                               # working values of the running select, mm
    set_dist: float = 0.0
    offset: float = 0.0                                # o, mm
    velocity: float = 0.0                              # v of the last cycle, mm/s
    integral: float = 0.0                              # PID I part, mm
    m_prev: float = 0.0                                # last measurement part of e (D on measurement)
    need_seed: bool = True                             # filter (re)starts from the next sample
    filtered: float = 0.0                              # last filtered feedback
    ref_shift: float = 0.0                             # REF referencing offset, mm
    referenced: bool = False                           # a REF has been taken (needed if the sensor is not absolute)
    last_s: float = 0.0                                # last finite encoder reading s, mm
    has_last_s: bool = False
    s_delayed: float | None = None                     # previous cycle's reading (no optimized scheduling);
                                                       # None before the first reading
    s_wrapped: float = 0.0                             # modulo sensor: the last wrapped reading ...
    s_unwrapped: float = 0.0                           # ... and the continuous one the law uses
    has_unwrap: bool = False
    last_p: float = 0.0
    last_a: float = 0.0
    last_var: float = 0.0
    sensor_source: SensorSource = SensorSource.SECOND_ENCODER
    sensor_var: str | None = None
    vals: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    pending: dict = field(default_factory=dict)        # CNC-object writes awaiting adoption
    a_bound: float = 0.0                               # acceleration the position bounds brake with
    pending_dryrun: HliState | None = None             # DRYRUN selected while the offset still brakes
    error: ErrorEvent | None = None                    # the error that put the controller in ERROR


class AxisDistanceController:
    """Axis-specific distance control of one axis.

    >>> from distctrl.params import AxisParameters
    >>> from distctrl.control import Command, Action, CycleInput, CycleOutput
    >>> ctrl = AxisDistanceController(AxisParameters(enabled=True), cycle_time=0.001)
    >>> inp, out = CycleInput(programmed_position=40.0, actual_position=40.0), CycleOutput()
    >>> inp.commands.append(Command(Action.ON, set_pos=40.0))
    >>> ctrl.update(inp, out), out.hli_state
    (<Result.OK: 0>, 1)
    """

    def __init__(self, params: AxisParameters, cycle_time: float = 0.001):
        if not (isinstance(cycle_time, (int, float)) and math.isfinite(cycle_time) and 1e-5 <= cycle_time <= 1.0):
            raise ParameterError(f"cycle_time = {cycle_time!r} s out of range; allowed: 1e-05 <= value <= 1",
                                 key="cycle_time", value=cycle_time, allowed="1e-05 <= value <= 1")
        self.params = params
        self.T = float(cycle_time)
        self.tuning = Tuning.from_params(params)
        self.state = ControllerState()
        self._fc = design_coefficients(self.tuning.filter, self.T)   # validates fg against Nyquist
        self._fs = [0.0] * law.FS_LEN
        self._buf = [0.0] * law.MAX_N
        self._rebased = False
        self._derive()
        self.state.a_bound = self._a_floor

    # ------------------------------------------------------------------ derived constants
    def _derive(self) -> None:
        """Recompute the per-cycle constants after a tuning change (never per cycle)."""
        p, t, T = self.params, self.tuning, self.T
        self._a_base = t.a_max if t.a_max > 0 else p.axis_a_max
        # an integral time far below the cycle time is meaningless; bounding T/i_tn keeps it finite
        self._i_gain = min(T / t.i_tn, _MAX_I_GAIN) if t.i_tn > 0 else 0.0
        self._d_gain = law.derivative_gain(t.kp, t.d_tv, T)     # per-cycle D gain (SPEC §5)
        # hot-path constants (the cycle reads these instead of the parameter object)
        self._jump_limit = p.max_act_value_change * T           # mm per cycle (70329)
        self._s_hi = p.max_pos - p.tolerance                    # 70330 above
        self._s_lo = p.min_pos + p.tolerance                    # 70576 below
        self._wait_tol = max(p.tolerance, _WAIT_WINDOW_MIN)
        self._mm_per_incr = p.sensor_mm_per_increment
        self._modulo = p.sensor_modulo                            # P-AXIS-00424 (0: by axis type)
        self._w_v = p.v_weight_down if p.v_weight_down > 0 else 1.0
        self._w_a = p.a_weight_down if p.a_weight_down > 0 else 1.0
        self._tuning_stamp = object()      # identity token: outputs showing older tuning refresh
        # the parameters and working values the cycle reads, as attributes of the controller
        self._kp, self._v_max, self._inv_T = t.kp, t.v_max, 1.0 / T
        self._sign_reversal, self._ref_offset = p.sensor_sign_reversal, p.ref_offset
        self._min_pos, self._max_pos = p.min_pos, p.max_pos
        self._optimized, self._both_encoders = p.optimized_scheduling, p.use_both_encoders
        self._adaptive, self._sw_limits = p.use_adaptive_acceleration, p.check_sw_limit_switch
        self._dev_lo, self._dev_hi = -p.max_deviation, p.max_deviation
        a_candidates = [self._a_base]
        if p.use_adaptive_acceleration:
            a_candidates.append(p.a_min)
        # the smallest acceleration the limiter may ever use: braking to a bound with it is always
        # feasible, so the bound never forces a velocity step
        self._a_floor = min(a_candidates) * min(1.0, self._w_a)

    # ------------------------------------------------------------------ public API
    def update(self, inp: CycleInput, out: CycleOutput) -> Result:
        """Run one GEO cycle: consume ``inp.commands``, compute, fill ``out``. Never raises on
        cycle data; errors are returned as events in ``out.events``.

        The common cycle (no command, nothing out of range) runs straight through this method with
        the constants of :meth:`_derive` in locals; the rare steps (commands, PLC cyclic values,
        monitoring errors, bound errors, the run-out to INACTIVE, tuning outputs) are methods of
        their own."""
        st = self.state
        T = self.T
        st.cycle += 1
        events: list[ErrorEvent] = []
        st.no_move_this_cycle = False
        absorbed = 0.0

        # 1. inputs made safe
        finite_inputs = True
        prog = inp.programmed_position
        if -_HUGE < prog < _HUGE:                      # False for NaN too
            st.last_p = prog
        else:
            prog, finite_inputs = st.last_p, False
        act = inp.actual_position
        if -_HUGE < act < _HUGE:
            st.last_a = act
        else:
            act, finite_inputs = st.last_a, False

        # 2. sensor pipeline: s now (mm); with optimized scheduling off the law sees last cycle's
        modulo = self._modulo
        incr = inp.sensor_increments
        if st.sensor_source is _ENCODER and -_HUGE < incr < _HUGE:
            # fast path of _read_sensor for the axis default source (same law function)
            s_now = _encoder_reading(incr, self._mm_per_incr, self._sign_reversal, self._ref_offset + st.ref_shift,
                                     modulo, self._min_pos, self._max_pos)
            sensor_ok = True
        else:
            s_now, sensor_ok = self._read_sensor(inp)
        if modulo and sensor_ok:
            s_now = self._unwrap(s_now)
        if self._optimized:
            s = s_now
        else:
            prev = st.s_delayed
            st.s_delayed = s_now
            s = s_now if prev is None else prev          # the very first cycle has no earlier reading
        if not sensor_ok:
            finite_inputs = False

        # 3. commands
        if inp.commands:
            absorbed, s_now, s, sensor_ok = self._apply_commands(inp, events, s_now, s, sensor_ok)

        state = st.hli_state
        running = state in MONITORED_STATES
        if running:
            # PLC cyclic set values (re-read every cycle while PLC-commanded)
            if st.source is _PLC:
                self._cyclic_set_values(inp)
            # 4. monitoring (running states only; not in FREEZE: lifting Z while frozen is allowed)
            if not finite_inputs:
                self._raise(ErrorId.INPUT_NOT_FINITE, events, inp.nc_line)
                state = st.hli_state
                running = state in MONITORED_STATES
            elif st.has_last_s and abs(s - st.last_s) > self._jump_limit:
                self._sensor_jump(s, events, inp.nc_line)
                state = st.hli_state
                running = state in MONITORED_STATES
            else:
                # the window applies to the reading as the sensor gives it (wrapped if modulo)
                s_window = _modulo_wrap(s, self._min_pos, self._max_pos) if modulo else s
                if s_window > self._s_hi or s_window < self._s_lo:
                    self._sensor_run_out(s_window, events, inp.nc_line)
                    state = st.hli_state
                    running = state in MONITORED_STATES
        if sensor_ok:
            st.last_s = s
            st.has_last_s = True
        else:
            s = st.last_s

        # 5. feedback, filter, error, PID
        d = -s
        o = st.offset
        const = st.mode is _CONST_DIST
        feedback = _feedback_value(const, self._both_encoders, d, act, prog + o)
        if state in _FILTERING:
            if st.need_seed:
                law.filter_seed(self._fc, self._fs, self._buf, feedback)
                st.need_seed = False
                st.m_prev = -feedback if const else feedback
            filtered = _filter_step(self._fc, self._fs, self._buf, feedback)
            if state == _FREEZE:
                st.m_prev = -filtered if const else filtered   # no D kick when tracking resumes
        else:
            filtered = feedback
            st.need_seed = True
        st.filtered = filtered

        target_dev = 0.0
        e = 0.0
        u = 0.0
        integral = i_cand = st.integral
        set_dist = st.set_dist
        scale = inp.set_distance_scale
        if scale != 1.0 and -_HUGE < scale < _HUGE:
            set_dist = set_dist * scale                 # 3D: the orthogonal set distance (SPEC §11)
        if running:
            target_dev, e, m = _mode_error(const, filtered, set_dist if const else st.set_pos, o)
            u, i_cand = _pid_step(self._kp, self._i_gain, self._d_gain, integral, st.m_prev, e, m)
            st.m_prev = m
            if not (-_HUGE < u < _HUGE and -_HUGE < i_cand < _HUGE):   # (rare: no call per cycle)
                u, i_cand = law.finite_step(u, i_cand, integral)   # never let inf/NaN through
        elif state == _TURNING_OFF:
            e = -o
            u = -o

        # 6. slope limiter and bounds
        override = inp.override
        if not (override > 0.0) or inp.feed_hold:      # also catches NaN
            override = 0.0
        elif override > 1.0:
            override = 1.0
        hold = override == 0.0 or state not in _MOVING
        v_lim = self._v_max * override
        a_lim = a_brake = self._a_base
        if self._adaptive and state in _TRACKING:
            # Fig. 31 keyed on the remaining control error e in every mode (SPEC §6); the braking
            # bound uses the acceleration that is left on the way to e = 0
            p = self.params
            e_abs = abs(e)
            a_lim = law.adaptive_acceleration(e_abs, p.a_min, self._a_base, p.dist_error_a_min,
                                              p.dist_error_a_max)
            a_brake = law.adaptive_braking_acceleration(e_abs, p.a_min, self._a_base, p.dist_error_a_min,
                                                        p.dist_error_a_max)
        if hold:
            u_lim, e_lim = 0.0, 0.0                    # wanted step 0: decelerate and stay
        else:
            u_lim, e_lim = u, e
        v_prev = st.velocity
        v, a_applied, v_applied = _slope_limit(u_lim, e_lim, v_prev, T, v_lim, a_lim, a_brake,
                                               self._w_v, self._w_a)
        lo, hi = self._dev_lo, self._dev_hi
        if self._sw_limits:
            p = self.params
            lo = max(lo, p.sw_limit_min - prog)
            hi = min(hi, p.sw_limit_max - prog)
        # a lowered acceleration (object write adopted while the offset still moves) must not make
        # the bounds brake harder than the motion allows: keep the old floor until at rest
        a_bound = self._a_floor
        if v_prev != 0.0 and st.a_bound > a_bound:     # max(a_floor, st.a_bound)
            a_bound = st.a_bound
        st.a_bound = a_bound
        v_limited = v
        v = _bound_velocity(v, o, T, lo, hi, a_bound)
        if v != v_limited and a_bound > a_applied:
            a_applied = a_bound                        # report the deceleration actually allowed
        o_new = _advance_offset(o, v, T, lo, hi)
        if not hold:
            # at a bound and wanting beyond it: 70331 (max_deviation) or the software limit
            wanted = o + u_lim
            if (wanted > hi + _LAND and hi - o_new <= _LAND) or (wanted < lo - _LAND and o_new - lo <= _LAND):
                self._bound_error(wanted, o_new, lo, hi, events, inp.nc_line)
                state = st.hli_state
            # integrator: keep the candidate only if the limiter did not clip in its direction
            if state in _TRACKING:
                st.integral = _integrator_after_limiter(integral, i_cand, u_lim, v, e, T)
        v_real = (o_new - o) * self._inv_T
        st.velocity = v_real
        st.offset = o_new
        if st.pending_dryrun is not None:
            state = self._pending_dryrun(state, v_real)
        if state == _TURNING_OFF and abs(o_new) <= _LAND and abs(v_real) <= a_applied * T:
            o_new, v_applied = self._run_out(o, v, v_lim, v_applied)
            state = _INACTIVE

        # 7. outputs
        out.offset = o_new
        out.m_actual_offset = o_new
        out.command_position = prog + o_new + absorbed
        out.absorbed_offset = absorbed
        if state != _INACTIVE:
            out.set_pos = st.set_pos
            out.set_distance = set_dist
        else:
            out.set_pos = st.set_pos if st.programmed_set_pos is None else st.programmed_set_pos
            out.set_distance = set_dist if st.programmed_set_dist is None else st.programmed_set_dist
        out.target_deviation = target_dev
        out.delta_deviation_pre_limiter = u
        out.sloped_delta_deviation = v * T
        out.delta_offset = o_new - o
        out.offset_velocity = st.velocity
        source = st.sensor_source
        out.sensor_value = st.last_var if source is _VARIABLE else \
            (_modulo_wrap(s, self._min_pos, self._max_pos) if modulo else s)
        out.feedback_value = feedback
        out.filtered_feedback = filtered
        out.hli_state = _INT[state]
        out.state = _INTERNAL_OF[state] if state != _ERROR and not st.no_move_this_cycle \
            else int(self._internal_state(state))
        out.v_max_int = v_applied
        out.a_max_int = a_applied
        if out.tuning_stamp is not self._tuning_stamp:  # tuning outputs change rarely
            self._tuning_outputs(out)
        out.surface_position = act - d
        out.measured_distance = d
        out.command_source = _INT_SOURCE[st.source]
        out.target_reached = state == _INACTIVE or (state in MONITORED_STATES and abs(e) <= self._wait_tol)
        out.sensor_valid = sensor_ok
        out.cycle = st.cycle
        out.vals = st.vals
        out.events = events
        if not events:
            return _OK
        return Result.ERROR if any(ev.severity == "error" for ev in events) else Result.WARNING

    # ------------------------------------------------------------------ the rare steps of a cycle
    def _apply_commands(self, inp: CycleInput, events: list, s_now: float, s: float,
                        sensor_ok: bool) -> tuple[float, float, float, bool]:
        """Step 3: the queued commands in order; returns (absorbed offset, s now, s, sensor ok),
        the reading taken anew after a REF or a sensor-source change."""
        st = self.state
        absorbed = 0.0
        for cmd in inp.commands:
            absorbed += self._apply(cmd, inp, events, s_now, sensor_ok)
        inp.commands.clear()
        if self._rebased:
            # REF or a sensor-source change: the reading has a new reference; use it at once (a
            # delayed value of the old reference would look like a jump) and restart monitoring
            self._rebased = False
            st.has_unwrap = False
            s_now, sensor_ok = self._read_sensor(inp)
            if self._modulo and sensor_ok:
                s_now = self._unwrap(s_now)
            s = st.s_delayed = s_now
            st.has_last_s = False
        return absorbed, s_now, s, sensor_ok

    def _cyclic_set_values(self, inp: CycleInput) -> None:
        """PLC-commanded and running: the cyclic set value of the mode (when given and finite)."""
        st = self.state
        if st.mode is _SET_POS and inp.cyclic_set_pos is not None and _finite(inp.cyclic_set_pos):
            st.set_pos = inp.cyclic_set_pos
        elif st.mode is _CONST_DIST and inp.cyclic_set_dist is not None and _finite(inp.cyclic_set_dist):
            st.set_dist = inp.cyclic_set_dist

    def _sensor_jump(self, s: float, events: list, line: int | None) -> None:
        """70329: the reading changed by more than max_act_value_change in one cycle."""
        p = self.params
        unit = p.length_unit
        self._raise(ErrorId.SENSOR_JUMP, events, line,
                    f"|Δs| = {abs(s - self.state.last_s):.6g} {unit} in {self.T:g} s, limit "
                    f"{p.max_act_value_change:g} {unit}/s")

    def _sensor_run_out(self, s_window: float, events: list, line: int | None) -> None:
        """70330 / 70576: the reading left the sensor window (max_pos / min_pos less the tolerance)."""
        if s_window > self._s_hi:
            self._raise(ErrorId.SENSOR_RUN_OUT_MAX, events, line, f"s = {s_window:.6g} {self.params.length_unit}")
        else:
            self._raise(ErrorId.SENSOR_RUN_OUT_MIN, events, line, f"s = {s_window:.6g} {self.params.length_unit}")

    def _bound_error(self, wanted: float, o_new: float, lo: float, hi: float, events: list,
                     line: int | None) -> None:
        """At a bound and wanting beyond it: 70331 (max_deviation) or the software limit."""
        max_dev = self.params.max_deviation
        if wanted > hi + _LAND and hi - o_new <= _LAND:
            self._raise(ErrorId.MAX_DEVIATION if hi >= max_dev - _LAND else ErrorId.SW_LIMIT,
                        events, line, f"wanted offset {wanted:.6g} mm, limit {hi:.6g} mm")
        else:
            self._raise(ErrorId.MAX_DEVIATION if lo <= -max_dev + _LAND else ErrorId.SW_LIMIT,
                        events, line, f"wanted offset {wanted:.6g} mm, limit {lo:.6g} mm")

    def _pending_dryrun(self, state: HliState, v_real: float) -> HliState:
        """A DRYRUN selected while the offset still braked (FREEZE): it begins once the offset stands."""
        st = self.state
        if state != _FREEZE:
            st.pending_dryrun = None
        elif v_real == 0.0:
            st.hli_state = state = st.pending_dryrun
            st.pending_dryrun = None
        return state

    def _run_out(self, o: float, v: float, v_lim: float, v_applied: float) -> tuple[float, float]:
        """TURNING_OFF has run its offset out: INACTIVE with the offset exactly 0; the velocity of
        this last step is kept so that the next cycle (at rest, or a new select) continues within the
        acceleration bound. Returns (offset 0, the velocity limit applied)."""
        st = self.state
        st.offset = 0.0
        if o * v > 0.0:
            # o had overshot 0 by rounding (~1e-17 mm): the snap moves against v, so report the
            # velocity and limit of the step actually made (SPEC §6 weighting by direction)
            st.velocity = -o * self._inv_T
            v_applied = v_lim if o < 0.0 else v_lim * self._w_v
        self._to_inactive()
        return 0.0, v_applied

    def _tuning_outputs(self, out: CycleOutput) -> None:
        """The working tuning values behind the CNC objects (written when the tuning changed)."""
        t = self.tuning
        out.kp, out.i_tn, out.d_tv = t.kp, t.i_tn, t.d_tv
        out.smoothing_fact, out.kalman_sigma = t.filter.smoothing_factor, t.filter.kalman_sigma
        out.n_cycles, out.filter_type = t.filter.effective_n, t.filter.filter_type.name   # n in use
        out.v_max_param, out.a_max_param = t.v_max, t.a_max
        out.tuning_stamp = self._tuning_stamp

    def law_constants(self) -> dict:
        """The derived constants the law runs with now (for the batch kernel, which must use the
        very same numbers): gains, accelerations, weights, and the filter coefficient buffer."""
        return {"T": self.T, "kp": self.tuning.kp, "v_max": self.tuning.v_max, "i_gain": self._i_gain,
                "d_gain": self._d_gain, "a_base": self._a_base, "w_v": self._w_v, "w_a": self._w_a,
                "a_floor": self._a_floor, "fc": list(self._fc)}

    def submit_hli(self, transition: int, position_mm: float = 0.0) -> Command:
        """Convenience: the Command a PLC transition maps to (put it into ``inp.commands``)."""
        return Command.from_hli(transition, position_mm)

    @property
    def hli_state(self) -> HliState:
        return self.state.hli_state

    # ------------------------------------------------------------------ sensor
    def _read_sensor(self, inp: CycleInput) -> tuple[float, bool]:
        """Encoder reading s (mm) from the configured source; (last s, False) when not finite."""
        st, p = self.state, self.params
        if st.sensor_source == SensorSource.VARIABLE:
            d = inp.sensor_variable
            if not _finite(d):
                return st.last_s, False
            st.last_var = d
            s = -d + st.ref_shift                          # the PLC delivers mm: no ref_offset here
            if self._modulo:
                s = p.min_pos + (s - p.min_pos) % (p.max_pos - p.min_pos)
            return s, True
        incr = inp.sensor_increments
        if not _finite(incr) or abs(incr) > law.HUGE:
            return st.last_s, False
        s = law.encoder_reading(incr, p.sensor_mm_per_increment, p.sensor_sign_reversal,
                                p.ref_offset + st.ref_shift, self._modulo, p.min_pos, p.max_pos)
        if not _finite(s):
            return st.last_s, False
        return s, True

    def _unwrap(self, s_wrapped: float) -> float:
        """P-AXIS-00424 modulo: the continuous reading behind the wrapped one (the first reading, and
        the first after a REF or a source change, starts it)."""
        st, p = self.state, self.params
        if st.has_unwrap:
            s = law.modulo_unwrap(s_wrapped, st.s_wrapped, st.s_unwrapped, p.min_pos, p.max_pos)
        else:
            s, st.has_unwrap = s_wrapped, True
        st.s_wrapped, st.s_unwrapped = s_wrapped, s
        return s

    # ------------------------------------------------------------------ errors
    def _raise(self, error_id: int, events: list, line: int | None, detail: str = "") -> None:
        """Record an error; severity 'error' puts the controller into ERROR (offset held)."""
        st = self.state
        ev = make_event(error_id, st.cycle, line, detail)
        events.append(ev)
        if ev.severity != "error":
            return
        if error_id == ErrorId.NOT_AVAILABLE:
            return                                   # no distance control on this axis: nothing to hold
        st.hli_state = _ERROR
        st.error = ev
        st.error_code = ERROR_CODE_BY_ID.get(int(error_id), InternalState.ERROR_OTHER)

    def _internal_state(self, state: HliState) -> InternalState:
        st = self.state
        if st.no_move_this_cycle and state == _INACTIVE:
            return InternalState.OFF_NO_MOVE
        if state == _INACTIVE:
            return InternalState.IDLE
        if state in _TRACKING:
            return InternalState.ACTIVE
        if state == _FREEZE:
            return InternalState.FREEZE
        if state == _TURNING_OFF:
            return InternalState.OFF
        if state == _ERROR:
            return st.error_code
        return InternalState.DRYRUN

    # ------------------------------------------------------------------ commands
    def _apply(self, cmd, inp: CycleInput, events: list, s_now: float, sensor_ok: bool) -> float:
        """Apply one command; returns the offset absorbed into the channel (mm)."""
        st = self.state
        line = getattr(cmd, "line", None)
        if line is None:
            line = inp.nc_line
        if isinstance(cmd, ObjectWrite):
            self._object_write(cmd, events, line)
            return 0.0
        if not isinstance(cmd, Command):
            events.append(make_event(ErrorId.COMMAND_VALUE_OUT_OF_RANGE, st.cycle, line,
                                     f"not a command: {type(cmd).__name__}", severity="warning"))
            return 0.0
        a = cmd.action
        if a in (Action.RESET, Action.AXIS_ERROR):
            absorbed = self._absorb_to_inactive()
            st.programmed_set_pos = st.programmed_set_dist = None
            return absorbed
        if a == Action.PROGRAM_END:
            if st.hli_state not in (_INACTIVE, _TURNING_OFF):    # deselected and running out: not active
                self._raise(ErrorId.ACTIVE_AT_PROGRAM_END, events, line)
            st.programmed_set_pos = st.programmed_set_dist = None
            return 0.0
        if a == Action.AXIS_RELEASE:
            if st.hli_state != _INACTIVE:
                self._raise(ErrorId.AXIS_RELEASED_WHILE_ACTIVE, events, line)
            return 0.0
        if a == Action.CHANNEL_ERROR:
            if st.hli_state not in (_INACTIVE, _ERROR):
                # docs/run.md: an NC run-time error stops the program and distance control holds its
                # offset in ERROR; the event is the channel's (no second one here)
                st.hli_state = _ERROR
                st.error = make_event(ErrorId.NC_RUNTIME, st.cycle, line, "the NC program stopped with an error")
                st.error_code = InternalState.ERROR_OTHER
            return 0.0
        if not self.params.enabled:
            self._raise(ErrorId.NOT_AVAILABLE, events, line)
            return 0.0
        problem = _check_command_values(cmd) or self._check_filter(cmd)
        if problem:
            self._raise(ErrorId.COMMAND_VALUE_OUT_OF_RANGE, events, line, problem)
            return 0.0
        if a != Action.NONE:
            # NC and PLC may both command; the last command sets the source state_r shows (SPEC §8)
            st.source = CommandSource(cmd.source)
            st.pending_dryrun = None
        state = st.hli_state
        if state == _ERROR and not (a == Action.OFF or a == Action.NONE):
            self._raise(ErrorId.INVALID_TRANSITION, events, line,
                        f"{a.name} in ERROR; ERROR is left only by OFF")
            return 0.0
        if state == _ERROR and a == Action.OFF and cmd.no_move:
            # FCT-M3 §8.1: 'Only a transition to TURNING OFF is possible to exit this state'
            events.append(make_event(ErrorId.NO_MOVE_IN_ERROR, st.cycle, line, "the offset runs out",
                                     severity="warning"))
            st.hli_state = _TURNING_OFF
            return 0.0
        # values (given with any command)
        if cmd.set_pos is not None:
            st.programmed_set_pos = float(cmd.set_pos)
            if state in MONITORED_STATES and st.mode == Mode.SET_POS:
                st.set_pos = st.programmed_set_pos
        if cmd.set_dist is not None:
            st.programmed_set_dist = float(cmd.set_dist)
            if state in MONITORED_STATES and st.mode == Mode.CONST_DIST:
                st.set_dist = st.programmed_set_dist
        if any(val is not None for val in cmd.vals):
            st.vals = tuple(float(new) if new is not None else old
                            for old, new in zip(st.vals, tuple(cmd.vals[:5]) + (None,) * 5))
        if cmd.sensor_var is not None:
            st.sensor_var = cmd.sensor_var
        if cmd.sensor_source is not None:
            new_source = SensorSource.SECOND_ENCODER if cmd.sensor_source == SensorSource.DEFAULT \
                else SensorSource(cmd.sensor_source)
            if new_source != st.sensor_source:
                if state != _INACTIVE:
                    self._raise(ErrorId.SENSOR_SOURCE_CHANGED, events, line,
                                f"{st.sensor_source.name} -> {new_source.name}")
                    return 0.0
                st.sensor_source = new_source
                st.has_last_s = False
                self._rebased = True
        self._nc_tuning(cmd)
        # the action
        if a == Action.NONE:
            return 0.0
        if a in (Action.ON, Action.DRYRUN):
            self._select(Mode.CONST_DIST if cmd.const_dist else Mode.SET_POS, a == Action.DRYRUN, cmd, events, line)
            return 0.0
        if a == Action.FREEZE:
            if state in MONITORED_STATES:
                st.hli_state = _FREEZE
            elif state != _FREEZE:
                self._raise(ErrorId.INVALID_TRANSITION, events, line, f"FREEZE in {state.name}")
            return 0.0
        if a == Action.OFF:
            if cmd.no_move:
                if state != _INACTIVE:
                    absorbed = self._absorb_to_inactive()
                    st.no_move_this_cycle = True
                    return absorbed
                return 0.0
            if state not in (_INACTIVE, _TURNING_OFF):
                st.hli_state = _TURNING_OFF
            return 0.0
        if a == Action.CHECK_POS:
            p = self.params
            if not sensor_ok:
                self._raise(ErrorId.INPUT_NOT_FINITE, events, line, "CHECK_POS")
            elif s_now > p.max_pos - p.tolerance:
                self._raise(ErrorId.SENSOR_RUN_OUT_MAX, events, line, f"CHECK_POS: s = {s_now:.6g} mm")
            elif s_now < p.min_pos + p.tolerance:
                self._raise(ErrorId.SENSOR_RUN_OUT_MIN, events, line, f"CHECK_POS: s = {s_now:.6g} mm")
            return 0.0
        if a == Action.REF:
            if state != _INACTIVE:
                self._raise(ErrorId.INVALID_TRANSITION, events, line, f"REF in {state.name}; only in INACTIVE")
            elif not sensor_ok:
                self._raise(ErrorId.INPUT_NOT_FINITE, events, line, "REF")
            else:
                # REF_POS (HLI position) is the position of the workpiece surface now: the reading is
                # shifted so that the measured surface a + s equals it; NC REF (no value) references
                # 'sensor zero', s = 0, i.e. REF_POS = a (SPEC §2, FCT-M3 ch. 10)
                # A PLC REF with CyclicCommand.D_Position valid takes D_Position as REF_POS (FCT-M3
                # §8.2, TF5200 §9.2: 'HLI_DIST_CTRL_REF: Reference position of the workpiece surface
                # (REF_POS)'), in the cycle the REF is taken; else command_w.position
                ref_pos = cmd.ref_position
                if cmd.source == CommandSource.PLC and inp.cyclic_set_pos is not None \
                        and _finite(inp.cyclic_set_pos):
                    ref_pos = inp.cyclic_set_pos
                act = self.state.last_a
                s_ref = 0.0 if ref_pos is None else float(ref_pos) - act
                st.ref_shift += s_ref - s_now
                st.referenced = True
                st.has_last_s = False
                self._rebased = True
            return 0.0
        return 0.0

    def _select(self, mode: Mode, dryrun: bool, cmd: Command, events: list, line: int | None) -> None:
        st = self.state
        state = st.hli_state
        target = running_state(mode, dryrun)
        if state == _TURNING_OFF:
            self._raise(ErrorId.SELECT_WHILE_TURNING_OFF, events, line)
            return
        if state in _TRACKING and target in _TRACKING and state != target:
            # FCT-M3 §8.1: ACTIVE <-> ACTIVE_CONST_DIST only through FREEZE or INACTIVE
            self._raise(ErrorId.INVALID_TRANSITION, events, line,
                        f"{state.name} -> {target.name} only through FREEZE or INACTIVE")
            return
        if not self.params.sensor_absolute and not st.referenced:
            # HLI DistanceControl transitions 1, 4, 5, 6: 'If no absolute encoder is used, distance
            # control must first be referenced'
            self._raise(ErrorId.SENSOR_NOT_REFERENCED, events, line,
                        "the sensor is not absolute (kenngr.distc.sensor_absolute = 0): REF first")
            return
        if mode == Mode.SET_POS and st.programmed_set_pos is None:
            self._raise(ErrorId.SELECT_WITHOUT_SET_VALUE, events, line, "SET_POS missing")
            return
        if mode == Mode.CONST_DIST and st.programmed_set_dist is None:
            self._raise(ErrorId.SELECT_WITHOUT_SET_VALUE, events, line, "SET_DIST missing")
            return
        if mode == Mode.SET_POS:
            st.set_pos = st.programmed_set_pos
        else:
            st.set_dist = st.programmed_set_dist
        st.source = CommandSource(cmd.source)
        if state == target:
            return                                   # re-select: new set value only
        # CNC-object writes are adopted exactly on INACTIVE -> ACTIVE(_CONST_DIST) and FREEZE ->
        # ACTIVE(_CONST_DIST) (FCT-M3 §7.6, §9.4), not on entering or leaving a DRYRUN state
        if state in (_INACTIVE, _FREEZE) and target in _TRACKING:
            self._adopt_pending()
        if state == _INACTIVE or mode != st.mode:
            st.need_seed = True                      # the feedback quantity starts (or changes)
            st.integral = 0.0
        st.mode = mode
        st.hli_state = target
        if target in (_DRY_SP, _DRY_CD) and st.velocity != 0.0:
            # SPEC §6: DRYRUN => the offset does not change. While it still brakes (from a tracking state
            # or an unfinished FREEZE) the state is FREEZE; DRYRUN begins when the offset stands.
            st.hli_state = _FREEZE
            st.pending_dryrun = target

    def _absorb_to_inactive(self) -> float:
        """Deselect at once; the channel takes over the offset (the axis does not move)."""
        st = self.state
        absorbed = st.offset
        st.offset = 0.0
        st.velocity = 0.0
        self._to_inactive()
        return absorbed

    def deselect_holding_offset(self) -> None:
        """Deselect as a RESET does (INACTIVE, set values and a pending DRYRUN forgotten, SPEC §8) but
        keep the offset: INACTIVE holds it, braking a moving offset within the limits. The channel's
        3D reset (FCT-M3 §12.4.4: "the previous offset ... is retained") uses it between cycles."""
        self._to_inactive()
        st = self.state
        st.pending_dryrun = None
        st.programmed_set_pos = st.programmed_set_dist = None

    def _to_inactive(self) -> None:
        st = self.state
        st.hli_state = _INACTIVE
        st.error = None
        st.error_code = InternalState.IDLE
        st.integral = 0.0
        st.need_seed = True

    def _adopt_pending(self) -> None:
        if not self.state.pending:
            return
        t = self.tuning
        for name, value in self.state.pending.items():
            setattr(t, name, value)
        self.state.pending.clear()
        self._derive()

    def _object_write(self, w: ObjectWrite, events: list, line: int | None) -> None:
        st = self.state
        if w.name not in WRITABLE_OBJECTS:
            events.append(make_event(ErrorId.OBJECT_READ_ONLY, st.cycle, line, w.name, severity="warning"))
            return
        problem = check_object_value(w.name, w.value)
        if problem:
            events.append(make_event(ErrorId.COMMAND_VALUE_OUT_OF_RANGE, st.cycle, line, problem,
                                     severity="warning"))
            return
        st.pending[w.name] = float(w.value)

    def _new_filter(self, cmd: Command) -> FilterConfig:
        """The filter configuration after the filter words of ``cmd`` (unchanged ones kept)."""
        f = self.tuning.filter
        return FilterConfig(
            cmd.filter_type if cmd.filter_type is not None else f.filter_type,
            int(cmd.n_cycles) if cmd.n_cycles is not None else f.n_cycles,
            float(cmd.smooth_fact) if cmd.smooth_fact is not None else f.smoothing_factor,
            float(cmd.kalman_sigma) if cmd.kalman_sigma is not None else f.kalman_sigma,
            int(cmd.order) if cmd.order is not None else f.order,
            float(cmd.fg_f0) if cmd.fg_f0 is not None else f.fg_f0)

    def _check_filter(self, cmd: Command) -> str:
        """'' when the filter the block leaves behind can run at this cycle time, else why not (e.g.
        LOWPASS with FG_F0=0, or LOWPASS selected while the cut-off is at or above Nyquist): the
        block is refused with 900005, the core never raises on it."""
        if cmd.filter_type is None and cmd.fg_f0 is None and cmd.order is None and cmd.n_cycles is None \
                and cmd.smooth_fact is None and cmd.kalman_sigma is None:
            return ""
        try:
            self._new_filter(cmd).check(self.T)
        except ParameterError as exc:
            return str(exc)
        return ""

    def _nc_tuning(self, cmd: Command) -> None:
        """Tuning programmed in a DIST_CTRL block takes effect with the block (bumpless)."""
        t = self.tuning
        changed = False
        for name in ("kp", "i_tn", "d_tv"):
            value = getattr(cmd, name)
            if value is not None:
                setattr(t, name, float(value))
                self.state.pending.pop(name, None)
                changed = True
        f = t.filter
        nf = self._new_filter(cmd)
        if nf != f:
            t.filter = nf
            self._fc = design_coefficients(nf, self.T)
            # bumpless: the new filter starts from the last filtered value
            law.filter_seed(self._fc, self._fs, self._buf, self.state.filtered)
            changed = True
        if changed:
            self._derive()


_HUGE = law.HUGE
_OK = Result.OK
_MOVING = frozenset({_ACTIVE, _ACTIVE_CD, _TURNING_OFF})   # the offset may move (not held)
_INT_SOURCE = {s: int(s) for s in CommandSource}
# the law functions of the common cycle, bound once (the same functions: law.py is the only copy)
_encoder_reading, _modulo_wrap, _feedback_value = law.encoder_reading, law.modulo_wrap, law.feedback_value
_filter_step, _mode_error, _pid_step = law.filter_step, law.mode_error, law.pid_step
_slope_limit, _bound_velocity, _advance_offset = law.slope_limit, law.bound_velocity, law.advance_offset
_integrator_after_limiter = law.integrator_after_limiter
_ENCODER, _VARIABLE, _PLC = SensorSource.SECOND_ENCODER, SensorSource.VARIABLE, CommandSource.PLC
_SET_POS, _CONST_DIST = Mode.SET_POS, Mode.CONST_DIST
_MAX_I_GAIN = 1e6          # T / i_tn is bounded: i_tn below T*1e-6 acts as T*1e-6
_INT = {s: int(s) for s in HliState}
_INTERNAL_OF = {_INACTIVE: int(InternalState.IDLE), _ACTIVE: int(InternalState.ACTIVE),
                _ACTIVE_CD: int(InternalState.ACTIVE), _FREEZE: int(InternalState.FREEZE),
                _TURNING_OFF: int(InternalState.OFF), _DRY_CD: int(InternalState.DRYRUN),
                _DRY_SP: int(InternalState.DRYRUN)}
def _finite(x) -> bool:
    return x == x and -law.HUGE < x < law.HUGE


_COMMAND_RANGES = (("kp", "kp"), ("i_tn", "i_tn"), ("d_tv", "d_tv"), ("n_cycles", "n_cycles"),
                   ("order", "low_pass_filter_order"), ("smooth_fact", "smoothing_factor"),
                   ("kalman_sigma", "kalman_sigma"), ("fg_f0", "low_pass_filter_fg_f0"))


def _check_command_values(cmd: Command) -> str:
    """'' when every value of the command is legal, else a message naming the first bad one."""
    for attr, field_name in _COMMAND_RANGES:
        value = getattr(cmd, attr)
        if value is None:
            continue
        spec = BY_FIELD[field_name]
        if not _finite(value) or not spec.check(value) or (spec.type != "REAL64" and int(value) != value):
            return f"{attr.upper()}={value!r} ({spec.id}); allowed: {spec.range_text()}"
    if cmd.filter_type is not None and (not isinstance(cmd.filter_type, FilterType)
                                        or cmd.filter_type == FilterType.PASS):
        return f"FILTER_TYPE={cmd.filter_type!r} unknown"
    for name in ("set_pos", "set_dist", "ref_position"):
        value = getattr(cmd, name)
        if value is not None and not _finite(value):
            return f"{name.upper()}={value!r} is not a finite number"
    for val in cmd.vals:
        if val is not None and not _finite(val):
            return f"VAL={val!r} is not a finite number"
    return ""


def check_object_value(name: str, value: float) -> str:
    """'' when ``value`` (internal units) may be written to the CNC object ``name``, else why not."""
    if not _finite(value):
        return f"{name} = {value!r} is not finite"
    if name in ("kp", "i_tn", "d_tv"):
        spec = BY_FIELD[name]
        if not spec.check(value):
            return f"{name} = {value!r} ({spec.id}); allowed: {spec.range_text()}"
    elif value < 0:
        return f"{name} = {value!r}; allowed: value >= 0"
    return ""
