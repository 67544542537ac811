"""The control law compiled with numba: closed-loop SET_POS kernels over whole signals.

There is no second copy of the law here. :func:`register_law` registers every function of
:data:`distctrl.control.law.LAW_FUNCTIONS` with :func:`numba.extending.register_jitable`, which
returns the function unchanged (CPython callers are unaffected) and makes it callable from jitted
code; the kernels below call ``law.*`` for every number and only do the bookkeeping around it,
in the order of :meth:`AxisDistanceController.update` (SPEC §3-§6):

    act = prog + o                          ideal drive: actual = last command position
    s   = surface[k] - act                  probe reading (the last cycle's without optimized scheduling)
    feedback = act + s                      (= act - d with d = -s)
    filtered = law.filter_step(...)         seeded from the first feedback (no jump)
    e = (filtered - set_pos) - o
    u, i_cand = law.pid_step(...)           derivative on the measurement (filtered)
    v = law.slope_limit(...) -> law.bound_velocity(...) -> o = law.advance_offset(...)
    integral = i_cand unless the limiter clipped in the direction of e (anti-windup)

What the kernels leave out (the cycle core has it): commands and state transitions, monitoring
(70329 sensor jump, 70330/70576 run-out, 70331 max deviation: here the offset just stays at the
bound), override / feed hold, CONST_DIST. Everything is float64, mm and s.

Importing this module imports numba; without numba it raises an ImportError that says how to
install it (check :func:`distctrl.batch.numba_available` first).
"""
from __future__ import annotations

import numpy as np

try:
    import numba  # noqa: F401  (the ImportError below names it)
    from numba import njit, prange
    from numba.extending import register_jitable
except ImportError as exc:          # pragma: no cover - exercised only without numba
    raise ImportError(
        "distctrl.batch.kernel needs numba (the compiled control law); install it with "
        "`pip install 'distctrl[batch]'`. "
        "Use distctrl.batch.numba_available() to check before importing.") from exc

from ..control import law
from ..control.controller import AxisDistanceController
from ..sim import physics
from .jitcache import cached

# ----------------------------------------------------------------------------- registration

_REGISTERED: set[int] = set()


#: compile options of the law functions. ``_nrt=False``: no reference counting of the array
#: arguments inside the law (the law never allocates; it only borrows the caller's buffers); this
#: removes an atomic incref/decref pair per array and call.
_LAW_JIT_OPTIONS = {"_nrt": False}
#: the per-cycle entry points the kernels call are inlined into them at numba-IR level (no call
#: with 3 array structs on the stack per cycle); the helpers they call stay separate functions
#: (inlining ``_push`` trips numba's pedantic IR checks). Only affects jitted callers.
_INLINE = frozenset({"filter_step", "mode_error", "pid_step", "adaptive_acceleration",
                     "slope_limit", "bound_velocity", "advance_offset"})


def register_law() -> None:
    """Register every law function, and the plant's (:mod:`distctrl.sim.physics`), with numba
    (idempotent). Done once on import of this module."""
    for fn in law.LAW_FUNCTIONS + physics.PHYSICS_FUNCTIONS:
        if id(fn) in _REGISTERED:
            continue
        options = dict(_LAW_JIT_OPTIONS)
        if fn.__name__ in _INLINE:
            options["inline"] = "always"
        same = register_jitable(**options)(fn)
        if same is not fn:          # register_jitable must hand back the plain function
            raise RuntimeError(f"numba.register_jitable replaced {fn.__name__}; CPython callers would change")
        _REGISTERED.add(id(fn))
    if id(physics.floor_float) not in _REGISTERED:
        # numba (the [batch] extra): loaded only where a kernel is compiled or run
        from numba.extending import overload

        @overload(physics.floor_float, jit_options=dict(_LAW_JIT_OPTIONS))
        def _floor_float(x):          # the same value for every finite x (and for |x| >= 2**63 too)
            return lambda x: np.floor(x)

        _REGISTERED.add(id(physics.floor_float))


register_law()

# ----------------------------------------------------------------------------- parameter vector

#: layout of the float64 parameter vector ``prm`` of one parameter set (see :func:`pack_params`).
#: Its first columns are the law's constants (``AxisDistanceController.law_constants()``), written by
#: :func:`put_law_constants`; the closed-loop kernel's vector starts with the same columns.
LAW_CONSTANT_COLUMNS = ("T", "kp", "i_gain", "d_gain", "v_max", "a_base", "w_v", "w_a", "a_floor")
P_T = 0            # cycle time, s
P_KP = 1           # kp
P_I_GAIN = 2       # T / i_tn (0 = no I part)
P_D_GAIN = 3       # per-cycle D gain (law.derivative_gain of kp, d_tv, T)
P_V_LIM = 4        # velocity limit of the offset, mm/s (override 1)
P_A_BASE = 5       # acceleration limit, mm/s² (a_max, or the axis acceleration when a_max = 0)
P_W_V = 6          # lowering weight of the velocity (1 = off)
P_W_A = 7          # lowering weight of the acceleration (1 = off)
P_A_FLOOR = 8      # smallest acceleration the limiter may use (braking to a bound)
assert (P_T, P_KP, P_I_GAIN, P_D_GAIN, P_V_LIM, P_A_BASE, P_W_V, P_W_A, P_A_FLOOR) == tuple(range(9))
P_LO = 9           # offset bounds, mm (max_deviation and, if checked, software limits)
P_HI = 10
P_SET_POS = 11     # SET_POS, mm
P_PROG = 12        # programmed position of the axis (constant), mm
P_ADAPTIVE = 13    # 1.0: adaptive acceleration (Fig. 31)
P_A_MIN = 14       # mm/s²
P_DEV_A_MIN = 15   # mm
P_DEV_A_MAX = 16   # mm
P_DELAY = 17       # 1.0: optimized scheduling off (the law sees the last cycle's reading)
P_S_BEFORE = 18    # with P_DELAY: the reading of the cycle before the first one, mm
P_LEN = 19


def put_law_constants(prm: np.ndarray, constants: dict) -> None:
    """Write the law's constants (``AxisDistanceController.law_constants()``) into the first
    ``len(LAW_CONSTANT_COLUMNS)`` columns of a parameter vector (both kernels' layouts start so)."""
    for j, name in enumerate(LAW_CONSTANT_COLUMNS):
        prm[j] = constants[name]


def pack_params(params, cycle_time: float, set_pos: float, programmed_position: float = 0.0,
                s_before: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(fc, prm)`` for one :class:`~distctrl.params.AxisParameters` set.

    The derived constants are taken from an :class:`AxisDistanceController` built with the same
    parameters, so kernel and cycle core cannot disagree about them. ``s_before`` is only used
    when ``optimized_scheduling`` is off: the reading the law sees in the first cycle.
    """
    ctrl = AxisDistanceController(params, cycle_time)     # validates, designs the filter
    c = ctrl.law_constants()
    p = params
    lo, hi = -p.max_deviation, p.max_deviation
    if p.check_sw_limit_switch:
        lo = max(lo, p.sw_limit_min - programmed_position)
        hi = min(hi, p.sw_limit_max - programmed_position)
    prm = np.zeros(P_LEN)
    put_law_constants(prm, c)
    prm[P_LO] = lo
    prm[P_HI] = hi
    prm[P_SET_POS] = set_pos
    prm[P_PROG] = programmed_position
    prm[P_ADAPTIVE] = 1.0 if p.use_adaptive_acceleration else 0.0
    prm[P_A_MIN] = p.a_min
    prm[P_DEV_A_MIN] = p.dist_error_a_min
    prm[P_DEV_A_MAX] = p.dist_error_a_max
    prm[P_DELAY] = 0.0 if p.optimized_scheduling else 1.0
    prm[P_S_BEFORE] = s_before
    return np.asarray(c["fc"], dtype=np.float64), prm


# ----------------------------------------------------------------------------- kernels
# error_model="numpy": the kernels' own divisions (by T > 0) are not checked for zero


@cached
@njit(cache=True, nogil=True, error_model="numpy")
def _setpos_loop_into(fc, prm, surface_mm, n_cycles, fs, buf, out_offset, out_velocity):
    """The closed loop of one parameter set; fills out_offset[:n] and out_velocity[:n]."""
    T = prm[P_T]
    kp = prm[P_KP]
    i_gain = prm[P_I_GAIN]
    d_gain = prm[P_D_GAIN]
    v_lim = prm[P_V_LIM]
    a_base = prm[P_A_BASE]
    w_v = prm[P_W_V]
    w_a = prm[P_W_A]
    a_floor = prm[P_A_FLOOR]
    lo = prm[P_LO]
    hi = prm[P_HI]
    set_pos = prm[P_SET_POS]
    prog = prm[P_PROG]
    adaptive = prm[P_ADAPTIVE] != 0.0
    a_min = prm[P_A_MIN]
    dev_a_min = prm[P_DEV_A_MIN]
    dev_a_max = prm[P_DEV_A_MAX]
    delay = prm[P_DELAY] != 0.0
    s_delayed = prm[P_S_BEFORE]

    o = 0.0
    v_prev = 0.0
    integral = 0.0
    m_prev = 0.0
    for k in range(n_cycles):
        act = prog + o
        reading = surface_mm[k] - act
        if delay:
            s = s_delayed
            s_delayed = reading
        else:
            s = reading
        feedback = act + s
        if k == 0:
            law.filter_seed(fc, fs, buf, feedback)
            m_prev = feedback
        filtered = law.filter_step(fc, fs, buf, feedback)
        target_dev = filtered - set_pos
        e = target_dev - o
        u, i_cand = law.pid_step(kp, i_gain, d_gain, integral, m_prev, e, filtered)
        m_prev = filtered
        a_lim = a_base
        a_brake = a_base
        if adaptive:
            a_lim = law.adaptive_acceleration(abs(e), a_min, a_base, dev_a_min, dev_a_max)
            a_brake = law.adaptive_braking_acceleration(abs(e), a_min, a_base, dev_a_min, dev_a_max)
        v, a_applied, v_applied = law.slope_limit(u, e, v_prev, T, v_lim, a_lim, a_brake, w_v, w_a)
        v = law.bound_velocity(v, o, T, lo, hi, a_floor)
        o_new = law.advance_offset(o, v, T, lo, hi)
        integral = law.integrator_after_limiter(integral, i_cand, u, v, e, T)
        v_prev = (o_new - o) * (1.0 / T)
        o = o_new
        out_offset[k] = o
        out_velocity[k] = v_prev


@cached
@njit(cache=True, nogil=True, error_model="numpy")
def run_setpos_loop(fc, prm, surface_mm, n_cycles):
    """SET_POS distance control of one parameter set over ``n_cycles`` cycles (ON at cycle 0).

    ``fc``: the law's coefficient buffer (:func:`pack_params`), ``prm``: the parameter vector
    (``P_*``), ``surface_mm``: workpiece surface position per cycle. Returns
    ``(offset, velocity)`` per cycle (mm, mm/s), the values after each cycle.
    """
    n = min(n_cycles, surface_mm.shape[0])
    out_offset = np.empty(n)
    out_velocity = np.empty(n)
    fs = np.zeros(law.FS_LEN)
    buf = np.zeros(law.MAX_N)
    _setpos_loop_into(fc, prm, surface_mm, n, fs, buf, out_offset, out_velocity)
    return out_offset, out_velocity


@cached
@njit(cache=True, nogil=True, error_model="numpy")
def run_setpos_loop_into(fc, prm, surface_mm, out_offset, out_velocity):
    """:func:`run_setpos_loop` into caller-owned outputs (no allocation): as many cycles as
    ``out_offset`` is long (at most ``len(surface_mm)``); returns that number."""
    n = min(out_offset.shape[0], out_velocity.shape[0], surface_mm.shape[0])
    fs = np.zeros(law.FS_LEN)
    buf = np.zeros(law.MAX_N)
    _setpos_loop_into(fc, prm, surface_mm, n, fs, buf, out_offset, out_velocity)
    return n


@cached
@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def run_setpos_batch(fc2, prm2, surface_mm, n_cycles):
    """:func:`run_setpos_loop` for many parameter sets on the same surface, in parallel.

    ``fc2``: (n_sets, FC_LEN), ``prm2``: (n_sets, P_LEN). Returns ``(offset, velocity)`` of shape
    (n_sets, n_cycles).
    """
    n_sets = prm2.shape[0]
    n = min(n_cycles, surface_mm.shape[0])
    out_offset = np.empty((n_sets, n))
    out_velocity = np.empty((n_sets, n))
    for i in prange(n_sets):
        fs = np.zeros(law.FS_LEN)
        buf = np.zeros(law.MAX_N)
        _setpos_loop_into(fc2[i], prm2[i], surface_mm, n, fs, buf, out_offset[i], out_velocity[i])
    return out_offset, out_velocity


def compile_kernels() -> None:
    """Compile all kernels now (a few seconds) instead of on their first call."""
    fc = np.zeros(law.FC_LEN)
    fc[law.FC_KIND] = float(law.PASS)
    prm = np.zeros(P_LEN)
    prm[P_T] = 1e-3
    surface = np.zeros(2)
    run_setpos_loop(fc, prm, surface, 2)
    run_setpos_loop_into(fc, prm, surface, np.empty(2), np.empty(2))
    run_setpos_batch(fc.reshape(1, -1), prm.reshape(1, -1), surface, 2)


def numba_available() -> bool:
    """Always True here (this module imported numba); see :func:`distctrl.batch.numba_available`."""
    return True


__all__ = ["register_law", "pack_params", "run_setpos_loop", "run_setpos_loop_into", "run_setpos_batch",
           "compile_kernels", "numba_available", "P_LEN"]
