/*
 * C reference of the closed-loop batch kernel (distctrl.batch.closed_loop.closed_loop).
 *
 * The same loop, operation for operation and in the same order, as the numba kernel with the law
 * functions of distctrl.control.law inlined by hand, so that the outputs are bit-for-bit equal when
 * compiled without floating-point contraction or fast math:
 *
 *     gcc -O2 -fno-fast-math -ffp-contract=off -shared -fPIC -o libclosed_loop.so closed_loop.c -lm
 *
 * Scope (what bench/bench_batch.py and tests/batch/test_c_reference.py use):
 *   - filter: MOVING_AVERAGE only (law.filter_seed / law._push / law.filter_step for that kind:
 *     ring buffer, running sum, re-sum once per window). A set with any other filter kind is not
 *     run: out_error = (-2, kind), outputs NaN.
 *   - sensor: the encoder probe only. A plant with the distance sensor (PL_SENSOR != 0, the kernel's
 *     SENSOR_DISTANCE) is not run: out_error = (-3, PL_SENSOR), outputs NaN.
 *   - modes: SET_POS, CONST_DIST with one encoder (feedback = distance) and CONST_DIST with both
 *     encoders (feedback = d + c - a) - the three feedback variants of the kernel.
 *   - everything else of the kernel: probe noise / stroke clamp / quantisation / dead time,
 *     optimized scheduling on or off, monitoring 70329 / 70330 / 70576, PID with the non-finite
 *     guard, adaptive acceleration, slope limiter with the lowering limits, max_deviation and SW
 *     limit bounds, bound_velocity / brake_velocity, advance_offset, 70331 / SW limit,
 *     anti-windup, encoder modulo; the drive with bus delay, kv loop, feed-forward, v/a limits,
 *     forward Euler and encoder quantisation.
 *
 * Inputs are the arrays the numba kernel gets: packed rows [fc (FC_LEN) | prm (Q_LEN)] from
 * closed_loop.pack_sets, the plant vector (PL_*), and prog / surface / noise per cycle. Outputs as
 * the kernel: out_offset and out_distance (n_sets x n, row-major), out_error (n_sets x 2).
 * Called through ctypes by bench/bench_batch.py (no file format in between).
 */
#include <math.h>
#include <stdint.h>

/* ---- layouts: must equal distctrl.control.law / distctrl.batch.closed_loop (checked from Python
 *      through closed_loop_layout()) */
#define MAX_N 100
#define MAX_SECTIONS 3
#define FC_KIND 0
#define FC_N 1
#define FC_INV_N 7
#define FC_SOS 8
#define FC_ZI (FC_SOS + 6 * MAX_SECTIONS)
#define FC_PRED (FC_ZI + 2 * MAX_SECTIONS + 3)   /* after Kalman gain, prior variance, EXPO factor */
#define FC_LEN (FC_PRED + MAX_N)
#define MOVING_AVERAGE 1
#define HUGE_MM 1e12
#define LAND 1e-9

enum { Q_T, Q_KP, Q_I_GAIN, Q_D_GAIN, Q_V_MAX, Q_A_BASE, Q_W_V, Q_W_A, Q_A_FLOOR,
       Q_ADAPTIVE, Q_A_MIN, Q_DEV_A_MIN, Q_DEV_A_MAX, Q_OPTIMIZED, Q_BOTH,
       Q_MAX_DEV, Q_CHECK_SW, Q_SW_MIN, Q_SW_MAX,
       Q_JUMP, Q_S_HI, Q_S_LO,
       Q_MM_PER_INCR, Q_SIGN_REV, Q_REF_OFF, Q_MODULO, Q_MIN_POS, Q_MAX_POS,
       Q_PROBE_IPM, Q_PROBE_REF, Q_LEN };
#define PACKED_LEN (FC_LEN + Q_LEN)

enum { PL_Z0, PL_ACT0, PL_KV, PL_VMAX, PL_DV, PL_BUS, PL_RES, PL_FF,
       PL_RMIN, PL_RMAX, PL_DELAY, PL_NOISE, PL_K_ON, PL_MODE, PL_SET,
       PL_RESONANT, PL_P11, PL_P12, PL_P21, PL_P22,
       PL_SENSOR, PL_K_FIRST, PL_DRES, PL_NCHAR, PL_LEN };

#define MODE_CONST_DIST 1
/* distctrl.errors.ErrorId values, passed in by the caller (closed_loop_batch's err_ids) */

/* ---- the law (distctrl.control.law), inlined by hand; same expressions, same order ---- */

/* Python's float % (numba: fmod, then the sign of the divisor) */
static inline double py_mod(double a, double span)
{
    double mod = fmod(a, span);
    if (mod != 0.0) {
        if ((span < 0.0) != (mod < 0.0))
            mod += span;
    } else {
        mod = copysign(0.0, span);
    }
    return mod;
}

static inline double encoder_reading(double increments, double mm_per_increment, int sign_reversal,
                                     double offset_mm, int modulo, double lo, double hi)
{
    double s = increments * mm_per_increment;
    if (sign_reversal)
        s = -s;
    s = s + offset_mm;
    if (modulo) {
        double span = hi - lo;
        s = lo + py_mod(s - lo, span);
    }
    return s;
}

static inline double modulo_wrap(double s, double lo, double hi)
{
    return lo + py_mod(s - lo, hi - lo);
}

static inline double modulo_unwrap(double s_wrapped, double last_wrapped, double last_unwrapped, double lo,
                                   double hi)
{
    double span = hi - lo;
    return last_unwrapped + (py_mod(s_wrapped - last_wrapped + 0.5 * span, span) - 0.5 * span);
}

static inline double brake_velocity(double remaining, double a, double T)
{
    if (remaining <= 0.0 || a <= 0.0)
        return 0.0;
    double a_t = a * T;
    if (a_t * T <= 0.0)
        return sqrt(2.0 * a * remaining);
    double q = remaining / (a_t * T);
    if (q > 1e12)
        return sqrt(2.0 * a * remaining);
    double k = sqrt(0.25 + 2.0 * q) - 0.5;
    double j = floor(k);
    double f = (q - 0.5 * j * (j + 1.0)) / (j + 1.0);
    if (f < 0.0)
        f = 0.0;
    else if (f > 1.0)
        f = 1.0;
    return a_t * (j + f);
}

static inline double adaptive_acceleration(double error_abs, double a_min, double a_max,
                                           double dev_a_min, double dev_a_max)
{
    if (error_abs <= dev_a_min)
        return a_min;
    if (error_abs >= dev_a_max)
        return a_max;
    return a_min + (a_max - a_min) * (error_abs - dev_a_min) / (dev_a_max - dev_a_min);
}

static inline double adaptive_braking_acceleration(double error_abs, double a_min, double a_max,
                                                   double dev_a_min, double dev_a_max)
{
    double a_here = adaptive_acceleration(error_abs, a_min, a_max, dev_a_min, dev_a_max);
    return a_min < a_here ? a_min : a_here;
}

static inline double band(double v_wanted, double v_prev, double v_lim, double a_t)
{
    double lo = v_prev - a_t;
    double hi = v_prev + a_t;
    if (lo < -v_lim)
        lo = -v_lim;
    if (hi > v_lim)
        hi = v_lim;
    if (lo > hi)
        return v_prev > 0.0 ? v_prev - a_t : v_prev + a_t;
    if (v_wanted < lo)
        return lo;
    if (v_wanted > hi)
        return hi;
    return v_wanted;
}

static inline double slope_limit(double u, double e, double v_prev, double T, double v_lim,
                                 double a_lim, double a_brake, double w_v, double w_a)
{
    double v_lim_down = v_lim * w_v, a_lim_down = a_lim * w_a;
    double v_wanted = u * (1.0 / T);
    double vb = sqrt(2.0 * a_brake * fabs(e));
    double v = band((-vb <= v_wanted && v_wanted <= vb) ? v_wanted : (v_wanted > 0.0 ? vb : -vb),
                    v_prev, v_lim, a_lim * T);
    if (v >= 0.0 || (v_lim_down == v_lim && a_lim_down == a_lim))
        return v;
    vb = sqrt(2.0 * (a_brake * w_a) * fabs(e));
    v = band((-vb <= v_wanted && v_wanted <= vb) ? v_wanted : (v_wanted > 0.0 ? vb : -vb),
             v_prev, v_lim_down, a_lim_down * T);
    if (v <= 0.0)
        return v;
    return 0.0;           /* both branches of the law return velocity 0 here */
}

static inline double bound_velocity(double v, double o, double T, double lo, double hi, double a_floor)
{
    if (a_floor <= 0.0)
        return ((v > 0.0 && o < hi) || (v < 0.0 && o > lo)) ? 0.0 : v;
    if (v > 0.0) {
        double room = hi - o;
        if (room < (v * v / (2.0 * a_floor) + 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300) {
            double v_hi = brake_velocity(room, a_floor, T);
            if (v > v_hi)
                v = v_hi;
        }
    } else if (v < 0.0) {
        double room = o - lo;
        if (room < (v * v / (2.0 * a_floor) - 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300) {
            double v_lo = -brake_velocity(room, a_floor, T);
            if (v < v_lo)
                v = v_lo;
        }
    }
    return v;
}

static inline double advance_offset(double o, double v, double T, double lo, double hi)
{
    double o_new = o + v * T;
    if (o_new > hi)
        o_new = o <= hi ? hi : (v <= 0.0 ? o_new : o);
    if (o_new < lo)
        o_new = o >= lo ? lo : (v >= 0.0 ? o_new : o);
    return o_new;
}

static inline double integrator_after_limiter(double integral, double i_candidate, double u, double v,
                                              double e, double T)
{
    double clipped = u - v * T;
    if (fabs(clipped) <= 1e-12 || (clipped > 0.0) != (e > 0.0))
        return i_candidate;
    return integral;
}

/* ---- one parameter set (closed_loop.closed_loop) ---- */

static void fill_nan(double *a, double *b, int64_t from, int64_t n)
{
    for (int64_t j = from; j < n; j++) {
        a[j] = NAN;
        b[j] = NAN;
    }
}

static void closed_loop_one(const double *fc, const double *prm, const double *plant, const double *prog,
                            const double *surface, const double *noise, int64_t n, double *out_offset,
                            double *out_distance, int64_t *out_error, const int64_t *err_ids)
{
    const int64_t E_JUMP = err_ids[0], E_RUN_MAX = err_ids[1], E_RUN_MIN = err_ids[2],
                  E_MAX_DEV = err_ids[3], E_SW = err_ids[4];
    out_error[0] = -1;
    out_error[1] = 0;
    int kind = (int)fc[FC_KIND];
    int nf = (int)fc[FC_N];
    if (kind != MOVING_AVERAGE || nf < 1 || nf > MAX_N) {
        out_error[0] = -2;
        out_error[1] = kind;
        fill_nan(out_offset, out_distance, 0, n);
        return;
    }
    if (plant[PL_SENSOR] != 0.0) {
        out_error[0] = -3;
        out_error[1] = (int64_t)plant[PL_SENSOR];
        fill_nan(out_offset, out_distance, 0, n);
        return;
    }
    const double T = prm[Q_T], kp = prm[Q_KP], i_gain = prm[Q_I_GAIN], d_gain = prm[Q_D_GAIN];
    const double v_max = prm[Q_V_MAX], a_base = prm[Q_A_BASE], w_v = prm[Q_W_V], w_a = prm[Q_W_A];
    const double a_floor = prm[Q_A_FLOOR];
    const int adaptive = prm[Q_ADAPTIVE] != 0.0;
    const double a_min = prm[Q_A_MIN], dev_a_min = prm[Q_DEV_A_MIN], dev_a_max = prm[Q_DEV_A_MAX];
    const int optimized = prm[Q_OPTIMIZED] != 0.0;
    const int both = prm[Q_BOTH] != 0.0;
    const double max_dev = prm[Q_MAX_DEV];
    const int check_sw = prm[Q_CHECK_SW] != 0.0;
    const double sw_min = prm[Q_SW_MIN], sw_max = prm[Q_SW_MAX];
    const double jump_limit = prm[Q_JUMP], s_hi = prm[Q_S_HI], s_lo = prm[Q_S_LO];
    const double mm_per_incr = prm[Q_MM_PER_INCR];
    const int sign_rev = prm[Q_SIGN_REV] != 0.0;
    const double ref_off = prm[Q_REF_OFF];
    const int modulo = prm[Q_MODULO] != 0.0;
    const double min_pos = prm[Q_MIN_POS], max_pos = prm[Q_MAX_POS];
    const double probe_ipm = prm[Q_PROBE_IPM], probe_ref = prm[Q_PROBE_REF];

    double z_pos = plant[PL_Z0];
    double z_act = plant[PL_ACT0];
    double z_vel = 0.0;
    const double kv = plant[PL_KV], dr_vmax = plant[PL_VMAX], dr_dv = plant[PL_DV];
    const int nbus = (int)plant[PL_BUS];
    const double res = plant[PL_RES], ff = plant[PL_FF];
    const double r_min = plant[PL_RMIN], r_max = plant[PL_RMAX];
    const int ndel = (int)plant[PL_DELAY];
    const int has_noise = plant[PL_NOISE] != 0.0;
    const int64_t k_on = (int64_t)plant[PL_K_ON];
    const int const_dist = (int)plant[PL_MODE] == MODE_CONST_DIST;
    const double set_value = plant[PL_SET];
    /* the drive's mechanical resonance (physics.resonance_step): the probe sees the nozzle */
    const int resonant = plant[PL_RESONANT] != 0.0;
    const double p11 = plant[PL_P11], p12 = plant[PL_P12], p21 = plant[PL_P21], p22 = plant[PL_P22];
    double z_noz = z_pos, defl = 0.0, defl_rate = 0.0;

    double ring_static[64];
    double dline_static[64];
    double *ring = ring_static, *dline = dline_static;
    if (nbus + 1 > 64 || ndel > 64) {       /* the benchmark's plants are far below this */
        out_error[0] = -3;
        out_error[1] = 0;
        fill_nan(out_offset, out_distance, 0, n);
        return;
    }
    for (int j = 0; j < nbus + 1; j++)
        ring[j] = z_pos;
    int ring_w = 0;
    double prev_sp = z_pos;
    int dline_i = 0;
    /* the moving average's state: ring index, running sum (law fs[FS_IDX], fs[FS_TOTAL]) */
    double buf[MAX_N];
    int f_idx = 0;
    double f_total = 0.0;

    double o = 0.0, vel = 0.0, integral = 0.0, m_prev = 0.0;
    int need_seed = 1;
    double a_bound_state = a_floor;
    double s_delayed = 0.0, last_s = 0.0;
    int has_last_s = 0;
    double s_wrapped = 0.0, s_unwrapped = 0.0; /* modulo encoder */
    for (int64_t k = 0; k < n; k++) {
        /* ---- probe (EncoderProbe.read) */
        double sz = surface[k];
        double z = z_noz;
        out_distance[k] = z - sz;
        double x = -1.0 * (z - sz);
        if (has_noise)
            x += noise[k];
        if (x < r_min)
            x = r_min;
        else if (x > r_max)
            x = r_max;
        double y = floor((x - probe_ref) * probe_ipm + 0.5);
        if (ndel > 0) {
            if (k == 0)
                for (int j = 0; j < ndel; j++)
                    dline[j] = y;
            double yo = dline[dline_i];
            dline[dline_i] = y;
            dline_i = dline_i + 1 < ndel ? dline_i + 1 : 0;
            y = yo;
        }
        /* ---- cycle core (AxisDistanceController.update) */
        double pr = prog[k];
        double act = z_act;
        double s_now = encoder_reading(y, mm_per_incr, sign_rev, ref_off, modulo, min_pos, max_pos);
        if (modulo) { /* AxisDistanceController._unwrap */
            s_unwrapped = k > 0 ? modulo_unwrap(s_now, s_wrapped, s_unwrapped, min_pos, max_pos) : s_now;
            s_wrapped = s_now;
            s_now = s_unwrapped;
        }
        double s;
        if (optimized) {
            s = s_now;
        } else {
            s = k == 0 ? s_now : s_delayed;
            s_delayed = s_now;
        }
        int running = k >= k_on;
        int64_t err_id = 0;
        if (running) {
            double s_window = modulo ? modulo_wrap(s, min_pos, max_pos) : s;
            if (has_last_s && fabs(s - last_s) > jump_limit)
                err_id = E_JUMP;
            else if (s_window > s_hi)
                err_id = E_RUN_MAX;
            else if (s_window < s_lo)
                err_id = E_RUN_MIN;
        }
        if (err_id != 0) {
            out_error[0] = k;
            out_error[1] = err_id;
            fill_nan(out_offset, out_distance, k, n);
            return;
        }
        last_s = s;
        has_last_s = 1;
        double d = -s;
        /* law.feedback_value: a - d (SET_POS), d (CONST_DIST), d + c - a (CONST_DIST, both encoders) */
        double feedback = !const_dist ? act - d : (both ? d + (pr + o) - act : d);
        double target_dev = 0.0, e = 0.0, u = 0.0, i_cand = integral;
        if (running) {
            if (need_seed) {
                /* law.filter_seed, MOVING_AVERAGE */
                for (int i = 0; i < nf; i++)
                    buf[i] = feedback;
                f_idx = 0;
                f_total = feedback * nf;
                need_seed = 0;
                m_prev = const_dist ? -feedback : feedback;
            }
            /* law.filter_step -> law._push, MOVING_AVERAGE */
            double old = buf[f_idx];
            buf[f_idx] = feedback;
            double total = f_total + feedback - old;
            f_idx += 1;
            if (f_idx >= nf) {
                f_idx = 0;
                total = 0.0;                 /* law._ring_sum */
                for (int i = 0; i < nf; i++)
                    total += buf[i];
            }
            f_total = total;
            double filtered = f_total * fc[FC_INV_N];   /* law.moving_mean */
            double m;
            if (!const_dist) {
                target_dev = filtered - set_value;
                e = target_dev - o;
                m = filtered;
            } else {
                target_dev = filtered - set_value;
                e = set_value - filtered;
                m = -filtered;
            }
            /* law.pid_step */
            i_cand = integral + kp * i_gain * e;
            u = kp * e + i_cand + d_gain * (m - m_prev);
            m_prev = m;
            if (!(-HUGE_MM < u && u < HUGE_MM) || !(-HUGE_MM < i_cand && i_cand < HUGE_MM)) {
                if (u != u)
                    u = 0.0;
                else
                    u = u > HUGE_MM ? HUGE_MM : (u < -HUGE_MM ? -HUGE_MM : u);
                i_cand = integral;
            }
        }
        double v_lim = v_max * 1.0;
        double a_lim = a_base, a_brake = a_base;
        if (adaptive && running) {
            a_lim = adaptive_acceleration(fabs(e), a_min, a_base, dev_a_min, dev_a_max);
            a_brake = adaptive_braking_acceleration(fabs(e), a_min, a_base, dev_a_min, dev_a_max);
        }
        double u_lim, e_lim;
        if (running) {
            u_lim = u;
            e_lim = e;
        } else {
            u_lim = 0.0;
            e_lim = 0.0;
        }
        double v = slope_limit(u_lim, e_lim, vel, T, v_lim, a_lim, a_brake, w_v, w_a);
        double lo = -max_dev, hi = max_dev;
        if (check_sw) {
            double lo_sw = sw_min - pr;
            if (lo_sw > lo)
                lo = lo_sw;
            double hi_sw = sw_max - pr;
            if (hi_sw < hi)
                hi = hi_sw;
        }
        double a_bound;
        if (vel == 0.0)
            a_bound = a_floor;
        else
            a_bound = a_bound_state > a_floor ? a_bound_state : a_floor;
        a_bound_state = a_bound;
        v = bound_velocity(v, o, T, lo, hi, a_bound);
        double o_new = advance_offset(o, v, T, lo, hi);
        if (running) {
            double wanted = o + u_lim;
            if (wanted > hi + LAND && hi - o_new <= LAND)
                err_id = hi >= max_dev - LAND ? E_MAX_DEV : E_SW;
            else if (wanted < lo - LAND && o_new - lo <= LAND)
                err_id = lo <= -max_dev + LAND ? E_MAX_DEV : E_SW;
            if (err_id != 0) {
                out_error[0] = k;
                out_error[1] = err_id;
                fill_nan(out_offset, out_distance, k, n);
                return;
            }
            integral = integrator_after_limiter(integral, i_cand, u_lim, v, e, T);
        }
        vel = (o_new - o) * (1.0 / T);
        o = o_new;
        out_offset[k] = o_new;
        double cmd = pr + o_new + 0.0;
        /* ---- drive (Drive.step) */
        ring[ring_w] = cmd;
        ring_w = ring_w < nbus ? ring_w + 1 : 0;
        double c = ring[ring_w];
        double dv = kv * (c - z_act);
        if (ff != 0.0)
            dv += ff * (c - prev_sp) * (1.0 / T);
        prev_sp = c;
        if (dv > dr_vmax)
            dv = dr_vmax;
        else if (dv < -dr_vmax)
            dv = -dr_vmax;
        if (dv > z_vel + dr_dv)
            dv = z_vel + dr_dv;
        else if (dv < z_vel - dr_dv)
            dv = z_vel - dr_dv;
        z_pos = z_pos + dv * T;
        if (resonant) {
            double de = defl_rate - (dv - z_vel);
            double e = defl;
            defl = p11 * e + p12 * de;
            defl_rate = p21 * e + p22 * de;
            z_noz = z_pos + defl;
        } else {
            z_noz = z_pos;
        }
        z_vel = dv;
        z_act = res != 0.0 ? floor(z_pos * (1.0 / res) + 0.5) * res : z_pos;
    }
}

/* ---- entry points (ctypes) ---- */

/* layout[0..4] = FC_LEN, Q_LEN, PL_LEN, MAX_N, PACKED_LEN: the Python side checks them */
void closed_loop_layout(int64_t *layout)
{
    layout[0] = FC_LEN;
    layout[1] = Q_LEN;
    layout[2] = PL_LEN;
    layout[3] = MAX_N;
    layout[4] = PACKED_LEN;
}

/* Sets [first, first + count) of the batch, one after the other (one core). err_ids: the ErrorId
 * values of SENSOR_JUMP, SENSOR_RUN_OUT_MAX, SENSOR_RUN_OUT_MIN, MAX_DEVIATION, SW_LIMIT. */
void closed_loop_batch(int64_t first, int64_t count, const double *packed, const double *plant,
                       const double *prog, const double *surface, const double *noise, int64_t n,
                       double *out_offset, double *out_distance, int64_t *out_error, const int64_t *err_ids)
{
    for (int64_t i = first; i < first + count; i++) {
        const double *row = packed + i * PACKED_LEN;
        closed_loop_one(row, row + FC_LEN, plant, prog, surface, noise, n, out_offset + i * n,
                        out_distance + i * n, out_error + 2 * i, err_ids);
    }
}
