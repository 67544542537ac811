component distctrl_thc "distctrl's distance-control law as a torch height control in the servo thread (docs/linuxcnc.md)";
description """
The CONST_DIST loop of distctrl's control law (distctrl/control/law.py: filter, PID with derivative on the
measurement and anti-windup, slope limiter with braking, max_deviation bound), translated operation for
operation into C so that its outputs equal the Python law's bit for bit (tests/linuxcnc/test_thc.py checks
it in halrun for every filter type). The arc voltage is linearised into the distance as distctrl's PLC does
(distance = (arc-voltage-in - arc-v0) / arc-k). Pins are named like plasmac's where they mean the same.

States (state-out): 0 idle (thc-enable off: the law does not run, the offset stays, or returns to 0 with
offset-reset), 1 active, 2 locked
(corner lock or void lock: the wanted step is 0, the offset brakes within the acceleration limit and
stays, the integrator holds). Entering active seeds the filter with the current distance (no jump).
Corner lock: current-velocity below cornerlock-threshold percent of requested-velocity. Void lock:
distctrl's void_lock function (distctrl/plc/process/void_lock.py, its ST): the arc voltage's rate over a
window of voidlock-window s above voidlock-slope for voidlock-on-cycles periods closes it; steady for
voidlock-off-cycles periods with the window's mean at most voidlock-release-band above the level before
the void opens it; the window starts afresh whenever thc-enable comes on.

The filter coefficients fc-000..fc-134 are the law's coefficient buffer (distctrl.control.filters.
design_coefficients; the low-pass is designed with scipy there): `distctrl linuxcnc thc-config` prints
them as setp lines, validated with the documents' ranges.
""";
pin in float arc_voltage_in "arc voltage (V)";
pin in float arc_v0 = 95.0 "linearisation: voltage at zero height (V)";
pin in float arc_k = 6.0 "linearisation: V per mm";
pin in bit thc_enable "run the law (active)";
pin in bit offset_reset "while idle: the offset returns to 0 (motion's external-offset planner smooths the step; e.g. at the cut's end)";
pin in bit use_both_encoders "P-AXIS-00500: feedback d + c - a (FCT-M3 §7.1) instead of d";
pin in float axis_z_position "a: the Z joint's actual position (joint.N.pos-fb)";
pin in float axis_z_command "c: the Z joint's commanded position (joint.N.motor-pos-cmd)";
pin in bit cornerlock_enable "enable corner lock";
pin in float cornerlock_threshold = 90.0 "corner lock below this percentage of requested-velocity";
pin in float current_velocity "current path velocity (units/s), motion.current-vel";
pin in float requested_velocity "requested path velocity (units/s)";
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
pin in float max_deviation = 20.0 "bound of the offset (mm), P-AXIS-00414";
pin in float resolution = 0.001 "mm per offset count (wire plasmac.offset-scale to it; 0: no counts)";
pin in float fc-###[135] "the law's filter coefficients (design_coefficients)";
pin out s32 z_offset_counts "offset in counts, connect to axis.z.eoffset-counts";
pin out float offset_scale "mm per count, connect to axis.z.eoffset-scale";
pin out bit z_offset_enable "connect to axis.z.eoffset-enable";
pin out bit cornerlock_is_locked "corner locked";
pin out bit voidlock_is_locked "void locked";
pin out float offset "the offset o (mm)";
pin out float distance "the linearised distance (mm)";
pin out float filtered "the filtered distance (mm)";
pin out float velocity "the offset's velocity (mm/s)";
pin out s32 state_out "0 idle, 1 active, 2 locked";
variable double buf[100];
variable double fs[11];
variable double cf[135];
variable double integral;
variable double m_prev;
variable double v_prev;
variable double o;
variable int was_active;
variable double vbuf[100];
variable double vmean[100];
variable double vsum;
variable double vlevel;
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
    double T = fperiod, d, fb, y, e, m, u, ic, v, t_over_tn, dg, clipped;
    int i, lower, locked;
    for (i = 0; i < 135; i++)
        cf[i] = fc(i);
    offset_scale = resolution;
    z_offset_enable = thc_enable;
    d = (arc_voltage_in - arc_v0) * (1.0 / arc_k);
    distance = d;
    /* the locks (also while idle, so that they are current when the law starts) */
    if (cornerlock_enable)
        cornerlock_is_locked = current_velocity < requested_velocity * cornerlock_threshold * 0.01;
    else
        cornerlock_is_locked = 0;
    if (!voidlock_enable || !thc_enable) {
        nfill = 0;
        nmfill = 0;
        vsum = 0.0;
        voidlock_is_locked = 0;
        non = 0;
        noff = 0;
    } else {
        int N = (int)lround(voidlock_window / T), full, mfull;
        double x = arc_voltage_in, old, mean_old, mean = 0.0, rate;
        if (N < 1)
            N = 1;
        if (N > 100)
            N = 100;
        if (vi >= N)
            vi = 0;
        old = vbuf[vi];
        full = nfill >= N;
        mean_old = vmean[vi];
        mfull = nmfill >= N;
        vbuf[vi] = x;
        vsum = vsum + x - (full ? old : 0.0);
        if (!full)
            nfill += 1;
        if (nfill >= N) {
            mean = vsum / N;
            vmean[vi] = mean;
            if (nmfill < N)
                nmfill += 1;
        }
        vi = (vi + 1) % N;
        if (!full) {
            voidlock_is_locked = 0;
            non = 0;
            noff = 0;
        } else {
            rate = (x - old) / (N * T);
            if (!voidlock_is_locked) {
                if (fabs(rate) > voidlock_slope)
                    non += 1;
                else
                    non = 0;
                if (non >= voidlock_on_cycles) {
                    voidlock_is_locked = 1;
                    vlevel = mfull ? mean_old : old;
                    noff = 0;
                }
            } else {
                if (fabs(rate) <= voidlock_slope && mean - vlevel <= voidlock_release_band)
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
    if (!thc_enable) {
        was_active = 0;
        state_out = 0;
        velocity = 0.0;
        v_prev = 0.0;
        if (offset_reset)
            o = 0.0;
        offset = o;
        z_offset_counts = resolution > 0.0 ? (int)lround(o / resolution) : 0;
        return;
    }
    fb = use_both_encoders ? d + axis_z_command - axis_z_position : d;    /* law.feedback_value */
    if (!was_active) {                 /* activation: the filter starts from this sample, no jump */
        filter_seed(cf, fs, buf, fb);
        integral = 0.0;
        m_prev = -fb;
        was_active = 1;
    }
    locked = cornerlock_is_locked || voidlock_is_locked;
    y = filter_step(cf, fs, buf, fb);
    filtered = y;
    e = set_dist - y;
    m = -y;
    if (locked) {                       /* FREEZE: no wanted step, brake within the limits */
        u = 0.0;
        e = 0.0;
        ic = integral;
    } else {
        t_over_tn = i_tn > 0.0 ? T / i_tn : 0.0;
        dg = derivative_gain(kp, d_tv, T);
        ic = integral + kp * t_over_tn * e;
        u = kp * e + ic + dg * (m - m_prev);
        if (!(-HUGE_MM < u && u < HUGE_MM && -HUGE_MM < ic && ic < HUGE_MM)) {
            u = u != u ? 0.0 : (u > HUGE_MM ? HUGE_MM : (u < -HUGE_MM ? -HUGE_MM : u));
            ic = integral;
        }
    }
    v = slope_limit_side(u, e, v_prev, T, v_max, a_max, a_max, v_max, a_max, &lower);
    v = bound_velocity(v, o, T, -max_deviation, max_deviation, a_max);
    o = advance_offset(o, v, T, -max_deviation, max_deviation);
    clipped = u - v * T;
    if (!locked && (fabs(clipped) <= 1e-12 || (clipped > 0.0) != (e > 0.0)))
        integral = ic;
    m_prev = m;
    v_prev = v;
    velocity = v;
    offset = o;
    z_offset_counts = resolution > 0.0 ? (int)lround(o / resolution) : 0;
    state_out = locked ? 2 : 1;
}
