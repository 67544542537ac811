/*
 * SIMD anchor of the closed-loop batch kernel (issue 27): the law of closed_loop.c, vectorised
 * across parameter sets on a structure-of-arrays layout, as distctrl.batch.soa runs it in numba.
 *
 * closed_loop.c runs one set after the other: each cycle is a serial chain of divisions and square
 * roots, which leaves most of a core's vector units idle. Here LANES sets run side by side, cycle
 * by cycle; every per-set quantity is a row of LANES doubles, and each step of the cycle is a loop
 * over the lanes that gcc -O3 -march=native turns into vector instructions (the law's branches are
 * short selects it if-converts). The operations and their order are those of closed_loop.c (the
 * same inline functions: this file includes it), so compiled without contraction and fast math
 *
 *     gcc -O3 -march=native -fno-fast-math -ffp-contract=off -fno-math-errno -fno-trapping-math -shared -fPIC \
 *         -o libclosed_loop_simd.so closed_loop_simd.c -lm
 *
 * the outputs are bit for bit those of closed_loop.c and of the numba kernel
 * (tests/batch/test_c_simd.py). -fno-math-errno only lets sqrt and floor compile to their vector
 * instructions (both correctly rounded either way).
 *
 * The rare paths (adaptive acceleration, the slope limiter's lowering pass, braking near a bound) run
 * for a block of lanes only when one of its lanes needs them: a test over the lanes (`any`), then the
 * selects for all lanes, as a C programmer would write it (distctrl.batch.soa tests per lane and runs the
 * rare path per set); a lane that does not need a path gets the same value either way.
 *
 * Scope: as closed_loop.c (MOVING_AVERAGE, the encoder probe), without a modulo encoder. A block
 * with a set outside it runs its sets through closed_loop_one. A set that raises a controller error
 * keeps computing in its lane; its outputs are NaN from the error cycle on, written when the block
 * is done (as distctrl.batch.soa does).
 */
#include "closed_loop.c"

#define LANES 8

/* ---- the law's branchy functions as selects (every candidate computed, one chosen; & and | of the
 *      comparisons, not && and ||), so that gcc if-converts the lane loop; each candidate is the
 *      expression of closed_loop.c, in its order ---- */

static inline double brake_velocity_sel(double remaining, double a, double T)
{
    double a_t = a * T;
    double direct = sqrt(2.0 * a * remaining);
    double q = remaining / (a_t * T);
    double k = sqrt(0.25 + 2.0 * q) - 0.5;
    double j = floor(k);
    double f = (q - 0.5 * j * (j + 1.0)) / (j + 1.0);
    f = f < 0.0 ? 0.0 : (f > 1.0 ? 1.0 : f);
    double stepped = a_t * (j + f);
    double r = (a_t * T <= 0.0 | q > 1e12) ? direct : stepped;
    return (remaining <= 0.0 | a <= 0.0) ? 0.0 : r;
}

static inline double adaptive_acceleration_sel(double error_abs, double a_min, double a_max,
                                               double dev_a_min, double dev_a_max)
{
    double mid = a_min + (a_max - a_min) * (error_abs - dev_a_min) / (dev_a_max - dev_a_min);
    double upper = error_abs >= dev_a_max ? a_max : mid;
    return error_abs <= dev_a_min ? a_min : upper;
}

static inline double band_sel(double v_wanted, double v_prev, double v_lim, double a_t)
{
    double lo = v_prev - a_t;
    double hi = v_prev + a_t;
    lo = lo < -v_lim ? -v_lim : lo;
    hi = hi > v_lim ? v_lim : hi;
    double r = v_wanted < lo ? lo : (v_wanted > hi ? hi : v_wanted);
    double stuck = v_prev > 0.0 ? v_prev - a_t : v_prev + a_t;
    return lo > hi ? stuck : r;
}

/* law.slope_limit as selects, in two passes, so that a block skips the lowering pass (a second square root and band)
 * when none of its lanes needs it: the first pass, and whether the lowering pass decides the result ... */
static inline double slope_first(double u, double e, double v_prev, double T, double v_lim, double a_lim,
                                 double a_brake, double w_v, double w_a, int64_t *down)
{
    double v_lim_down = v_lim * w_v, a_lim_down = a_lim * w_a;
    double v_wanted = u * (1.0 / T);
    double vb = sqrt(2.0 * a_brake * fabs(e));
    double v = band_sel((-vb <= v_wanted & v_wanted <= vb) ? v_wanted : (v_wanted > 0.0 ? vb : -vb),
                        v_prev, v_lim, a_lim * T);
    *down = !(v >= 0.0 | (v_lim_down == v_lim & a_lim_down == a_lim));
    return v;
}

/* ... and the lowering pass (the result where *down) */
static inline double slope_down(double u, double e, double v_prev, double T, double v_lim, double a_lim,
                                double a_brake, double w_v, double w_a)
{
    double v_lim_down = v_lim * w_v, a_lim_down = a_lim * w_a;
    double v_wanted = u * (1.0 / T);
    double vb2 = sqrt(2.0 * (a_brake * w_a) * fabs(e));
    double v2 = band_sel((-vb2 <= v_wanted & v_wanted <= vb2) ? v_wanted : (v_wanted > 0.0 ? vb2 : -vb2),
                         v_prev, v_lim_down, a_lim_down * T);
    return v2 <= 0.0 ? v2 : 0.0;
}

static inline double bound_velocity_sel(double v, double o, double T, double lo, double hi, double a_floor)
{
    double no_floor = ((v > 0.0 & o < hi) | (v < 0.0 & o > lo)) ? 0.0 : v;
    double room_hi = hi - o;
    double thr_hi = (v * v / (2.0 * a_floor) + 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300;
    double v_hi = brake_velocity_sel(room_hi, a_floor, T);
    double up = (room_hi < thr_hi & v > v_hi) ? v_hi : v;
    double room_lo = o - lo;
    double thr_lo = (v * v / (2.0 * a_floor) - 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300;
    double v_lo = -brake_velocity_sel(room_lo, a_floor, T);
    double dn = (room_lo < thr_lo & v < v_lo) ? v_lo : v;
    double r = v > 0.0 ? up : (v < 0.0 ? dn : v);
    return a_floor <= 0.0 ? no_floor : r;
}

/* whether bound_velocity_sel can return anything but v: braking near a bound (or no floor) */
static inline int64_t bound_needed(double v, double o, double T, double lo, double hi, double a_floor)
{
    double thr_hi = (v * v / (2.0 * a_floor) + 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300;
    double thr_lo = (v * v / (2.0 * a_floor) - 0.5 * v * T + 0.125 * a_floor * T * T) * (1.0 + 1e-12) + 1e-300;
    return (a_floor <= 0.0) | (v > 0.0 & hi - o < thr_hi) | (v < 0.0 & o - lo < thr_lo);
}

static inline double advance_offset_sel(double o, double v, double T, double lo, double hi)
{
    double o_new = o + v * T;
    o_new = o_new > hi ? (o <= hi ? hi : (v <= 0.0 ? o_new : o)) : o_new;
    o_new = o_new < lo ? (o >= lo ? lo : (v >= 0.0 ? o_new : o)) : o_new;
    return o_new;
}

/* The moving-average windows: ring[b][i] of lane b (LANES x MAX_N), index and running sum per lane. */
typedef struct {
    double buf[LANES][MAX_N];
} rings_t;

static void block_simd(const int64_t *rows, int nl, const double *packed, const double *plant,
                       const double *prog, const double *surface, const double *noise, int64_t n,
                       double *out_offset, double *out_distance, int64_t *out_error, const int64_t *err_ids)
{
    const int64_t E_JUMP = err_ids[0], E_RUN_MAX = err_ids[1], E_RUN_MIN = err_ids[2],
                  E_MAX_DEV = err_ids[3], E_SW = err_ids[4];
    /* per-lane parameters (a missing lane repeats the last set; it is computed, never written) */
    double T_[LANES], kp[LANES], i_gain[LANES], d_gain[LANES], v_max[LANES], a_base[LANES], w_v[LANES],
        w_a[LANES], a_floor[LANES], a_min[LANES], dev_a_min[LANES], dev_a_max[LANES], max_dev[LANES],
        sw_min[LANES], sw_max[LANES], jump_limit[LANES], s_hi[LANES], s_lo[LANES], mm_per_incr[LANES],
        ref_off[LANES], probe_ipm[LANES], probe_ref[LANES], inv_n[LANES];
    int64_t adaptive[LANES], optimized[LANES], both[LANES], check_sw[LANES], sign_rev[LANES];
    int nf[LANES];
    const double *row[LANES];
    for (int b = 0; b < LANES; b++) {
        const double *r = packed + rows[b < nl ? b : nl - 1] * PACKED_LEN;
        const double *prm = r + FC_LEN;
        row[b] = r;
        T_[b] = prm[Q_T]; kp[b] = prm[Q_KP]; i_gain[b] = prm[Q_I_GAIN]; d_gain[b] = prm[Q_D_GAIN];
        v_max[b] = prm[Q_V_MAX]; a_base[b] = prm[Q_A_BASE]; w_v[b] = prm[Q_W_V]; w_a[b] = prm[Q_W_A];
        a_floor[b] = prm[Q_A_FLOOR]; adaptive[b] = prm[Q_ADAPTIVE] != 0.0; a_min[b] = prm[Q_A_MIN];
        dev_a_min[b] = prm[Q_DEV_A_MIN]; dev_a_max[b] = prm[Q_DEV_A_MAX];
        optimized[b] = prm[Q_OPTIMIZED] != 0.0; both[b] = prm[Q_BOTH] != 0.0; max_dev[b] = prm[Q_MAX_DEV];
        check_sw[b] = prm[Q_CHECK_SW] != 0.0; sw_min[b] = prm[Q_SW_MIN]; sw_max[b] = prm[Q_SW_MAX];
        jump_limit[b] = prm[Q_JUMP]; s_hi[b] = prm[Q_S_HI]; s_lo[b] = prm[Q_S_LO];
        mm_per_incr[b] = prm[Q_MM_PER_INCR]; sign_rev[b] = prm[Q_SIGN_REV] != 0.0; ref_off[b] = prm[Q_REF_OFF];
        probe_ipm[b] = prm[Q_PROBE_IPM]; probe_ref[b] = prm[Q_PROBE_REF];
        nf[b] = (int)r[FC_N];
        inv_n[b] = r[FC_INV_N];
    }
    /* the plant: the same for all lanes */
    const double kv = plant[PL_KV], dr_vmax = plant[PL_VMAX], dr_dv = plant[PL_DV];
    const int nbus = (int)plant[PL_BUS];
    const double res = plant[PL_RES], ff = plant[PL_FF];
    const double r_min = plant[PL_RMIN], r_max = plant[PL_RMAX];
    const int ndel = (int)plant[PL_DELAY];
    const int has_noise = plant[PL_NOISE] != 0.0;
    const int64_t k_on = (int64_t)plant[PL_K_ON];
    const int64_t const_dist = (int)plant[PL_MODE] == MODE_CONST_DIST;
    const double set_value = plant[PL_SET];
    const int resonant = plant[PL_RESONANT] != 0.0;
    const double p11 = plant[PL_P11], p12 = plant[PL_P12], p21 = plant[PL_P21], p22 = plant[PL_P22];

    /* lane state */
    double z_pos[LANES], z_act[LANES], z_vel[LANES], z_noz[LANES], defl[LANES], defl_rate[LANES];
    double prev_sp[LANES], o[LANES], vel[LANES], integral[LANES], m_prev[LANES], a_bound_state[LANES];
    double s_delayed[LANES], last_s[LANES], f_total[LANES];
    double y[LANES], fb[LANES];
    int f_idx[LANES], resum[LANES];
    int64_t err_k[LANES], err_id[LANES], run_l[LANES], adapt_l[LANES], leid[LANES], ldown[LANES];
    double le[LANES], lu[LANES], lic[LANES], la[LANES], lab[LANES], lv[LANES], llo[LANES], lhi[LANES];
    double ring[64][LANES], dline[64][LANES];
    rings_t rg;                        /* on the stack (a thread-local copy is not 64-byte aligned) */
    for (int b = 0; b < LANES; b++) {
        z_pos[b] = plant[PL_Z0];
        z_act[b] = plant[PL_ACT0];
        z_vel[b] = 0.0;
        z_noz[b] = z_pos[b];
        defl[b] = defl_rate[b] = 0.0;
        prev_sp[b] = z_pos[b];
        o[b] = vel[b] = integral[b] = m_prev[b] = 0.0;
        a_bound_state[b] = a_floor[b];
        s_delayed[b] = last_s[b] = 0.0;
        f_total[b] = 0.0;
        f_idx[b] = 0;
        err_k[b] = -1;
        err_id[b] = 0;
    }
    for (int j = 0; j < nbus + 1; j++)
        for (int b = 0; b < LANES; b++)
            ring[j][b] = plant[PL_Z0];
    int ring_w = 0, dline_i = 0;

    for (int64_t k = 0; k < n; k++) {
        const double sz = surface[k], pr = prog[k], nz = has_noise ? noise[k] : 0.0;
        const int64_t running = k >= k_on;
        /* ---- probe (EncoderProbe.read), cycle core up to the feedback */
        for (int b = 0; b < LANES; b++) {
            double z = z_noz[b];
            double x = -1.0 * (z - sz);
            if (has_noise)
                x += nz;
            x = x < r_min ? r_min : (x > r_max ? r_max : x);
            y[b] = floor((x - probe_ref[b]) * probe_ipm[b] + 0.5);
        }
        for (int b = 0; b < nl; b++)
            out_distance[rows[b] * n + k] = z_noz[b] - sz;
        if (ndel > 0) {
            if (k == 0)
                for (int j = 0; j < ndel; j++)
                    for (int b = 0; b < LANES; b++)
                        dline[j][b] = y[b];
            for (int b = 0; b < LANES; b++) {
                double yo = dline[dline_i][b];
                dline[dline_i][b] = y[b];
                y[b] = yo;
            }
            dline_i = dline_i + 1 < ndel ? dline_i + 1 : 0;
        }
        for (int b = 0; b < LANES; b++) {
            double act = z_act[b];
            double s_now = y[b] * mm_per_incr[b];        /* encoder_reading without modulo */
            s_now = sign_rev[b] ? -s_now : s_now;
            s_now = s_now + ref_off[b];
            double s = optimized[b] ? s_now : (k == 0 ? s_now : s_delayed[b]);
            s_delayed[b] = optimized[b] ? s_delayed[b] : s_now;
            int64_t eid = 0;
            if (running) {
                eid = (k > 0 && fabs(s - last_s[b]) > jump_limit[b]) ? E_JUMP
                    : (s > s_hi[b] ? E_RUN_MAX : (s < s_lo[b] ? E_RUN_MIN : 0));
            }
            if (eid != 0 && err_k[b] < 0) {
                err_k[b] = k;
                err_id[b] = eid;
            }
            last_s[b] = s;
            double d = -s;
            fb[b] = !const_dist ? act - d : (both[b] ? d + (pr + o[b]) - act : d);
        }
        if (running) {
            if (k == k_on) {                    /* law.filter_seed, MOVING_AVERAGE */
                for (int b = 0; b < LANES; b++) {
                    for (int i = 0; i < nf[b]; i++)
                        rg.buf[b][i] = fb[b];
                    f_idx[b] = 0;
                    f_total[b] = fb[b] * nf[b];
                    m_prev[b] = const_dist ? -fb[b] : fb[b];
                }
            }
            int any_resum = 0;
            for (int b = 0; b < LANES; b++) {    /* law._push, MOVING_AVERAGE */
                double old = rg.buf[b][f_idx[b]];
                rg.buf[b][f_idx[b]] = fb[b];
                f_total[b] = f_total[b] + fb[b] - old;
                f_idx[b] += 1;
                resum[b] = f_idx[b] >= nf[b];
                any_resum |= resum[b];
            }
            if (any_resum)
                for (int b = 0; b < LANES; b++)
                    if (resum[b]) {
                        double total = 0.0;     /* law._ring_sum */
                        for (int i = 0; i < nf[b]; i++)
                            total += rg.buf[b][i];
                        f_total[b] = total;
                        f_idx[b] = 0;
                    }
        }
        /* ---- the law from the filtered value on: short lane loops (each if-converted and vectorised;
         *      gcc gives up on one loop with all of it), every value computed, `running` selects */
        for (int b = 0; b < LANES; b++) {        /* lane masks: gcc does not vectorise a select on a scalar */
            run_l[b] = running;
            adapt_l[b] = adaptive[b] & running;
        }
        for (int b = 0; b < LANES; b++) {        /* law.pid_step with the non-finite guard */
            const int64_t run = run_l[b];
            double filtered = f_total[b] * inv_n[b];
            double target_dev = filtered - set_value;
            double e_r = !const_dist ? target_dev - o[b] : set_value - filtered;
            double m = !const_dist ? filtered : -filtered;
            double i_r = integral[b] + kp[b] * i_gain[b] * e_r;
            double u_r = kp[b] * e_r + i_r + d_gain[b] * (m - m_prev[b]);
            int64_t bad = !(-HUGE_MM < u_r & u_r < HUGE_MM) | !(-HUGE_MM < i_r & i_r < HUGE_MM);
            double u_clip = u_r > HUGE_MM ? HUGE_MM : (u_r < -HUGE_MM ? -HUGE_MM : u_r);
            double u_fix = u_r != u_r ? 0.0 : u_clip;
            u_r = bad ? u_fix : u_r;
            i_r = bad ? integral[b] : i_r;
            le[b] = run ? e_r : 0.0;
            lu[b] = run ? u_r : 0.0;
            lic[b] = run ? i_r : integral[b];
            m_prev[b] = run ? m : m_prev[b];
        }
        /* the rare paths run for a block only when one of its lanes needs them (an `any` over the lanes, as
         * a C programmer writes it; the other lanes take the same values as without the test) */
        int64_t any_adapt = 0;
        for (int b = 0; b < LANES; b++)
            any_adapt |= adapt_l[b];
        if (any_adapt) {
            for (int b = 0; b < LANES; b++) {    /* adaptive acceleration */
                double a_here = adaptive_acceleration_sel(fabs(le[b]), a_min[b], a_base[b], dev_a_min[b],
                                                          dev_a_max[b]);
                double a_brk = a_min[b] < a_here ? a_min[b] : a_here;
                la[b] = adapt_l[b] ? a_here : a_base[b];
                lab[b] = adapt_l[b] ? a_brk : a_base[b];
            }
        } else {
            for (int b = 0; b < LANES; b++)
                la[b] = lab[b] = a_base[b];
        }
        int64_t any_down = 0;
        for (int b = 0; b < LANES; b++) {        /* law.slope_limit (u_lim, e_lim: 0 before the select) */
            lv[b] = slope_first(lu[b], le[b], vel[b], T_[b], v_max[b] * 1.0, la[b], lab[b], w_v[b], w_a[b],
                                &ldown[b]);
            any_down |= ldown[b];
        }
        if (any_down)                            /* its lowering pass */
            for (int b = 0; b < LANES; b++) {
                double dn = slope_down(lu[b], le[b], vel[b], T_[b], v_max[b] * 1.0, la[b], lab[b], w_v[b], w_a[b]);
                lv[b] = ldown[b] ? dn : lv[b];
            }
        int64_t any_bound = 0;
        for (int b = 0; b < LANES; b++) {        /* the offset's bounds, law.bound_velocity */
            double lo = -max_dev[b], hi = max_dev[b];
            double lo_sw = sw_min[b] - pr, hi_sw = sw_max[b] - pr;
            lo = (check_sw[b] & lo_sw > lo) ? lo_sw : lo;
            hi = (check_sw[b] & hi_sw < hi) ? hi_sw : hi;
            double a_keep = a_bound_state[b] > a_floor[b] ? a_bound_state[b] : a_floor[b];
            double a_bound = vel[b] == 0.0 ? a_floor[b] : a_keep;
            a_bound_state[b] = a_bound;
            llo[b] = lo;
            lhi[b] = hi;
            any_bound |= bound_needed(lv[b], o[b], T_[b], lo, hi, a_bound);
        }
        if (any_bound)                           /* braking near a bound */
            for (int b = 0; b < LANES; b++)
                lv[b] = bound_velocity_sel(lv[b], o[b], T_[b], llo[b], lhi[b], a_bound_state[b]);
        for (int b = 0; b < LANES; b++) {        /* law.advance_offset, 70331 / SW limit, anti-windup */
            const double T = T_[b];
            double v = lv[b], lo = llo[b], hi = lhi[b];
            double o_new = advance_offset_sel(o[b], v, T, lo, hi);
            double wanted = o[b] + lu[b];
            int64_t over = wanted > hi + LAND & hi - o_new <= LAND;
            int64_t under = wanted < lo - LAND & o_new - lo <= LAND;
            int64_t id_hi = hi >= max_dev[b] - LAND ? E_MAX_DEV : E_SW;
            int64_t id_lo = lo <= -max_dev[b] + LAND ? E_MAX_DEV : E_SW;
            leid[b] = over ? id_hi : (under ? id_lo : 0);
            double clipped = lu[b] - v * T;                  /* law.integrator_after_limiter */
            double i_new = (fabs(clipped) <= 1e-12 | (clipped > 0.0) != (le[b] > 0.0)) ? lic[b] : integral[b];
            integral[b] = run_l[b] ? i_new : integral[b];
            vel[b] = (o_new - o[b]) * (1.0 / T);
            o[b] = o_new;
        }
        for (int b = 0; b < LANES; b++) {        /* the first controller error of a lane */
            int64_t first_err = (leid[b] != 0) & (err_k[b] < 0) & (run_l[b] != 0);
            err_k[b] = first_err ? k : err_k[b];
            err_id[b] = first_err ? leid[b] : err_id[b];
        }
        for (int b = 0; b < nl; b++)
            out_offset[rows[b] * n + k] = o[b];
        /* ---- drive (Drive.step) */
        for (int b = 0; b < LANES; b++)
            ring[ring_w][b] = pr + o[b] + 0.0;
        ring_w = ring_w < nbus ? ring_w + 1 : 0;
        for (int b = 0; b < LANES; b++) {
            const double T = T_[b];
            double c = ring[ring_w][b];
            double dv = kv * (c - z_act[b]);
            if (ff != 0.0)
                dv += ff * (c - prev_sp[b]) * (1.0 / T);
            prev_sp[b] = c;
            dv = dv > dr_vmax ? dr_vmax : (dv < -dr_vmax ? -dr_vmax : dv);
            dv = dv > z_vel[b] + dr_dv ? z_vel[b] + dr_dv : (dv < z_vel[b] - dr_dv ? z_vel[b] - dr_dv : dv);
            z_pos[b] = z_pos[b] + dv * T;
            if (resonant) {
                double de = defl_rate[b] - (dv - z_vel[b]);
                double e0 = defl[b];
                defl[b] = p11 * e0 + p12 * de;
                defl_rate[b] = p21 * e0 + p22 * de;
                z_noz[b] = z_pos[b] + defl[b];
            } else {
                z_noz[b] = z_pos[b];
            }
            z_vel[b] = dv;
            z_act[b] = res != 0.0 ? floor(z_pos[b] * (1.0 / res) + 0.5) * res : z_pos[b];
        }
    }
    (void)row;
    for (int b = 0; b < nl; b++) {
        int64_t i = rows[b];
        out_error[2 * i] = err_k[b];
        out_error[2 * i + 1] = err_id[b];
        if (err_k[b] >= 0)
            fill_nan(out_offset + i * n, out_distance + i * n, err_k[b], n);
    }
}

static int simd_eligible(const double *r, const double *plant)
{
    const double *prm = r + FC_LEN;
    int nf = (int)r[FC_N];
    return (int)r[FC_KIND] == MOVING_AVERAGE && nf >= 1 && nf <= MAX_N && prm[Q_MODULO] == 0.0
           && plant[PL_SENSOR] == 0.0 && (int)plant[PL_BUS] + 1 <= 64 && (int)plant[PL_DELAY] <= 64;
}

/* Sets [first, first + count), LANES at a time (one core); the same arguments as closed_loop_batch. */
void closed_loop_simd_batch(int64_t first, int64_t count, const double *packed, const double *plant,
                            const double *prog, const double *surface, const double *noise, int64_t n,
                            double *out_offset, double *out_distance, int64_t *out_error, const int64_t *err_ids)
{
    for (int64_t i0 = first; i0 < first + count; i0 += LANES) {
        int nl = (int)(first + count - i0 < LANES ? first + count - i0 : LANES);
        int64_t rows[LANES];
        int ok = 1;
        for (int b = 0; b < nl; b++) {
            rows[b] = i0 + b;
            ok &= simd_eligible(packed + rows[b] * PACKED_LEN, plant);
        }
        if (ok) {
            block_simd(rows, nl, packed, plant, prog, surface, noise, n, out_offset, out_distance, out_error,
                       err_ids);
        } else {
            for (int b = 0; b < nl; b++) {
                const double *r = packed + rows[b] * PACKED_LEN;
                closed_loop_one(r, r + FC_LEN, plant, prog, surface, noise, n, out_offset + rows[b] * n,
                                out_distance + rows[b] * n, out_error + 2 * rows[b], err_ids);
            }
        }
    }
}
