component distctrl_thc "distctrl's distance-control law as a torch height control in the servo thread (docs/linuxcnc.md)";
description """
distctrl's cycle core (distctrl/control/controller.py, AxisDistanceController.update, with the law of
distctrl/control/law.py: filter, PID with derivative on the measurement and anti-windup, slope limiter with
braking and the lowering weights, the adaptive acceleration, the max_deviation bound and the software
limits; CONST_DIST and SET_POS (mode), DRYRUN; the HLI states; the monitoring errors) translated operation for
operation into C, so that its outputs equal the Python core's bit for bit (tests/linuxcnc/test_thc.py checks
it in halrun for every filter type, the state transitions and every monitoring error, against
distctrl.linuxcnc.thc.ThcCore). The arc voltage is linearised into the distance as distctrl's PLC does
(distance = (arc-voltage-in - arc-v0) * (1 / arc-k)); the core sees it as the sensor variable (reading
s = -distance). Pins are named like plasmac's where they mean the same.

States (state, HLI DistanceControl's numbers): 0 INACTIVE, 1 ACTIVE, 4 ACTIVE_CONST_DIST, 2 FREEZE,
3 TURNING_OFF, 5 ERROR, 6 DRYRUN_CONST_DIST, 7 DRYRUN_SETPOS. The pins give the commands a PLC would:
thc-enable on in INACTIVE = ON_CONST_DIST with set-dist (mode 0) or ON with set-pos (mode 1), DRYRUN with
the mode's set value if dryrun is on (entering seeds the filter with the current feedback: no jump); a lock
(corner or void) in ACTIVE(_CONST_DIST) = FREEZE (the wanted step is 0, the offset brakes within the
acceleration limit and stays, the integrator holds), the lock open again = ON into the frozen mode;
thc-enable off = OFF: TURNING_OFF runs the offset out to 0 within the limits, then INACTIVE. Monitoring while ACTIVE(_CONST_DIST) or DRYRUN (error-id, the
documents' IDs): 70329 the reading changed by more than max-act-value-change * period, 70330 / 70576 the
reading left the window max-pos - tolerance / min-pos + tolerance, 70331 the offset at max-deviation and
the law wants beyond, 900002 the same at a software limit (check-sw-limit-switch), 900001 a non-finite input. ERROR holds the offset (it brakes and stays) and is left
only by thc-enable off (TURNING_OFF, the run-out) and on again.
Corner lock (cornerlock-mode 0, the default): distctrl's corner_lock process function
(distctrl/plc/process/corner_lock.py, its ST): while tracking (ACTIVE_CONST_DIST, or the FREEZE it
commanded), armed once current-velocity * 60 has reached (cornerlock-threshold + cornerlock-hysteresis) % of
feed-upm (F times the override, units/min), then locked below cornerlock-threshold % (or feed-upm 0) and open
again at threshold + hysteresis. cornerlock-mode 1: plasmac 1.235's rule (locked below cornerlock-threshold %
of feed-upm, open above 99 %, while thc-enable is on; no arming).
Void lock: distctrl's void_lock function (distctrl/plc/process/void_lock.py, its ST), while tracking: the arc
voltage's rate over a window of voidlock-window s above voidlock-slope for voidlock-on-cycles periods closes
it; steady for voidlock-off-cycles periods with the window's mean at most voidlock-release-band above the
level before the void opens it; the window starts afresh at every select; a non-finite sample is not
stored and counts as unsteady. Switching cornerlock-enable or voidlock-enable resets the function.

The filter coefficients fc-000..fc-134 are the law's coefficient buffer (distctrl.control.filters.
design_coefficients; the low-pass is designed with scipy there): `distctrl linuxcnc thc-setp` prints
them as setp lines, validated with the documents' ranges.
""";
pin in float arc_voltage_in "arc voltage (V)";
pin in float arc_v0 = 95.0 "linearisation: voltage at zero height (V)";
pin in float arc_k = 6.0 "linearisation: V per mm";
pin in bit thc_enable "on: ON_CONST_DIST (from INACTIVE); off: OFF (TURNING_OFF runs the offset out to 0)";
pin in bit use_both_encoders "P-AXIS-00500: feedback d + c - a (FCT-M3 §7.1) instead of d";
pin in float axis_z_position "a: the Z joint's actual position (joint.N.pos-fb)";
pin in float axis_z_command "p: Z as programmed, without this component's offset (the core adds it: c = p + offset)";
pin in bit cornerlock_enable "enable corner lock";
pin in float cornerlock_threshold = 90.0 "corner lock below this % of feed-upm (corner_lock.share * 100; plasmac's threshold)";
pin in float current_velocity "current path velocity (units/s), motion.current-vel";
pin in float feed_upm "the feed F times the override (units/min), motion.feed-upm (plasmac's feed-upm)";
pin in s32 cornerlock_mode "0: distctrl's corner_lock process function (default); 1: plasmac's rule";
pin in float cornerlock_hysteresis = 5.0 "mode 0: opens at cornerlock-threshold + this (% of feed-upm), corner_lock.hysteresis";
pin in bit voidlock_enable "enable void lock";
pin in float voidlock_slope = 500.0 "void lock above this arc-voltage rate over the window (V/s)";
pin in float voidlock_window = 0.02 "the rate's window (s; 20 ms spans a 50 Hz ripple period; at most 100 periods)";
pin in s32 voidlock_on_cycles = 3 "periods in a row above the rate until the void lock closes";
pin in s32 voidlock_off_cycles = 20 "steady periods in a row until the void lock opens";
pin in float voidlock_release_band = 5.0 "the window's mean may be this much (V) above the level before the void to open";
pin in float set_dist = 1.5 "SET_DIST: the cut height (mm)";
pin in float kp = 0.5 "KP, P-AXIS-00759 (0 < kp <= 2)";
pin in float i_tn "I_TN, P-AXIS-00764 (s; 0 = no I part)";
pin in float d_tv "D_TV, P-AXIS-00765 (s; 0 = no D part)";
pin in float v_max = 100.0 "velocity limit of the offset (mm/s), P-AXIS-00415 in mm/s";
pin in float a_max = 2000.0 "acceleration limit of the offset (mm/s^2), P-AXIS-00416";
pin in float max_deviation = 20.0 "bound of the offset (mm), P-AXIS-00414 (70331)";
pin in float max_act_value_change = 5000.0 "P-AXIS-00417 (mm/s): the reading may change by this * period (70329)";
pin in float max_pos = 50000.0 "P-AXIS-00419 (mm): upper end of the reading s = -distance (70330)";
pin in float min_pos = -50000.0 "P-AXIS-00420 (mm): lower end of the reading s = -distance (70576)";
pin in float tolerance = 0.0 "P-AXIS-00421 (mm): the window is min-pos + tolerance .. max-pos - tolerance";
pin in bit check_sw_limit_switch "P-AXIS-00428: the offset bounded by the software limits (c = p + offset within them)";
pin in float sw_limit_max = 214748.3646 "P-AXIS-00177 swe_pos (mm, axis-z-command's coordinates)";
pin in float sw_limit_min = -214748.3648 "P-AXIS-00178 swe_neg (mm)";
pin in float v_weight_down "P-AXIS-00533: v-max of a lowering move times this (fraction, 0 = off)";
pin in float a_weight_down "P-AXIS-00534: a-max of a lowering move times this (fraction, 0 = off)";
pin in bit use_adaptive_acceleration "P-AXIS-00501: the acceleration by the control error (FCT-M3 Fig. 31)";
pin in float a_min = 500.0 "P-AXIS-00502: the acceleration up to dist-error-a-min (mm/s^2)";
pin in float dist_error_a_min = 0.1 "P-AXIS-00504 (mm)";
pin in float dist_error_a_max = 0.5 "P-AXIS-00505 (mm): a-max from this control error on";
pin in s32 mode "0: CONST_DIST (the height set-dist above the plate); 1: SET_POS (the surface at set-pos); read at the select";
pin in float set_pos "SET_POS (mm, axis-z-command's coordinates): the surface position; read every period while ACTIVE (cyclic D_Position)";
pin in bit dryrun "on: thc-enable selects DRYRUN (CONST_DIST): the cycle runs, the offset stands (target-deviation, wanted-step)";
pin in float resolution = 0.001 "mm per offset count (wire plasmac.offset-scale to it; 0: no counts)";
pin in float fc-###[135] "the law's filter coefficients (design_coefficients)";
pin out s32 z_offset_counts "offset in counts, connect to axis.z.eoffset-counts";
pin out float offset_scale "mm per count, connect to axis.z.eoffset-scale";
pin out bit z_offset_enable "connect to axis.z.eoffset-enable";
pin out bit cornerlock_is_locked "corner locked";
pin out bit voidlock_is_locked "void locked";
pin out float voidlock_rate "the void lock's arc-voltage rate over its window (V/s; NaN before the first full window)";
pin out float voidlock_mean "the void lock's window mean (V; NaN until the window is full)";
pin out float offset "the offset o (mm)";
pin out float distance "the linearised distance (mm)";
pin out float filtered "the filtered distance (mm; the unfiltered one where the filter does not run)";
pin out float velocity "the offset's velocity (mm/s)";
pin out float target_deviation "the filtered distance minus SET_DIST (mm), in ACTIVE_CONST_DIST and DRYRUN";
pin out float wanted_step "the law's step before the limiter (mm per period; delta_deviation_pre_limiter)";
pin out s32 state "HLI state: 0 INACTIVE, 2 FREEZE, 3 TURNING_OFF, 4 ACTIVE_CONST_DIST, 5 ERROR, 6 DRYRUN_CONST_DIST";
pin out s32 error_id "the error that put it into ERROR (70329, 70330, 70576, 70331, 900001, ...), 0 once INACTIVE";
variable double buf[100];
variable double fs[11];
variable double cf[135];
variable double integral;
variable double m_prev;
variable double vel;
variable double o;
variable double sd;
variable double last_s;
variable double last_p;
variable double last_a;
variable double a_bound_st;
variable int hli;
variable int errv;
variable int seeded;
variable int has_last_s;
variable int mode_cd;
variable int sel_cd;
variable double sp;
variable double vbuf[100];
variable double vmean[100];
variable double vsum;
variable double vlevel;
variable double vmean_now;
variable double vrate;
variable int cl_armed;
variable int cl_locked;
variable int held;
variable int vinit;
variable int pend_dry;
variable int vi;
variable int nfill;
variable int nmfill;
variable int non;
variable int noff;
function _ fp "one period of the law";
license "GPL";
author "distctrl";
;;
#include <math.h>

#define FC_KIND 0
#define FC_N 1
#define FC_ALPHA 2
#define FC_DECAY_N 4
#define FC_WSUM 5
#define FC_NSEC 6
#define FC_INV_N 7
#define FC_SOS 8
#define FC_ZI 26
#define FC_GAIN 32
#define FC_P_PRIOR 33
#define FC_EXPO_OLDER 34
#define FC_PRED 35
#define FS_IDX 0
#define FS_TOTAL 1
#define FS_P 2
#define FS_LAST 3
#define FS_ZI 4
#define FS_TSUM 10
#define K_PASS 0
#define K_MA 1
#define K_EXPO 2
#define K_LOWPASS 3
#define K_KALMAN_MA 4
#define HUGE_MM 1e12
#define D_ROOM_SHARE 0.3
#define MAX_I_GAIN 1e6
#define LAND 1e-9
/* HLI_DIST_CTRL_STATE_* (distctrl/base/states.py) and the error IDs (distctrl/errors) */
#define S_INACTIVE 0
#define S_FREEZE 2
#define S_TURNING_OFF 3
#define S_ACTIVE_CD 4
#define S_ACTIVE 1
#define S_DRY_SP 7
#define S_ERROR 5
#define S_DRY_CD 6
#define E_SW_LIMIT 900002
#define E_SENSOR_JUMP 70329
#define E_RUN_OUT_MAX 70330
#define E_MAX_DEVIATION 70331
#define E_RUN_OUT_MIN 70576
#define E_NOT_FINITE 900001
#define E_INVALID_TRANSITION 900003
#define E_VALUE_OUT_OF_RANGE 900005
#define FINITE(x) ((x) == (x) && -HUGE_MM < (x) && (x) < HUGE_MM)

/* ---- distctrl/control/law.py, function for function, the same operations in the same order ---- */

static double ring_sum(const double *b, int n)
{
    double total = 0.0;
    int i;
    for (i = 0; i < n; i++)
        total += b[i];
    return total;
}

static double ring_expo_sum(const double *b, int n, int idx, double alpha)
{
    double total = 0.0, w = 1.0, rho = 1.0 - alpha;
    int j = idx - 1, k;
    for (k = 0; k < n; k++) {
        if (j < 0)
            j += n;
        total += w * b[j];
        w *= rho;
        j -= 1;
    }
    return total;
}

static void filter_seed(const double *c, double *s, double *b, double x0)
{
    int kind = (int)c[FC_KIND], n = (int)c[FC_N], i, nsec;
    for (i = 0; i < n; i++)
        b[i] = x0;
    s[FS_IDX] = 0.0;
    s[FS_LAST] = x0;
    s[FS_TSUM] = 0.0;
    if (kind == K_MA || kind == K_KALMAN_MA) {
        s[FS_TOTAL] = x0 * n;
        if (kind == K_KALMAN_MA)
            s[FS_TSUM] = x0 * (0.5 * n * (n - 1));
    } else if (kind == K_EXPO) {
        s[FS_TOTAL] = x0 * c[FC_WSUM];
    } else {
        s[FS_TOTAL] = 0.0;
    }
    s[FS_P] = (1.0 - c[FC_GAIN]) * c[FC_P_PRIOR];
    nsec = (int)c[FC_NSEC];
    for (i = 0; i < nsec; i++) {
        s[FS_ZI + 2 * i] = c[FC_ZI + 2 * i] * x0;
        s[FS_ZI + 2 * i + 1] = c[FC_ZI + 2 * i + 1] * x0;
    }
}

static void push(const double *c, double *s, double *b, int kind, int n, double x)
{
    int idx = (int)s[FS_IDX];
    double old = b[idx], total;
    b[idx] = x;
    if (kind == K_MA)
        total = s[FS_TOTAL] + x - old;
    else
        total = x + (1.0 - c[FC_ALPHA]) * s[FS_TOTAL] - c[FC_DECAY_N] * old;
    idx += 1;
    if (idx >= n) {
        idx = 0;
        if (kind == K_MA)
            total = ring_sum(b, n);
        else
            total = ring_expo_sum(b, n, n, c[FC_ALPHA]);
    }
    s[FS_IDX] = idx;
    s[FS_TOTAL] = total;
}

static double kalman_prediction(const double *c, const double *b, int n, int idx)
{
    double pred = 0.0;
    int j = idx, i;
    for (i = 0; i < n; i++) {
        pred += c[FC_PRED + i] * b[j];
        j += 1;
        if (j >= n)
            j = 0;
    }
    return pred;
}

static double filter_step(const double *c, double *s, double *b, double x)
{
    int kind = (int)c[FC_KIND], n = (int)c[FC_N], idx, i, j;
    double y, v, pred, s0, s1, old;
    if (kind == K_PASS) {
        y = x;
    } else if (kind == K_MA) {
        push(c, s, b, kind, n, x);
        y = s[FS_TOTAL] * c[FC_INV_N];
    } else if (kind == K_EXPO) {
        push(c, s, b, kind, n, x);
        y = c[FC_ALPHA] * x + c[FC_EXPO_OLDER] * (s[FS_TOTAL] - x);
    } else if (kind == K_LOWPASS) {
        v = x;
        y = x;
        for (i = 0; i < (int)c[FC_NSEC]; i++) {
            int o_ = FC_SOS + 6 * i, z = FS_ZI + 2 * i;
            y = c[o_] * v + s[z];
            s[z] = c[o_ + 1] * v - c[o_ + 4] * y + s[z + 1];
            s[z + 1] = c[o_ + 2] * v - c[o_ + 5] * y;
            v = y;
        }
        y = v;
    } else if (kind == K_KALMAN_MA) {
        idx = (int)s[FS_IDX];
        s0 = s[FS_TOTAL];
        s1 = s[FS_TSUM];
        pred = (6.0 * s1 - (2.0 * n - 2.0) * s0) / (n * (n - 1.0));
        y = pred + c[FC_GAIN] * (x - pred);
        old = b[idx];
        b[idx] = x;
        s1 = s1 - (s0 - old) + (n - 1.0) * x;
        s0 = s0 - old + x;
        idx += 1;
        if (idx >= n) {
            idx = 0;
            s0 = 0.0;
            s1 = 0.0;
            for (j = 0; j < n; j++) {
                s0 += b[j];
                s1 += j * b[j];
            }
        }
        s[FS_IDX] = idx;
        s[FS_TOTAL] = s0;
        s[FS_TSUM] = s1;
    } else {
        idx = (int)s[FS_IDX];
        pred = kalman_prediction(c, b, n, idx);
        y = pred + c[FC_GAIN] * (x - pred);
        b[idx] = x;
        idx += 1;
        if (idx >= n)
            idx = 0;
        s[FS_IDX] = idx;
    }
    s[FS_LAST] = y;
    return y;
}

static double derivative_gain(double kp_, double d_tv_, double T)
{
    double g_max, x;
    if (!(d_tv_ > 0.0))
        return 0.0;
    g_max = D_ROOM_SHARE * (1.0 - kp_);
    if (!(g_max > 0.0))
        return 0.0;
    x = kp_ * d_tv_ / T;
    return x / (1.0 + x / g_max);
}

static double brake_velocity(double remaining, double a, double T)
{
    double a_t, q, k, j, f;
    if (remaining <= 0.0 || a <= 0.0)
        return 0.0;
    a_t = a * T;
    if (a_t * T <= 0.0)
        return sqrt(2.0 * a * remaining);
    q = remaining / (a_t * T);
    if (q > 1e12)
        return sqrt(2.0 * a * remaining);
    k = sqrt(0.25 + 2.0 * q) - 0.5;
    j = floor(k);
    f = (q - 0.5 * j * (j + 1.0)) / (j + 1.0);
    if (f < 0.0)
        f = 0.0;
    else if (f > 1.0)
        f = 1.0;
    return a_t * (j + f);
}

static double slope_limit_side(double u, double e, double v_prev_, double T, double v_lim, double a_lim,
                               double a_brake, double v_lim_down, double a_lim_down, int *lower)
{
    double v_wanted = u * (1.0 / T), vb = sqrt(2.0 * a_brake * fabs(e)), a_t, lo, hi, v;
    if (!(-vb <= v_wanted && v_wanted <= vb))
        v_wanted = v_wanted > 0.0 ? vb : -vb;
    a_t = a_lim * T;
    lo = v_prev_ - a_t;
    hi = v_prev_ + a_t;
    if (lo < -v_lim)
        lo = -v_lim;
    if (hi > v_lim)
        hi = v_lim;
    if (lo > hi)
        v = v_prev_ > 0.0 ? v_prev_ - a_t : v_prev_ + a_t;
    else if (v_wanted < lo)
        v = lo;
    else if (v_wanted > hi)
        v = hi;
    else
        v = v_wanted;
    *lower = v < 0.0 && !(v_lim_down == v_lim && a_lim_down == a_lim);
    return v;
}

static double adaptive_acceleration(double error_abs, double a_min_, double a_max_, double dev_a_min,
                                    double dev_a_max)
{
    if (error_abs <= dev_a_min)
        return a_min_;
    if (error_abs >= dev_a_max)
        return a_max_;
    return a_min_ + (a_max_ - a_min_) * (error_abs - dev_a_min) / (dev_a_max - dev_a_min);
}

static double adaptive_braking_acceleration(double error_abs, double a_min_, double a_max_, double dev_a_min,
                                            double dev_a_max)
{
    double a_here = adaptive_acceleration(error_abs, a_min_, a_max_, dev_a_min, dev_a_max);
    return a_min_ < a_here ? a_min_ : a_here;
}

/* law.slope_limit: returns v, *a_applied */
static double slope_limit(double u, double e, double v_prev_, double T, double v_lim, double a_lim, double a_brake,
                          double w_v, double w_a, double *a_applied)
{
    double v_lim_down = v_lim * w_v, a_lim_down = a_lim * w_a, v;
    int lower, dummy;
    v = slope_limit_side(u, e, v_prev_, T, v_lim, a_lim, a_brake, v_lim_down, a_lim_down, &lower);
    if (!lower) {
        *a_applied = a_lim;
        return v;
    }
    v = slope_limit_side(u, e, v_prev_, T, v_lim_down, a_lim_down, a_brake * w_a, v_lim_down, a_lim_down, &dummy);
    if (v <= 0.0) {
        *a_applied = a_lim_down;
        return v;
    }
    /* the velocity passes zero this period: stop there, go on next period */
    *a_applied = v_prev_ < 0.0 ? a_lim_down : a_lim;
    return 0.0;
}

static int brakes_to_bound(double speed, double room, double T, double a_floor)
{
    return room < (speed * speed / (2.0 * a_floor) + 0.5 * speed * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12)
                  + 1e-300;
}

static double bound_velocity(double v, double o_, double T, double lo, double hi, double a_floor)
{
    double vb;
    if (a_floor <= 0.0)
        return ((v > 0.0 && o_ < hi) || (v < 0.0 && o_ > lo)) ? 0.0 : v;
    if (v > 0.0) {
        if (brakes_to_bound(v, hi - o_, T, a_floor)) {
            vb = brake_velocity(hi - o_, a_floor, T);
            if (v > vb)
                v = vb;
        }
    } else if (v < 0.0) {
        if (brakes_to_bound(-v, o_ - lo, T, a_floor)) {
            vb = -brake_velocity(o_ - lo, a_floor, T);
            if (v < vb)
                v = vb;
        }
    }
    return v;
}

static double advance_offset(double o_, double v, double T, double lo, double hi)
{
    double n_ = o_ + v * T;
    if (n_ > hi)
        n_ = o_ <= hi ? hi : (v <= 0.0 ? n_ : o_);
    if (n_ < lo)
        n_ = o_ >= lo ? lo : (v >= 0.0 ? n_ : o_);
    return n_;
}

FUNCTION(_) {
    double T = fperiod, inv_T = 1.0 / T, d_in, s_now, s, d, prog, act, fb, y, e, m, u, ic, integral0, v, v_prev,
           i_gain, dg, a_base, a_floor, a_lim, a_applied, a_bound, v_lim, lo, hi, v_limited, o_prev, o_new, u_lim,
           e_lim, wanted, clipped, v_real, w_v, w_a, a_brake, tdev;
    int i, locked, finite_inputs = 1, sensor_ok, running, hold, st0, tracking, freeze = 0;
    for (i = 0; i < 135; i++)
        cf[i] = fc(i);
    if (!vinit) {                               /* VoidLock's initial state: no mean, no rate, no level */
        vmean_now = NAN;
        vrate = NAN;
        vlevel = NAN;
        vinit = 1;
    }
    offset_scale = resolution;
    d_in = (arc_voltage_in - arc_v0) * (1.0 / arc_k);
    distance = d_in;
    /* the locks: distctrl's corner_lock and void_lock process functions (distctrl/plc/process/corner_lock.py,
       void_lock.py, their step) as distctrl's PLC runs them on an axis: state_r.actual_state is the state of
       the last period (hli), the hold is ours in a FREEZE the locks commanded (held); a switch resets */
    tracking = hli == S_ACTIVE_CD || hli == S_ACTIVE || (hli == S_FREEZE && held);
    if (cornerlock_mode == 1) {                 /* plasmac 1.235's rule (plasmac.comp, CUT_MODE_01) */
        double vc = current_velocity * 60.0;
        if (!cornerlock_enable || !thc_enable)
            cornerlock_is_locked = 0;
        else if (vc < feed_upm * cornerlock_threshold * 0.01)
            cornerlock_is_locked = 1;
        else if (cornerlock_is_locked && vc > feed_upm * 0.99)
            cornerlock_is_locked = 0;
        cl_armed = 0;
        cl_locked = 0;
    } else {
        if (!cornerlock_enable || !tracking) {  /* switched off (reset), or not tracking (disarmed) */
            cl_armed = 0;
            cl_locked = 0;
        } else {
            double ref = feed_upm * 1.0, vc = current_velocity * 60.0;   /* D_CommandFeed * override, D_ActiveFeed */
            double share = cornerlock_threshold * 0.01, hyst = cornerlock_hysteresis * 0.01;
            int back = ref > 0.0 && vc >= (share + hyst) * ref;
            if (!cl_armed)
                cl_armed = back;
            else if (cl_locked)
                cl_locked = !back;
            else
                cl_locked = ref <= 0.0 || vc < share * ref;
        }
        cornerlock_is_locked = cornerlock_enable && cl_armed && cl_locked;
    }
    if (!voidlock_enable) {                     /* switched off: VoidLock.reset() */
        vi = 0;
        nfill = 0;
        nmfill = 0;
        vsum = 0.0;
        vmean_now = NAN;
        vrate = NAN;
        vlevel = NAN;
        voidlock_is_locked = 0;
        non = 0;
        noff = 0;
    } else if (!tracking) {                     /* the window starts afresh at the select */
        nfill = 0;
        nmfill = 0;
        vsum = 0.0;
        vmean_now = NAN;
        voidlock_is_locked = 0;
        non = 0;
        noff = 0;
    } else {
        int N = (int)rint(voidlock_window / T), full, mfull, vfinite, steady;
        double x = arc_voltage_in, old, mean_old, rate;
        if (N < 1)
            N = 1;
        if (N > 100)
            N = 100;
        if (vi >= N)
            vi = 0;
        vfinite = isfinite(x);
        old = vbuf[vi];
        full = nfill >= N;                      /* old is a sample taken N periods ago */
        mean_old = vmean[vi];                   /* the window mean N periods ago */
        mfull = nmfill >= N;
        if (vfinite) {                          /* a non-finite sample is not stored */
            vbuf[vi] = x;
            vsum += full ? x - old : x;
            if (!full)
                nfill += 1;
            if (nfill >= N) {
                vmean_now = vsum / N;
                vmean[vi] = vmean_now;
                if (nmfill < N)
                    nmfill += 1;
            }
            vi = (vi + 1) % N;
        }
        if (!full) {
            voidlock_is_locked = 0;
            non = 0;
            noff = 0;
        } else {
            rate = vfinite ? (x - old) * (1.0 / (N * T)) : INFINITY;
            vrate = rate;
            steady = fabs(rate) <= voidlock_slope;
            if (!voidlock_is_locked) {
                non = steady ? 0 : non + 1;
                if (non >= voidlock_on_cycles) {
                    voidlock_is_locked = 1;
                    vlevel = mfull ? mean_old : old;
                    noff = 0;
                }
            } else {
                if (steady && vmean_now - vlevel <= voidlock_release_band)
                    noff += 1;
                else
                    noff = 0;
                if (noff >= voidlock_off_cycles) {
                    voidlock_is_locked = 0;
                    non = 0;
                }
            }
        }
    }
    voidlock_rate = vrate;
    voidlock_mean = vmean_now;
    locked = cornerlock_is_locked || voidlock_is_locked;

    /* ---- AxisDistanceController.update (distctrl/control/controller.py) as the component reaches it:
       CONST_DIST, PLC-commanded, the distance as the sensor variable, optimized scheduling, no adaptive
       acceleration, no lowering weights (1), no software limits, override 1 ---- */
    a_base = a_max;
    w_v = v_weight_down > 0.0 ? v_weight_down : 1.0;
    w_a = a_weight_down > 0.0 ? a_weight_down : 1.0;
    /* min(a_candidates) * min(1.0, w_a): the smallest acceleration the limiter may use */
    a_floor = (use_adaptive_acceleration && a_min < a_base ? a_min : a_base) * (w_a < 1.0 ? w_a : 1.0);
    i_gain = i_tn > 0.0 ? (T / i_tn < MAX_I_GAIN ? T / i_tn : MAX_I_GAIN) : 0.0;
    dg = derivative_gain(kp, d_tv, T);
    /* 1. inputs made safe */
    prog = axis_z_command;
    if (-HUGE_MM < prog && prog < HUGE_MM)
        last_p = prog;
    else {
        prog = last_p;
        finite_inputs = 0;
    }
    act = axis_z_position;
    if (-HUGE_MM < act && act < HUGE_MM)
        last_a = act;
    else {
        act = last_a;
        finite_inputs = 0;
    }
    /* 2. the sensor variable: s = -d + ref_shift (0) */
    if (FINITE(d_in)) {
        s_now = -d_in + 0.0;
        sensor_ok = 1;
    } else {
        s_now = last_s;
        sensor_ok = 0;
        finite_inputs = 0;
    }
    s = s_now;
    /* 3. the PLC's commands from the state of the last period and the locks of this one */
    st0 = hli;
    if (st0 == S_INACTIVE && thc_enable)                         /* the select reads the mode */
        sel_cd = mode != 1;
    if (!thc_enable) {
        if (st0 == S_ACTIVE_CD || st0 == S_ACTIVE || st0 == S_FREEZE || st0 == S_ERROR || st0 == S_DRY_CD
                || st0 == S_DRY_SP) {
            hli = S_TURNING_OFF;                                 /* OFF */
            pend_dry = 0;
        }
    } else if (st0 == S_INACTIVE || (st0 == S_FREEZE && held && !locked)) {
        if (!FINITE(sel_cd ? set_dist : set_pos)) {              /* ON refused: 900005 */
            hli = S_ERROR;
            errv = E_VALUE_OUT_OF_RANGE;
        } else {                                                 /* ON_CONST_DIST with SET_DIST, ON with SET_POS */
            if (sel_cd)
                sd = set_dist;
            else
                sp = set_pos;
            if (st0 == S_INACTIVE || mode_cd != sel_cd) {
                seeded = 0;
                integral = 0.0;
            }
            mode_cd = sel_cd;
            if (st0 == S_INACTIVE && dryrun) {                   /* DRYRUN (HLI CONST_DIST / DRYRUN) */
                hli = sel_cd ? S_DRY_CD : S_DRY_SP;
                if (vel != 0.0) {                                /* the offset still moves: FREEZE until it stands */
                    pend_dry = hli;
                    hli = S_FREEZE;
                }
            } else
                hli = sel_cd ? S_ACTIVE_CD : S_ACTIVE;
        }
        if (st0 == S_INACTIVE && locked && !dryrun) {            /* FREEZE at once */
            freeze = 1;
            if (hli == S_ACTIVE_CD || hli == S_ACTIVE)
                hli = S_FREEZE;
            else
                errv = E_INVALID_TRANSITION;
        }
    } else if ((st0 == S_ACTIVE_CD || st0 == S_ACTIVE) && locked) {
        hli = S_FREEZE;                                          /* FREEZE */
        freeze = 1;
    }
    running = hli == S_ACTIVE_CD || hli == S_ACTIVE || hli == S_DRY_CD || hli == S_DRY_SP;
    if (running) {
        if (mode_cd) {                                           /* the PLC's cyclic D_Distance / D_Position */
            if (FINITE(set_dist))
                sd = set_dist;
        } else if (FINITE(set_pos))
            sp = set_pos;
        /* 4. monitoring */
        if (!finite_inputs) {
            hli = S_ERROR;
            errv = E_NOT_FINITE;
        } else if (has_last_s && fabs(s - last_s) > max_act_value_change * T) {
            hli = S_ERROR;
            errv = E_SENSOR_JUMP;
        } else if (s > max_pos - tolerance) {
            hli = S_ERROR;
            errv = E_RUN_OUT_MAX;
        } else if (s < min_pos + tolerance) {
            hli = S_ERROR;
            errv = E_RUN_OUT_MIN;
        }
        running = hli == S_ACTIVE_CD || hli == S_ACTIVE || hli == S_DRY_CD || hli == S_DRY_SP;
    }
    if (sensor_ok) {
        last_s = s;
        has_last_s = 1;
    } else
        s = last_s;
    /* 5. feedback, filter, error, PID */
    d = -s;
    o_prev = o;
    if (mode_cd)                                                 /* law.feedback_value */
        fb = use_both_encoders ? d + (prog + o_prev) - act : d;
    else
        fb = act - d;
    if (hli == S_ACTIVE_CD || hli == S_ACTIVE || hli == S_FREEZE || hli == S_DRY_CD || hli == S_DRY_SP) {
        if (!seeded) {
            filter_seed(cf, fs, buf, fb);
            seeded = 1;
            m_prev = mode_cd ? -fb : fb;
        }
        y = filter_step(cf, fs, buf, fb);
        if (hli == S_FREEZE)
            m_prev = mode_cd ? -y : y;                           /* no D kick when tracking resumes */
    } else {
        y = fb;
        seeded = 0;
    }
    filtered = y;
    e = 0.0;
    u = 0.0;
    tdev = 0.0;
    integral0 = ic = integral;
    if (running) {
        if (mode_cd) {                                           /* law.mode_error, CONST_DIST */
            tdev = y - sd;
            e = sd - y;
            m = -y;
        } else {                                                 /* SET_POS: the surface against SET_POS */
            tdev = y - sp;
            e = tdev - o_prev;
            m = y;
        }
        ic = integral + kp * i_gain * e;                         /* law.pid_step */
        u = kp * e + ic + dg * (m - m_prev);
        m_prev = m;
        if (!(-HUGE_MM < u && u < HUGE_MM && -HUGE_MM < ic && ic < HUGE_MM)) {   /* law.finite_step */
            u = u != u ? 0.0 : (u > HUGE_MM ? HUGE_MM : (u < -HUGE_MM ? -HUGE_MM : u));
            ic = integral0;
        }
    } else if (hli == S_TURNING_OFF) {
        e = -o_prev;
        u = -o_prev;
    }
    /* 6. slope limiter and bounds */
    hold = !(hli == S_ACTIVE_CD || hli == S_ACTIVE || hli == S_TURNING_OFF);
    v_lim = v_max * 1.0;
    a_lim = a_brake = a_base;
    if (use_adaptive_acceleration && (hli == S_ACTIVE_CD || hli == S_ACTIVE)) {      /* Fig. 31 on the remaining error e */
        double e_abs = fabs(e);
        a_lim = adaptive_acceleration(e_abs, a_min, a_base, dist_error_a_min, dist_error_a_max);
        a_brake = adaptive_braking_acceleration(e_abs, a_min, a_base, dist_error_a_min, dist_error_a_max);
    }
    if (hold) {
        u_lim = 0.0;
        e_lim = 0.0;
    } else {
        u_lim = u;
        e_lim = e;
    }
    v_prev = vel;
    v = slope_limit(u_lim, e_lim, v_prev, T, v_lim, a_lim, a_brake, w_v, w_a, &a_applied);
    lo = -max_deviation;
    hi = max_deviation;
    if (check_sw_limit_switch) {                                 /* c = p + o within swe_neg .. swe_pos */
        double lo_sw = sw_limit_min - prog, hi_sw = sw_limit_max - prog;
        if (lo_sw > lo)
            lo = lo_sw;
        if (hi_sw < hi)
            hi = hi_sw;
    }
    a_bound = a_floor;
    if (v_prev != 0.0 && a_bound_st > a_bound)
        a_bound = a_bound_st;
    a_bound_st = a_bound;
    v_limited = v;
    v = bound_velocity(v, o_prev, T, lo, hi, a_bound);
    if (v != v_limited && a_bound > a_applied)
        a_applied = a_bound;
    o_new = advance_offset(o_prev, v, T, lo, hi);
    if (!hold) {
        wanted = o_prev + u_lim;
        if (wanted > hi + LAND && hi - o_new <= LAND) {         /* 70331, or the software limit 900002 */
            hli = S_ERROR;
            errv = hi >= max_deviation - LAND ? E_MAX_DEVIATION : E_SW_LIMIT;
        } else if (wanted < lo - LAND && o_new - lo <= LAND) {
            hli = S_ERROR;
            errv = lo <= -max_deviation + LAND ? E_MAX_DEVIATION : E_SW_LIMIT;
        }
        if (hli == S_ACTIVE_CD || hli == S_ACTIVE) {            /* law.integrator_after_limiter */
            clipped = u_lim - v * T;
            integral = (fabs(clipped) <= 1e-12 || (clipped > 0.0) != (e > 0.0)) ? ic : integral0;
        }
    }
    v_real = (o_new - o_prev) * inv_T;
    vel = v_real;
    o = o_new;
    if (pend_dry) {                                              /* a DRYRUN begins once the offset stands */
        if (hli != S_FREEZE)
            pend_dry = 0;
        else if (v_real == 0.0) {
            hli = pend_dry;
            pend_dry = 0;
        }
    }
    if (hli == S_TURNING_OFF && fabs(o_new) <= LAND && fabs(v_real) <= a_applied * T) {
        o = 0.0;                                                 /* the run-out: INACTIVE, offset exactly 0 */
        if (o_prev * v > 0.0)
            vel = -o_prev * inv_T;
        o_new = 0.0;
        hli = S_INACTIVE;
        errv = 0;
        integral = 0.0;
        seeded = 0;
    }
    /* 7. outputs */
    offset = o_new;
    velocity = vel;
    target_deviation = tdev;
    wanted_step = u;
    state = hli;
    error_id = errv;
    held = hli == S_FREEZE && (freeze || held);     /* the hold is ours while the FREEZE the locks commanded lasts */
    z_offset_counts = resolution > 0.0 ? (int)lround(o_new / resolution) : 0;
    z_offset_enable = thc_enable || hli != S_INACTIVE || o_new != 0.0 || z_offset_counts != 0;
}
