"""The control law of distance control, as plain functions over floats and flat buffers.

This module is the *only* copy of the law (SPEC §2-§6). The cycle core
(:mod:`distctrl.control.controller`) calls these functions in plain CPython; the batch kernel
(:mod:`distctrl.batch.kernel`) registers the very same functions with numba and compiles them.
Therefore they obey numba's subset: scalars, ``math`` functions, and 1-D indexable buffers (a
Python ``list`` in the scalar core, a ``numpy`` array in the kernel), no objects, no exceptions.

Units: mm, s, Hz. ``T`` is the GEO cycle time in s.

Filter buffers (designed by :func:`distctrl.control.filters.design_coefficients`):
  ``fc`` coefficients: [kind, n, alpha, sigma, rho^n, sum_(k<n) rho^k, n_sections, 1/n,
  sos (3 sections x b0 b1 b2 a0 a1 a2), zi for a unit input (3 sections x 2),
  Kalman gain K, Kalman prior variance P-, EXPO weight factor of the older values beta,
  prediction coefficients c_0..c_(n-1) (oldest first)]    (rho = 1 - alpha)
  ``fs`` state: [ring index, running sum, Kalman P, last output, zi (3 sections x 2), running sum of
  position x value (KALMAN_MA)]
  ``buf`` ring buffer of the last n inputs (measurements), length MAX_N.
"""
from __future__ import annotations

from math import floor, sqrt

# filter kinds (FilterType values)
PASS = 0
MOVING_AVERAGE = 1
EXPO_MEAN = 2
LOWPASS = 3
KALMAN_MA = 4
KALMAN_EXPO = 5

MAX_N = 100            # n_cycles < 100
MAX_SECTIONS = 3       # order <= 6
FC_KIND, FC_N, FC_ALPHA, FC_SIGMA, FC_DECAY_N, FC_WSUM, FC_NSEC, FC_INV_N = 0, 1, 2, 3, 4, 5, 6, 7
FC_SOS = 8
FC_ZI = FC_SOS + 6 * MAX_SECTIONS
FC_GAIN = FC_ZI + 2 * MAX_SECTIONS       # Kalman gain K (constant for a configuration)
FC_P_PRIOR = FC_GAIN + 1                 # Kalman prior variance P- of the prediction
FC_EXPO_OLDER = FC_P_PRIOR + 1           # EXPO_MEAN: beta = alpha / (1 - rho^(n-1)), see filter_step
FC_PRED = FC_EXPO_OLDER + 1              # n prediction coefficients, oldest measurement first
FC_LEN = FC_PRED + MAX_N
FS_IDX, FS_TOTAL, FS_P, FS_LAST, FS_ZI = 0, 1, 2, 3, 4
FS_TSUM = FS_ZI + 2 * MAX_SECTIONS         # KALMAN_MA: sum of j * x_j over the window (j = 0 oldest)
FS_LEN = FS_TSUM + 1

#: everything the scalar law ever lets through is clipped to this (mm); keeps inf/overflow out
HUGE = 1e12


# ----------------------------------------------------------------------------- sensor

def encoder_reading(increments, mm_per_increment, sign_reversal, offset_mm, modulo, lo, hi):
    """Encoder-2 reading s (mm) from raw increments (SPEC §2): scale, sign, shift, modulo."""
    s = increments * mm_per_increment
    if sign_reversal:
        s = -s
    s = s + offset_mm
    if modulo:
        span = hi - lo
        s = lo + (s - lo) % span
    return s


def modulo_wrap(s, lo, hi):
    """A reading wrapped into [lo, hi) (P-AXIS-00424 modulo)."""
    return lo + (s - lo) % (hi - lo)


def modulo_unwrap(s_wrapped, last_wrapped, last_unwrapped, lo, hi):
    """The continuous reading behind a modulo one: the last continuous value plus the shortest step
    on the circle [lo, hi), so a reading crossing the wrap point moves on instead of jumping a span."""
    span = hi - lo
    return last_unwrapped + ((s_wrapped - last_wrapped + 0.5 * span) % span - 0.5 * span)


# ----------------------------------------------------------------------------- filters

def _ring_sum(buf, n):
    total = 0.0
    for i in range(n):
        total += buf[i]
    return total


def _ring_expo_sum(buf, n, idx, alpha):
    """Sum of rho^k x_(newest-k) (rho = 1 - alpha, k = 0 .. n-1) over the ring, newest at idx-1."""
    total = 0.0
    w = 1.0
    rho = 1.0 - alpha
    j = idx - 1
    for _ in range(n):
        if j < 0:
            j += n
        total += w * buf[j]
        w *= rho
        j -= 1
    return total


def filter_seed(fc, fs, buf, x0):
    """Start the filter from the sample x0: history filled with it, output x0 (no jump)."""
    kind = int(fc[FC_KIND])
    n = int(fc[FC_N])
    for i in range(n):
        buf[i] = x0
    fs[FS_IDX] = 0.0
    fs[FS_LAST] = x0
    fs[FS_TSUM] = 0.0
    if kind == MOVING_AVERAGE or kind == KALMAN_MA:
        fs[FS_TOTAL] = x0 * n
        if kind == KALMAN_MA:
            fs[FS_TSUM] = x0 * (0.5 * n * (n - 1))
    elif kind == EXPO_MEAN:
        fs[FS_TOTAL] = x0 * fc[FC_WSUM]
    else:
        fs[FS_TOTAL] = 0.0
    fs[FS_P] = (1.0 - fc[FC_GAIN]) * fc[FC_P_PRIOR]     # Kalman: the (constant) posterior variance
    nsec = int(fc[FC_NSEC])
    for s in range(nsec):
        fs[FS_ZI + 2 * s] = fc[FC_ZI + 2 * s] * x0
        fs[FS_ZI + 2 * s + 1] = fc[FC_ZI + 2 * s + 1] * x0


def window_sum_update(total, x, old):
    """Running sum of the last n values after x enters and ``old`` leaves the window."""
    return total + x - old


def moving_mean(total, inv_n):
    """MOVING_AVERAGE output from the running sum of the last n values; ``inv_n`` = 1/n
    (``fc[FC_INV_N]``): a multiplication, which a vectorised kernel does at full rate."""
    return total * inv_n


def _push(fc, fs, buf, kind, n, x):
    """Put x into the ring of the last n values, updating the running sum (MOVING_AVERAGE) or the
    geometric sum H = sum_(k<n) rho^k x_(newest-k), rho = 1 - alpha, over the window (EXPO_MEAN)."""
    idx = int(fs[FS_IDX])
    old = buf[idx]
    buf[idx] = x
    if kind == MOVING_AVERAGE:
        total = window_sum_update(fs[FS_TOTAL], x, old)
    else:
        total = x + (1.0 - fc[FC_ALPHA]) * fs[FS_TOTAL] - fc[FC_DECAY_N] * old
    idx += 1
    if idx >= n:
        idx = 0
        # re-sum once per window so rounding of the running sum cannot accumulate
        if kind == MOVING_AVERAGE:
            total = _ring_sum(buf, n)
        else:
            total = _ring_expo_sum(buf, n, n, fc[FC_ALPHA])
    fs[FS_IDX] = idx
    fs[FS_TOTAL] = total


def kalman_prediction(fc, buf, n, idx):
    """The Kalman filters' prediction of the current measurement (SPEC §4): the least-squares line
    through the last n measurements (weighted with the exponential mean's weights for KALMAN_EXPO),
    evaluated at the current cycle, i.e. the mean extrapolated over its own delay. A fixed linear
    combination with the coefficients ``fc[FC_PRED:]`` (oldest first); ``idx`` is the ring position
    of the oldest measurement."""
    pred = 0.0
    j = idx
    for i in range(n):
        pred += fc[FC_PRED + i] * buf[j]
        j += 1
        if j >= n:
            j = 0
    return pred


def filter_step(fc, fs, buf, x):
    """One sample through the configured filter (SPEC §4); returns the filtered value."""
    kind = int(fc[FC_KIND])
    n = int(fc[FC_N])
    if kind == PASS:
        y = x
    elif kind == MOVING_AVERAGE:
        _push(fc, fs, buf, kind, n, x)
        y = moving_mean(fs[FS_TOTAL], fc[FC_INV_N])
    elif kind == EXPO_MEAN:
        # the newest value has exactly the weight alpha (P-AXIS-00784); the n-1 older values share
        # 1 - alpha with geometric weights rho^k (k = 1 .. n-1), i.e. beta rho^k with
        # beta = alpha / (1 - rho^(n-1)); H - x is their rho-weighted sum
        _push(fc, fs, buf, kind, n, x)
        y = fc[FC_ALPHA] * x + fc[FC_EXPO_OLDER] * (fs[FS_TOTAL] - x)
    elif kind == LOWPASS:
        # cascaded second-order sections, direct form II transposed (as scipy.signal.sosfilt)
        v = x
        for s in range(int(fc[FC_NSEC])):
            o = FC_SOS + 6 * s
            z = FS_ZI + 2 * s
            y = fc[o] * v + fs[z]
            fs[z] = fc[o + 1] * v - fc[o + 4] * y + fs[z + 1]
            fs[z + 1] = fc[o + 2] * v - fc[o + 5] * y
            v = y
        y = v
    elif kind == KALMAN_MA:
        # the least-squares line through the last n measurements at the current cycle: with
        # S0 = sum x_j and S1 = sum j x_j (j = 0 oldest .. n-1 newest) it is
        # (6 S1 - (2n - 2) S0) / (n (n - 1)) (the coefficients FC_PRED); both sums run along with the
        # ring and are re-summed once per window so that rounding cannot accumulate
        idx = int(fs[FS_IDX])
        s0 = fs[FS_TOTAL]
        s1 = fs[FS_TSUM]
        pred = (6.0 * s1 - (2.0 * n - 2.0) * s0) / (n * (n - 1.0))
        y = pred + fc[FC_GAIN] * (x - pred)
        old = buf[idx]
        buf[idx] = x
        s1 = s1 - (s0 - old) + (n - 1.0) * x
        s0 = s0 - old + x
        idx += 1
        if idx >= n:
            idx = 0
            s0 = 0.0
            s1 = 0.0
            for j in range(n):             # the ring is in order now: buf[0] oldest
                s0 += buf[j]
                s1 += j * buf[j]
        fs[FS_IDX] = idx
        fs[FS_TOTAL] = s0
        fs[FS_TSUM] = s1
    else:
        # KALMAN_EXPO: predict the measurement from the last n measurements (the weighted line,
        # coefficients FC_PRED), then refine the prediction by the measurement with K = P-/(P- + sigma)
        idx = int(fs[FS_IDX])
        pred = kalman_prediction(fc, buf, n, idx)
        y = pred + fc[FC_GAIN] * (x - pred)
        buf[idx] = x
        idx += 1
        if idx >= n:
            idx = 0
        fs[FS_IDX] = idx
    fs[FS_LAST] = y
    return y


# ----------------------------------------------------------------------------- error by mode

def feedback_value(const_dist, both, d, act, command):
    """SPEC §3: the filter input (CNC object ``feedback_value``), mm.

    SET_POS: the measured surface ``a - d``. CONST_DIST: the distance ``d``. CONST_DIST with both
    encoders (P-AXIS-00500, FCT-M3 §7.1 ``d'act = filter(d'act + Zact - Zcom)``): ``d + c - a``, the
    distance the tool will have once the drive has reached its command position ``c = p + o``. The
    documents' d'act is the sensor encoder, which counts against Z (FCT-M3 §5: the two encoders act in
    opposite directions; SPEC §1: reading ``s = -d``), so ``s + a - c`` is ``-(d + c - a)``: the drive's
    lag is taken out of the loop, the command (with the controller's own offset) is inside the filter,
    and the filter's delay stays in the loop."""
    if not const_dist:
        return act - d
    if both:
        return d + command - act
    return d


def mode_error(const_dist, filtered, set_value, o):
    """SPEC §3: (target deviation, remaining error e, measurement part m of e) for the mode.

    SET_POS: filtered surface against SET_POS, ``e = (sf - SET_POS) - o``; CONST_DIST (one or both
    encoders): filtered distance against SET_DIST, ``e = SET_DIST - df``.
    """
    if not const_dist:
        target_dev = filtered - set_value
        return target_dev, target_dev - o, filtered
    return filtered - set_value, set_value - filtered, -filtered


# ----------------------------------------------------------------------------- PID

#: share of the room ``1 - kp`` that the D part may use (see :func:`derivative_gain`)
D_ROOM_SHARE = 0.3


def derivative_gain(kp, d_tv, T):
    """Per-cycle gain g of the D part on the change of the measurement (SPEC §5, docs/control-law.md).

    The offset step is ``u = kp e + I + g (m - m_prev)``. The P part already integrates (the offset
    moves by kp e every cycle), so a D term on the step acts on the offset like a proportional
    feedback of the measurement with the gain g: phase lead, which damps, while g is small. The
    literal ``g = kp d_tv / T`` (2 at the documents' start values kp 0.2, d_tv 0.01 s, T 1 ms)
    answers a measured change with twice the change and makes every loop with a dead time
    oscillate. So the literal gain x = kp d_tv / T is saturated: ``g = x / (1 + x / g_max)`` with
    ``g_max = D_ROOM_SHARE (1 - kp)``. It is the literal derivative time for small x, a larger d_tv is
    always a stronger D part, and P and D together never answer a measured change within one cycle
    with more than the change itself (kp + g < 1; kp = 1 already takes the whole error in one cycle,
    so from kp = 1 on the D part has no room and no effect). Measured: it never lowers the kp at
    which a loop becomes unstable, and lowers the overshoot of a P loop that overshoots (kp < 1)."""
    if not d_tv > 0.0:
        return 0.0
    g_max = D_ROOM_SHARE * (1.0 - kp)
    if not g_max > 0.0:
        return 0.0
    x = kp * d_tv / T
    return x / (1.0 + x / g_max)


def pid_step(kp, t_over_tn, d_gain, integral, m_prev, e, m):
    """PID on the offset step (SPEC §5).

    ``e`` is the remaining error, ``m`` its measurement part (derivative on measurement: the
    controller's own steps cause no kick), ``d_gain`` the D part's per-cycle gain
    (:func:`derivative_gain`). Returns (u, integral candidate); the caller keeps the candidate only
    if the limiter did not clip in the integrator's direction (no wind-up).
    """
    i_new = integral + kp * t_over_tn * e
    u = kp * e + i_new + d_gain * (m - m_prev)
    return u, i_new


def finite_step(u, i_candidate, integral):
    """Never let inf/NaN through: a non-finite (or beyond ``HUGE``) step u or integral candidate
    becomes u clipped to +-HUGE (0 for NaN) and the integral is kept. Returns (u, integral candidate)."""
    if -HUGE < u < HUGE and -HUGE < i_candidate < HUGE:
        return u, i_candidate
    return (0.0 if u != u else max(-HUGE, min(HUGE, u))), integral


def integrator_after_limiter(integral, i_candidate, u, v, e, T):
    """Anti-windup (SPEC §5): keep the new integral unless the limiter clipped the wanted step u
    in the direction the error pushes (then the integrator would wind up)."""
    clipped = u - v * T
    if abs(clipped) <= 1e-12 or (clipped > 0.0) != (e > 0.0):
        return i_candidate
    return integral


# ----------------------------------------------------------------------------- limiter

def brake_velocity(remaining, a, T):
    """Largest velocity (mm/s) from which the offset can still stop within ``remaining`` mm.

    Exact for the discrete motion o += v*T with |dv| <= a*T per cycle: from v = a*T*(j+f) the
    ladder v, v-aT, ..., f*aT covers exactly ``remaining``; following it lands on the target.
    """
    if remaining <= 0.0 or a <= 0.0:
        return 0.0
    a_t = a * T
    if a_t * T <= 0.0:                      # subnormal acceleration: a*T*T underflows
        return sqrt(2.0 * a * remaining)
    q = remaining / (a_t * T)
    if q > 1e12:
        # the ladder has more than ~1e6 rungs: the continuous limit is exact to 1e-6 relative,
        # and floor() of a huge (or infinite) count would overflow
        return sqrt(2.0 * a * remaining)
    k = sqrt(0.25 + 2.0 * q) - 0.5
    j = floor(k)
    f = (q - 0.5 * j * (j + 1.0)) / (j + 1.0)
    if f < 0.0:
        f = 0.0
    elif f > 1.0:
        f = 1.0
    return a_t * (j + f)


def adaptive_acceleration(error_abs, a_min, a_max, dev_a_min, dev_a_max):
    """Fig. 31 (P-AXIS-00501..00505): the acceleration limit for the remaining control error
    ``|e|`` (mm): a_min up to dist_error_a_min, a_max from dist_error_a_max, linear in between."""
    if error_abs <= dev_a_min:
        return a_min
    if error_abs >= dev_a_max:
        return a_max
    return a_min + (a_max - a_min) * (error_abs - dev_a_min) / (dev_a_max - dev_a_min)


def adaptive_braking_acceleration(error_abs, a_min, a_max, dev_a_min, dev_a_max):
    """The acceleration the braking bound ``|v| <= sqrt(2 a |e|)`` uses with adaptive acceleration
    (SPEC §6): the one that applies as e -> 0, a_min (or the current limit, if that is lower: the
    smallest of Fig. 31 between here and the target). Braking with the larger limit that applies far
    from the target cannot stop in time once the limit falls to a_min near it: the offset overshoots
    and the loop falls into a limit cycle, the opposite of the option's documented purpose (FCT-M3
    §7.2: 'to reduce a possible oscillation'). Measured figures: docs/control-law.md."""
    a_here = adaptive_acceleration(error_abs, a_min, a_max, dev_a_min, dev_a_max)
    return a_min if a_min < a_here else a_here


def _clamp(x, lo, hi):
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


def slope_limit_side(u, e, v_prev, T, v_lim, a_lim, a_brake, v_lim_down, a_lim_down):
    """One pass of the slope limiter with the limits (v_lim, a_lim), in mm/s: the wanted velocity
    u/T, braked to sqrt(2 a_brake |e|), then clamped into |v| <= v_lim and |v - v_prev| <= a_lim*T;
    if v_prev is above a lowered v_lim, it decelerates at the full rate rather than steps (the
    acceleration bound always holds). ``a_brake`` is a_lim, or less with adaptive acceleration
    (:func:`adaptive_braking_acceleration`).

    Returns (v, lower): ``lower`` is True if v lowers (v < 0) and lowering has its own (weighted)
    limits (v_lim_down, a_lim_down), so that :func:`slope_limit` makes a second pass with those.
    """
    v_wanted = u * (1.0 / T)            # (a kernel computes 1/T once for all sets)
    vb = sqrt(2.0 * a_brake * abs(e))
    if not -vb <= v_wanted <= vb:
        v_wanted = vb if v_wanted > 0.0 else -vb
    a_t = a_lim * T
    lo = v_prev - a_t
    hi = v_prev + a_t
    if lo < -v_lim:
        lo = -v_lim
    if hi > v_lim:
        hi = v_lim
    if lo > hi:
        v = v_prev - a_t if v_prev > 0.0 else v_prev + a_t
    elif v_wanted < lo:
        v = lo
    elif v_wanted > hi:
        v = hi
    else:
        v = v_wanted
    return v, v < 0.0 and not (v_lim_down == v_lim and a_lim_down == a_lim)


def slope_limit(u, e, v_prev, T, v_lim, a_lim, a_brake, w_v, w_a):
    """Slope limiter (SPEC §6). Returns (v, a_applied, v_lim_applied) in mm/s, mm/s², mm/s.

    From the wanted step u: velocity u/T, braked so the offset can stop within the remaining
    error, |v| <= sqrt(2 a_brake |e|) (SPEC §6; deliberately not the discrete ladder of
    :func:`brake_velocity`, which would forbid any one-step overshoot and so turn kp > 1 into
    kp = 1), then acceleration- and velocity-limited. A result towards the workpiece (v < 0) is
    computed with the lowering limits instead: v_lim, a_lim and a_brake weighted by w_v, w_a, w_a
    (P-AXIS-00533/00534; 1 = off).
    """
    v_lim_down = v_lim * w_v
    a_lim_down = a_lim * w_a
    v, lower = slope_limit_side(u, e, v_prev, T, v_lim, a_lim, a_brake, v_lim_down, a_lim_down)
    if not lower:
        return v, a_lim, v_lim
    v = slope_limit_side(u, e, v_prev, T, v_lim_down, a_lim_down, a_brake * w_a, v_lim_down, a_lim_down)[0]
    if v <= 0.0:
        return v, a_lim_down, v_lim_down
    # the lifting limits say "lower", the lowering limits say "lift": the velocity passes zero this
    # cycle; stop there (reachable within the limits of the side it comes from) and go on next cycle
    if v_prev < 0.0:
        return 0.0, a_lim_down, v_lim_down
    return 0.0, a_lim, v_lim


def bound_velocity(v, o, T, lo, hi, a_floor):
    """Keep the offset inside [lo, hi] (mm): brake towards a bound with the smallest acceleration
    the limiter can use, so the bound is reached at rest and never crossed.

    Far from a bound nothing is computed: the discrete stopping distance from v exceeds
    v²/(2a) + vT/2 by at most aT²/8, so with at least that much room ``v`` stands (exactly the
    result :func:`brake_velocity` would give)."""
    if a_floor <= 0.0:                      # no deceleration possible at all: do not approach a bound
        return 0.0 if (v > 0.0 and o < hi) or (v < 0.0 and o > lo) else v
    if v > 0.0:
        if _brakes_to_bound(v, hi - o, T, a_floor):
            v_hi = brake_velocity(hi - o, a_floor, T)
            if v > v_hi:
                v = v_hi
    elif v < 0.0:
        if _brakes_to_bound(-v, o - lo, T, a_floor):
            v_lo = -brake_velocity(o - lo, a_floor, T)
            if v < v_lo:
                v = v_lo
    return v


def _brakes_to_bound(speed, room, T, a_floor):
    """True if ``room`` (mm) may be too short to stop from ``speed`` (mm/s, > 0) at a_floor > 0."""
    return room < (speed * speed / (2.0 * a_floor) + 0.5 * speed * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) \
        + 1e-300


def near_bound(v, o, T, lo, hi, a_floor, inv_2a_floor):
    """True unless :func:`bound_velocity` certainly returns ``v`` unchanged (far from both bounds,
    or standing). A kernel can run the cheap test for many sets and the full function for the few.

    ``inv_2a_floor`` = 0.5 / a_floor, computed once per set: a multiplication where
    :func:`_brakes_to_bound` divides. The two thresholds differ by a few rounding steps, far less
    than the wider margin here (2e-12 against 1e-12), so this is True wherever
    :func:`_brakes_to_bound` is, and :func:`bound_velocity`, which tests again, decides as always.
    """
    if a_floor <= 0.0:
        return v != 0.0
    if v == 0.0:
        return False
    speed = abs(v)                      # one test for both directions (abs(v) == -v for v < 0 exactly)
    room = hi - o if v > 0.0 else o - lo
    return room < (speed * speed * inv_2a_floor + 0.5 * speed * T + 0.125 * a_floor * T * T) * (1.0 + 2e-12) \
        + 1e-300


def advance_offset(o, v, T, lo, hi):
    """o + v*T, kept inside [lo, hi] against rounding."""
    o_new = o + v * T
    if o_new > hi:
        o_new = hi if o <= hi else o_new if v <= 0.0 else o
    if o_new < lo:
        o_new = lo if o >= lo else o_new if v >= 0.0 else o
    return o_new


#: the functions numba compiles for the batch kernel (registered by distctrl.batch.kernel)
LAW_FUNCTIONS = (encoder_reading, modulo_wrap, modulo_unwrap, _ring_sum, _ring_expo_sum, filter_seed, window_sum_update,
                 moving_mean, _push, kalman_prediction, filter_step, feedback_value, mode_error, derivative_gain, pid_step, finite_step, integrator_after_limiter,
                 brake_velocity,
                 adaptive_acceleration, adaptive_braking_acceleration, _clamp, slope_limit_side, slope_limit,
                 _brakes_to_bound, near_bound, bound_velocity, advance_offset)
