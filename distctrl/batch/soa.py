"""The closed loop for a block of MOVING_AVERAGE parameter sets at once, vectorised across the sets.

:func:`distctrl.batch.closed_loop.closed_loop` runs one parameter set after the other. Each of its
cycles is a serial chain of divisions and square roots, so one set leaves most of a core idle
(about 21 M set-cycles/s). :func:`block_loop` runs ``BLOCK`` sets side by side, cycle by cycle,
with every per-set quantity in a row of one work array (structure of arrays). Each step of the
cycle is then a short loop over the sets, which LLVM compiles to AVX-512 (or AVX2) instructions,
8 (or 4) sets per instruction. :func:`distctrl.batch.closed_loop.run_batch` uses it for every
set it can take; docs/batch.md has the figures.

It is the same loop and gives the same numbers bit for bit (tests/batch/test_soa.py):

* the same law functions (``law.*``) compute every value, lane by lane;
* the same order of operations, with no fast math and no FMA contraction;
* what is rare or branchy leaves the vector loops and runs per set through the complete law
  function:
  - the lowering pass of the slope limiter (``law.slope_limit_side`` says whether it is needed);
  - braking near an offset bound (``law.near_bound`` decides, then ``law.bound_velocity`` runs);
  - seeding the filter (``law.filter_seed``);
  - the re-sum of a moving-average window when it wraps (``law._ring_sum``);
  - the adaptive acceleration (``law.adaptive_acceleration``) and the drive's velocity
    feed-forward, when a lane or the plant uses them;
  - the drive's mechanical resonance (``physics.resonance_step``): its own copy of the drive loop,
    chosen once per block, so the rigid drive's loop stays as it was;
  - monitoring errors.

Which sets it takes (:func:`soa_eligible`): filter MOVING_AVERAGE, no modulo encoder. The lanes of
one block may have different window lengths (they share one ring, see :func:`block_loop`);
:func:`plan_blocks` fills whole blocks with sets of one length first, whose ring bookkeeping and
re-sum are vector operations. The other sets go through ``closed_loop``.

The traces leave through an 8-cycle buffer per lane, a 64-byte line of a row at a time, with
non-temporal stores (:mod:`distctrl.batch.stream`; ordinary stores when the output rows are not
contiguous).

Restrictions, as for ``closed_loop`` (see there): the axis variant, the probe or the point distance
sensor, no events. A set
that raises a controller error stops at that cycle: its outputs are NaN from the error cycle on,
and ``out_error`` holds (cycle, id). Its lane keeps computing; the NaN are written over its row
from the error cycle on when the block is done.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..control import law
from ..sim import physics
from .jitcache import cached
from .layout import (PL_ACT0, PL_Z0, Q_A_BASE, Q_A_FLOOR, Q_A_MIN, Q_ADAPTIVE, Q_BOTH, Q_CHECK_SW, Q_D_GAIN,
                     Q_DEV_A_MAX, Q_DEV_A_MIN, Q_I_GAIN, Q_JUMP, Q_KP, Q_LEN, Q_MAX_DEV, Q_MAX_POS, Q_MIN_POS,
                     Q_MM_PER_INCR, Q_MODULO, Q_OPTIMIZED, Q_PROBE_IPM, Q_PROBE_REF, Q_REF_OFF, Q_S_HI,
                     Q_S_LO, Q_SIGN_REV, Q_SW_MAX, Q_SW_MIN, Q_T, Q_V_MAX, Q_W_A, Q_W_V, _E_JUMP, _E_RUN_MAX,
                     _E_RUN_MIN, _E_MAX_DEV, _E_SW, plant_constants, resonance_constants, sensor_constants)
from .stream import store_fence, store_stream

__all__ = ["BLOCK", "soa_eligible", "plan_blocks", "block_loop"]

#: sets per block (lanes): the work array (about 70 rows of BLOCK float64) stays in L1
BLOCK = 32

_FC = law.FC_LEN
_LAND = 1e-9                     # as controller._LAND

# rows of the work array: state, per-cycle values handed between the loops, then the Q_* parameters.
# Every access in the vector loops is W[<constant row>, b]: one allocation with constant row
# offsets, so LLVM needs no run-time alias checks (with them it refuses to vectorise). Whatever is
# indexed per lane or per cycle (the rings, the output buffer) is copied in and out by short loops.
(Z_POS, Z_ACT, Z_VEL, PREV_SP, OFS, VEL, INTEG, M_PREV, INV_2A, S_DELAYED, LAST_S, TOTAL, BOTH_ENC,
 Y_OLD, Y_NEW, OLD, FEEDBACK, CMD, C_IN, DIST, ERR_SENSOR, ERR_BOUND, U_LIM, E_LIM, I_CAND, V, V_LIM, A_LIM,
 LO, HI, LOWER, FLAG, A_BRAKE, C_USE, DV_FF, Z_NOZ, DEFL, DEFL_RATE, N_ROWS) = range(39)
_INV_N = N_ROWS                  # W[_INV_N, b]: 1/n of the lane's window
_P = N_ROWS + 1                  # W[_P + Q_*, b]: the set's parameters


def soa_eligible(packed: np.ndarray) -> np.ndarray:
    """Boolean per packed row: can :func:`block_loop` run it (MOVING_AVERAGE, no modulo encoder)?"""
    kind = packed[:, law.FC_KIND]
    modulo = packed[:, _FC + Q_MODULO]
    return (kind == law.MOVING_AVERAGE) & (modulo == 0.0)


def kernel_order(packed: np.ndarray) -> np.ndarray:
    """An order of packed rows that runs fastest when the rows go to the kernel a few hundred at a time
    (a sweep's blocks): the rows of :func:`block_loop` first, by window length, then the others, each group in
    its order. :func:`plan_blocks` fills lanes of ``BLOCK`` rows of one window length where it can; a block of
    256 random sets held about 50 such rows, in two lanes of mixed lengths, partly empty. Every row runs on its
    own, so the results per row do not depend on the order."""
    if not len(packed):
        return np.zeros(0, dtype=np.int64)
    lane = soa_eligible(packed)
    return np.lexsort((np.where(lane, packed[:, law.FC_N], 0.0), ~lane))      # stable: the rest in order


def plan_blocks(packed: np.ndarray, block: int = BLOCK) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split the rows into blocks for :func:`block_loop` and the rest for ``closed_loop``.

    Returns ``(lanes, counts, rest)``: ``lanes[j]`` the row indices of block j (``block`` of
    them; a partial last block repeats its last row, which is computed but not written),
    ``counts[j]`` how many of them are real, ``rest`` the rows that ``closed_loop`` runs. The
    rows of one window length fill whole blocks first; the remainders of all lengths, sorted by
    length, share the last blocks (so their shared ring is short).
    """
    ok = soa_eligible(packed)
    rows = np.flatnonzero(ok).astype(np.int64)
    rest = np.flatnonzero(~ok).astype(np.int64)
    rows = rows[np.argsort(packed[rows, law.FC_N], kind="stable")]
    # whole blocks of one window length first (their ring bookkeeping and re-sum are vector
    # operations), then what is left of every length, still sorted, in mixed blocks
    n_of = packed[rows, law.FC_N]
    full, left = [], []
    for n_value in np.unique(n_of):
        same = rows[n_of == n_value]
        cut = len(same) - len(same) % block
        full.append(same[:cut])
        left.append(same[cut:])
    if len(rows):
        rows = np.concatenate(full + left)
    lanes, counts = [], []
    for a in range(0, len(rows), block):
        part = rows[a:a + block]
        lane = np.empty(block, dtype=np.int64)
        lane[:len(part)] = part
        lane[len(part):] = part[-1]
        lanes.append(lane)
        counts.append(len(part))
    if lanes:
        return np.stack(lanes), np.asarray(counts, dtype=np.int64), rest
    return np.zeros((0, block), dtype=np.int64), np.zeros(0, dtype=np.int64), rest


@cached
@njit(cache=True, nogil=True, error_model="numpy")
def block_loop(packed, lanes, count, plant, prog, surface, noise, out_offset, out_distance, out_error):
    """The closed loop of the rows ``lanes[:count]`` of ``packed`` (MOVING_AVERAGE, no modulo
    encoder; ``len(lanes) == BLOCK``), written to their rows of the outputs.

    Same arguments and outputs as ``closed_loop`` otherwise: ``plant``, ``prog``, ``surface``,
    ``noise`` of the scenario; ``out_offset`` / ``out_distance`` (n_sets, n), ``out_error``
    (n_sets, 2).

    The moving-average windows of all lanes share one ring of ``max(n)`` rows: push q of every lane
    goes to row q mod max(n), and lane b's oldest value is the row n_b pushes back. Summing a lane's
    last n_b values oldest first is what ``law._push`` re-sums when its own ring wraps.
    """
    n = out_offset.shape[1]
    B = BLOCK
    # == B, but not a compile-time constant: LLVM would unroll a B-long copy between two arrays
    # into scalar moves (it cannot prove they do not overlap); with a run-time count it vectorises
    # the copy behind one overlap check
    n_lanes = lanes.shape[0]
    # the scenario's plant and select (the same for every lane)
    z0 = plant[PL_Z0]
    kv, dr_vmax, dr_dv, nbus, res, ff, r_min, r_max, ndel, has_noise, k_on, const_dist, set_value = \
        plant_constants(plant)
    resonant, p11, p12, p21, p22 = resonance_constants(plant)
    distance, k_first, dres, char_x, char_y = sensor_constants(plant)
    T = packed[lanes[0], _FC + Q_T]
    inv_T = 1.0 / T
    inv_res = 1.0 / res if res != 0.0 else 0.0

    W = np.zeros((_P + Q_LEN, B))
    n_win = np.empty(B, dtype=np.int64)
    ring_len = 1
    for b in range(B):
        i = lanes[b]
        for j in range(Q_LEN):
            W[_P + j, b] = packed[i, _FC + j]
        W[Z_POS, b] = z0
        W[Z_NOZ, b] = z0
        W[Z_ACT, b] = plant[PL_ACT0]
        W[PREV_SP, b] = z0
        a_floor = packed[i, _FC + Q_A_FLOOR]
        W[INV_2A, b] = 0.5 / a_floor if a_floor > 0.0 else 0.0
        W[A_LIM, b] = packed[i, _FC + Q_A_BASE]      # (set per cycle only where adaptive)
        W[A_BRAKE, b] = packed[i, _FC + Q_A_BASE]
        n_win[b] = int(packed[i, law.FC_N])
        # both encoders (P-AXIS-00500): the feedback is d + c - a (law.feedback_value)
        W[BOTH_ENC, b] = 1.0 if packed[i, _FC + Q_BOTH] != 0.0 else 0.0
        W[_INV_N, b] = packed[i, law.FC_INV_N]
        if n_win[b] > ring_len:
            ring_len = n_win[b]
    uniform = True                               # one window length for all lanes
    any_adaptive = False
    for b in range(B):
        uniform = uniform and n_win[b] == n_win[0]
        any_adaptive = any_adaptive or W[_P + Q_ADAPTIVE, b] != 0.0
    ring = np.empty((nbus + 1, B))               # Drive.setpoint_history, full of the start position
    for j in range(nbus + 1):
        for b in range(B):
            ring[j, b] = z0
    dline = np.empty((ndel if ndel > 0 else 1, B))   # the probe's dead time
    window = np.zeros((ring_len, B))             # the moving-average windows (shared ring)
    to_wrap = np.zeros(B, dtype=np.int64)        # per lane: pushes until law._push would re-sum
    death = np.full(B, n, dtype=np.int64)        # per lane: the error cycle (n: none)
    fs = np.zeros(law.FS_LEN)
    scratch = np.zeros(law.MAX_N)
    for b in range(count):
        out_error[lanes[b], 0] = -1
        out_error[lanes[b], 1] = 0
    # the traces: the last 8 cycles of every lane are kept, and a lane's 64-byte line of a trace row
    # is streamed to memory when it is complete (distctrl.batch.stream). grp_*[r, :cnt_*[r]]: the
    # lanes whose line ends in a cycle k with k % 8 == r (where their row lies in the cache lines)
    buf_o = np.empty((8, B))
    buf_d = np.empty((8, B))
    stream = (out_offset.strides[1] == 8 and out_distance.strides[1] == 8
              and out_offset.ctypes.data % 8 == 0 and out_distance.ctypes.data % 8 == 0)
    grp_o, cnt_o, tail_o = _line_groups(out_offset, lanes, count)
    grp_d, cnt_d, tail_d = _line_groups(out_distance, lanes, count)

    ring_w = 0
    dline_i = 0
    win_row = 0
    for k in range(n):
        sz = surface[k]
        pr = prog[k]
        nz = noise[k] if has_noise else 0.0
        running = k >= k_on
        first = k == 0
        push = running and k > k_on             # the seed cycle pushes after seeding (below)
        if push:                                # (k - k_on) % ring_len without a division
            win_row = win_row + 1 if win_row + 1 < ring_len else 0
        # ---- rows indexed per cycle or per lane: copied in
        if ndel > 0 and not first:
            for b in range(n_lanes):
                W[Y_OLD, b] = dline[dline_i, b]
        nxt = ring_w + 1 if ring_w < nbus else 0
        for b in range(n_lanes):
            W[C_IN, b] = ring[nxt, b]
        if push:
            # the value leaving lane b's window was pushed n_b pushes ago: ring row win_row - n_b
            if uniform:                         # one window length: one row, a vector copy
                r = win_row - n_win[0]
                if r < 0:
                    r += ring_len
                for b in range(n_lanes):
                    W[OLD, b] = window[r, b]
            else:
                for b in range(B):              # a gather
                    r = win_row - n_win[b]
                    if r < 0:
                        r += ring_len
                    W[OLD, b] = window[r, b]

        # ---- sensor, encoder reading, monitoring, feedback, the window sum (update() 1-4)
        if push:                                # every cycle after the seed: constant flags
            if distance:
                n_err = _sensor_lanes(W, sz, pr, nz, r_min, r_max, has_noise, ndel > 0, False, True, True,
                                      const_dist, True, char_x, char_y, dres)
            else:
                n_err = _sensor_lanes(W, sz, pr, nz, r_min, r_max, has_noise, ndel > 0, False, True, True,
                                      const_dist, False, char_x, char_y, dres)
        else:                                   # k <= k_first: no earlier reading (the first cycle,
            n_err = _sensor_lanes(W, sz, pr, nz, r_min, r_max, has_noise, ndel > 0 and not first,
                                  k <= k_first, running, push, const_dist, distance, char_x, char_y, dres)
        if ndel > 0:
            for b in range(n_lanes):
                dline[dline_i, b] = W[Y_NEW, b]
            if first:
                for j in range(1, ndel):
                    for b in range(B):
                        dline[j, b] = W[Y_NEW, b]
            dline_i = dline_i + 1 if dline_i + 1 < ndel else 0

        # ---- the filter's bookkeeping (law.filter_seed, law._push's ring and re-sum)
        if running:
            if k == k_on:
                for b in range(B):
                    fb = W[FEEDBACK, b]
                    law.filter_seed(packed[lanes[b], :_FC], fs, scratch, fb)
                    for j in range(ring_len):
                        window[j, b] = fb         # the seed fills the window
                    W[TOTAL, b] = law.window_sum_update(fs[law.FS_TOTAL], fb, fb)   # push 0: x0 leaves
                    W[M_PREV, b] = -fb if const_dist else fb
                    to_wrap[b] = n_win[b]
            for b in range(n_lanes):
                window[win_row, b] = W[FEEDBACK, b]
            if uniform:                           # all lanes wrap in the same cycle
                c = to_wrap[0] - 1
                if c == 0:                        # law._ring_sum of every lane, oldest first
                    nb = n_win[0]
                    r = win_row + 1 - nb
                    if r < 0:
                        r += ring_len
                    for b in range(B):
                        W[TOTAL, b] = 0.0
                    for j in range(nb):
                        for b in range(B):
                            W[TOTAL, b] += window[r, b]
                        r = r + 1 if r + 1 < ring_len else 0
                    c = nb
                to_wrap[0] = c
            else:                                 # count down in a vector loop, re-sum the few
                n_wrap = 0
                for b in range(B):
                    c = to_wrap[b] - 1
                    n_wrap += 1 if c == 0 else 0
                    to_wrap[b] = c
                if n_wrap:
                    for b in range(B):
                        if to_wrap[b] == 0:
                            W[TOTAL, b] = _window_sum(window, b, win_row, n_win[b], scratch)
                            to_wrap[b] = n_win[b]

        # ---- PID, slope limiter (first pass), bounds: the law, lane by lane (update() 5-6)
        # (short loops: their iterations are independent, so more of them overlap in the core)
        if running:
            for b in range(B):
                o = W[OFS, b]
                integral = W[INTEG, b]
                filtered = law.moving_mean(W[TOTAL, b], W[_INV_N, b])
                _target_dev, e, m = law.mode_error(const_dist, filtered, set_value, o)
                u, i_cand = law.pid_step(W[_P + Q_KP, b], W[_P + Q_I_GAIN, b], W[_P + Q_D_GAIN, b], integral,
                                         W[M_PREV, b], e, m)
                W[M_PREV, b] = m
                u, i_cand = law.finite_step(u, i_cand, integral)
                W[U_LIM, b] = u
                W[E_LIM, b] = e
                W[I_CAND, b] = i_cand
        else:
            for b in range(B):
                W[U_LIM, b] = 0.0
                W[E_LIM, b] = 0.0
                W[I_CAND, b] = W[INTEG, b]
        if any_adaptive:                      # else A_LIM and A_BRAKE hold a_base from the start
            for b in range(B):
                W[A_LIM, b] = W[_P + Q_A_BASE, b]
                W[A_BRAKE, b] = W[_P + Q_A_BASE, b]
        if running and any_adaptive:          # its own loop: the division only where needed
            for b in range(B):
                if W[_P + Q_ADAPTIVE, b] != 0.0:
                    e_abs = abs(W[E_LIM, b])
                    W[A_LIM, b] = law.adaptive_acceleration(e_abs, W[_P + Q_A_MIN, b], W[_P + Q_A_BASE, b],
                                                            W[_P + Q_DEV_A_MIN, b], W[_P + Q_DEV_A_MAX, b])
                    W[A_BRAKE, b] = law.adaptive_braking_acceleration(e_abs, W[_P + Q_A_MIN, b],
                                                                      W[_P + Q_A_BASE, b], W[_P + Q_DEV_A_MIN, b],
                                                                      W[_P + Q_DEV_A_MAX, b])
        n_flag = 0
        for b in range(B):
            o = W[OFS, b]
            u = W[U_LIM, b]
            e = W[E_LIM, b]
            v_lim = W[_P + Q_V_MAX, b] * 1.0
            a_lim = W[A_LIM, b]
            vel = W[VEL, b]
            v, lower = law.slope_limit_side(u, e, vel, T, v_lim, a_lim, W[A_BRAKE, b], v_lim * W[_P + Q_W_V, b],
                                            a_lim * W[_P + Q_W_A, b])
            max_dev = W[_P + Q_MAX_DEV, b]
            lo = -max_dev
            hi = max_dev
            if W[_P + Q_CHECK_SW, b] != 0.0:
                lo_sw = W[_P + Q_SW_MIN, b] - pr
                if lo_sw > lo:
                    lo = lo_sw
                hi_sw = W[_P + Q_SW_MAX, b] - pr
                if hi_sw < hi:
                    hi = hi_sw
            # the bounds brake with a_floor: the controller's a_bound is a_floor or max(a_floor,
            # a_bound), which stays a_floor while the parameters do not change (they do not here)
            flag = lower or law.near_bound(v, o, T, lo, hi, W[_P + Q_A_FLOOR, b], W[INV_2A, b])
            n_flag += 1 if flag else 0
            W[FLAG, b] = 1.0 if flag else 0.0
            W[LOWER, b] = 1.0 if lower else 0.0
            W[V, b] = v
            W[V_LIM, b] = v_lim
            W[LO, b] = lo
            W[HI, b] = hi
        if n_flag:
            for b in range(B):                # the lowering pass / braking near a bound: the full law
                if W[FLAG, b] != 0.0:
                    v = W[V, b]
                    if W[LOWER, b] != 0.0:
                        v_lim = W[V_LIM, b]
                        a_lim = W[A_LIM, b]
                        v = law.slope_limit(W[U_LIM, b], W[E_LIM, b], W[VEL, b], T, v_lim, a_lim, W[A_BRAKE, b],
                                            W[_P + Q_W_V, b], W[_P + Q_W_A, b])[0]
                    W[V, b] = law.bound_velocity(v, W[OFS, b], T, W[LO, b], W[HI, b], W[_P + Q_A_FLOOR, b])

        # ---- the offset, 70331 / SW limit, anti-windup, then the drive (Drive.step)
        n_bound = 0
        for b in range(B):
            o = W[OFS, b]
            v = W[V, b]
            lo = W[LO, b]
            hi = W[HI, b]
            o_new = law.advance_offset(o, v, T, lo, hi)
            err = 0.0
            if running:
                wanted = o + W[U_LIM, b]
                max_dev = W[_P + Q_MAX_DEV, b]
                if wanted > hi + _LAND and hi - o_new <= _LAND:
                    err = _E_MAX_DEV if hi >= max_dev - _LAND else _E_SW
                elif wanted < lo - _LAND and o_new - lo <= _LAND:
                    err = _E_MAX_DEV if lo <= -max_dev + _LAND else _E_SW
                W[INTEG, b] = law.integrator_after_limiter(W[INTEG, b], W[I_CAND, b], W[U_LIM, b], v,
                                                           W[E_LIM, b], T)
            W[ERR_BOUND, b] = err
            n_bound += 1 if err != 0.0 else 0
            W[VEL, b] = (o_new - o) * inv_T
            W[OFS, b] = o_new
            cmd = pr + o_new + 0.0
            W[CMD, b] = cmd
            W[C_USE, b] = cmd if nbus == 0 else W[C_IN, b]
        if ff != 0.0:                          # velocity feed-forward: its own loop (a division)
            for b in range(B):
                W[DV_FF, b] = ff * (W[C_USE, b] - W[PREV_SP, b]) * inv_T
        if resonant:                           # the nozzle: motor + the mode's deflection
            for b in range(B):
                c = W[C_USE, b]
                z_act = W[Z_ACT, b]
                dv = kv * (c - z_act)
                if ff != 0.0:
                    dv += W[DV_FF, b]
                W[PREV_SP, b] = c
                dv = physics.limit_velocity(dv, dr_vmax, W[Z_VEL, b], dr_dv)
                z_pos = W[Z_POS, b] + dv * T
                W[Z_POS, b] = z_pos
                e, de = physics.resonance_step(W[DEFL, b], W[DEFL_RATE, b], dv - W[Z_VEL, b], p11, p12, p21, p22)
                W[DEFL, b] = e
                W[DEFL_RATE, b] = de
                W[Z_NOZ, b] = z_pos + e
                W[Z_VEL, b] = dv
                W[Z_ACT, b] = physics.quantise(z_pos, res, inv_res) if res != 0.0 else z_pos
        else:                                  # rigid: the nozzle is the motor
            for b in range(B):
                c = W[C_USE, b]
                z_act = W[Z_ACT, b]
                dv = kv * (c - z_act)
                if ff != 0.0:
                    dv += W[DV_FF, b]
                W[PREV_SP, b] = c
                dv = physics.limit_velocity(dv, dr_vmax, W[Z_VEL, b], dr_dv)
                z_pos = W[Z_POS, b] + dv * T
                W[Z_POS, b] = z_pos
                W[Z_NOZ, b] = z_pos
                W[Z_VEL, b] = dv
                W[Z_ACT, b] = physics.quantise(z_pos, res, inv_res) if res != 0.0 else z_pos
        for b in range(n_lanes):
            ring[ring_w, b] = W[CMD, b]
        ring_w = nxt

        # ---- errors, outputs
        if n_err or n_bound:
            for b in range(count):
                if death[b] == n and (W[ERR_SENSOR, b] != 0.0 or W[ERR_BOUND, b] != 0.0):
                    i = lanes[b]
                    death[b] = k
                    out_error[i, 0] = k
                    out_error[i, 1] = int(W[ERR_SENSOR, b] if W[ERR_SENSOR, b] != 0.0 else W[ERR_BOUND, b])
        if stream:
            kk = k % 8
            for b in range(n_lanes):
                buf_o[kk, b] = W[OFS, b]
                buf_d[kk, b] = W[DIST, b]
            _stream_lines(out_offset, buf_o, lanes, grp_o[kk], cnt_o[kk], k)
            _stream_lines(out_distance, buf_d, lanes, grp_d[kk], cnt_d[kk], k)
        else:
            for b in range(count):
                i = lanes[b]
                out_offset[i, k] = W[OFS, b]
                out_distance[i, k] = W[DIST, b]
    if stream:                                 # the rows' last, partial lines: ordinary stores
        _write_tails(out_offset, buf_o, lanes, count, tail_o)
        _write_tails(out_distance, buf_d, lanes, count, tail_d)
        store_fence()
    for b in range(count):                     # a set that ran into an error: NaN from that cycle
        i = lanes[b]
        for j in range(death[b], n):
            out_offset[i, j] = np.nan
            out_distance[i, j] = np.nan


@cached
@njit(cache=True, nogil=True, error_model="numpy")
def _line_groups(out, lanes, count):
    """Where the lanes' rows of ``out`` lie in 64-byte lines: ``(group, counts, tail)``, with
    ``group[r, :counts[r]]`` the lanes whose line ends in a cycle k with k % 8 == r and ``tail[b]``
    the elements of lane b's last, partial line (rows of ``out.shape[1]`` doubles)."""
    group = np.zeros((8, BLOCK), dtype=np.int64)
    counts = np.zeros(8, dtype=np.int64)
    tail = np.zeros(BLOCK, dtype=np.int64)
    n = out.shape[1]
    for b in range(count):
        place = ((out.ctypes.data + lanes[b] * out.strides[0]) // 8) % 8    # column 0's place in its line
        r = (7 - place) % 8
        group[r, counts[r]] = b
        counts[r] += 1
        tail[b] = (place + n) % 8
    return group, counts, tail


@njit(nogil=True, error_model="numpy", inline="always")
def _write_tails(out, buf, lanes, count, tail):
    """The rows' last, partial lines from ``buf`` (the last 8 cycles), with ordinary stores."""
    n = out.shape[1]
    for b in range(count):
        i = lanes[b]
        for j in range(max(0, n - tail[b]), n):
            out[i, j] = buf[j % 8, b]


@njit(nogil=True, error_model="numpy", inline="always")
def _stream_lines(out, buf, lanes, group, count, k):
    """Write the trace line that ends in cycle k of each lane in ``group[:count]`` from ``buf``
    (the last 8 cycles, row k % 8): streamed when it is a whole line, the row's first, partial line
    (k < 7) with ordinary stores."""
    for g in range(count):
        b = group[g]
        i = lanes[b]
        if k >= 7:
            for j in range(k - 7, k + 1):
                store_stream(out, i, j, buf[j % 8, b])
        else:
            for j in range(k + 1):
                out[i, j] = buf[j % 8, b]


@njit(nogil=True, error_model="numpy", inline="always")
def _sensor_lanes(W, sz, pr, nz, r_min, r_max, has_noise, delayed, first, running, push, const_dist,
                  distance, char_x, char_y, dres):
    """update() 1-4 for every lane: the sensor's reading of the distance (``distance``: the point
    distance sensor through its variable, in mm; else the probe's increments; ``delayed``: the dead
    time's older reading is used), the encoder reading, the sensor monitoring (while ``running``;
    ``first``: no earlier reading), the feedback (``pr``: the programmed position) and the window sum
    (``push``). Returns the number of lanes with a sensor error.
    Inlined: called with constant flags, its tests vanish from the vector loop."""
    n_err = 0
    for b in range(BLOCK):
        z = W[Z_NOZ, b]                        # the sensor sees the nozzle (= the motor when rigid)
        W[DIST, b] = z - sz
        if distance:                           # DistanceSensor.read
            x = 1.0 * (z - sz)
            if has_noise:
                x += nz
            y = physics.distance_reading(x, r_max, char_x, char_y, dres)
        else:                                  # EncoderProbe.read
            x = -1.0 * (z - sz)
            if has_noise:
                x += nz
            y = physics.probe_increments(x, r_min, r_max, W[_P + Q_PROBE_REF, b], W[_P + Q_PROBE_IPM, b])
        W[Y_NEW, b] = y
        if delayed:
            y = W[Y_OLD, b]
        if distance:                           # SENSOR_SOURCE=VARIABLE: d in mm (no REF, no modulo here)
            s_now = -y + 0.0
        else:
            s_now = law.encoder_reading(y, W[_P + Q_MM_PER_INCR, b], W[_P + Q_SIGN_REV, b] != 0.0,
                                        W[_P + Q_REF_OFF, b], False, W[_P + Q_MIN_POS, b], W[_P + Q_MAX_POS, b])
        if W[_P + Q_OPTIMIZED, b] != 0.0 or first:
            s = s_now                          # no earlier reading
        else:
            s = W[S_DELAYED, b]
        W[S_DELAYED, b] = s_now
        err = 0.0
        if running:
            if not first and abs(s - W[LAST_S, b]) > W[_P + Q_JUMP, b]:
                err = _E_JUMP
            elif s > W[_P + Q_S_HI, b]:
                err = _E_RUN_MAX
            elif s < W[_P + Q_S_LO, b]:
                err = _E_RUN_MIN
        W[ERR_SENSOR, b] = err
        n_err += 1 if err != 0.0 else 0
        W[LAST_S, b] = s
        d = -s
        fb = law.feedback_value(const_dist, W[BOTH_ENC, b] != 0.0, d, W[Z_ACT, b], pr + W[OFS, b])
        W[FEEDBACK, b] = fb
        if push:
            W[TOTAL, b] = law.window_sum_update(W[TOTAL, b], fb, W[OLD, b])
    return n_err


@njit(nogil=True, error_model="numpy", inline="always")
def _window_sum(window, b, newest_row, nb, scratch):
    """law._ring_sum of lane b's last nb values, oldest first (what law._push re-sums on a wrap)."""
    ring_len = window.shape[0]
    r = newest_row + 1 - nb
    if r < 0:
        r += ring_len
    for j in range(nb):                       # no % per value: an integer division is slow
        scratch[j] = window[r, b]
        r = r + 1 if r + 1 < ring_len else 0
    return law._ring_sum(scratch, nb)
