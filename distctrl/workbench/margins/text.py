"""The margins as text: what ``distctrl margins`` prints (:func:`format_text`).

Part of :mod:`distctrl.workbench.margins` (docs/margins.md); the package face re-exports every name.
"""
from __future__ import annotations

import math
from .model import KP_RANGE, KP_SEARCH_MAX, MAX_CROSSINGS_SHOWN


def _cycles(n: int) -> str:
    return f"{n} cycle" if n == 1 else f"{n} cycles"


def _hz(f: float | None) -> str:
    return "-" if f is None else f"{f:.2f} Hz"


def format_text(res) -> str:
    """The margins of ``res`` (a :class:`~distctrl.workbench.margins.result.MarginResult`, which this module does
    not import: the result imports it) as the text ``distctrl margins`` prints."""
    m = res.model
    T = m.cycle_time
    lines = [f"margins of the distance-control loop of axis {m.axis} ({m.scenario})",
             f"  mode {m.mode}" + (" with both encoders (P-AXIS-00500)" if m.both_encoders else
                                   " with one encoder" if m.mode == "CONST_DIST" else ""),
             f"  cycle time T = {T * 1e3:g} ms",
             "  loop (linear, limiter-free, small signals):",
             f"    filter       {m.filter_label}",
             f"    PID          KP = {m.kp:g} ({m.kp_source}), I_TN = " +
             (f"{m.i_tn:g} s" if m.i_tn > 0 else "0 s (no I part)") +
             f", D_TV = {m.d_tv:g} s (D gain {m.d_gain:.4g} per cycle)",
             "    offset       integration of the PID output, 1/(1 - z^-1), no slope limiter",
             f"    dead time    {_cycles(m.dead_time_cycles)} = {m.dead_time_cycles * T * 1e3:g} ms "
             f"(machine read 1, sensor delay_cycles {m.sensor_delay_cycles}, optimized_scheduling "
             f"{'on: 0' if m.optimized_scheduling else 'off: 1'})",
             f"    drive        kv = {m.kv:g} 1/s, feed-forward {m.feedforward:g}, bus delay "
             f"{_cycles(m.bus_delay_cycles)}"
             + (f", resonance {m.resonance_hz:g} Hz (damping {m.damping:g}) between motor and nozzle"
                if m.resonance_hz else "")
             + (f"; sensor gain {m.sensor_gain:.4g} mm/mm" if m.sensor_gain != 1.0 else "")]
    for note in m.notes:
        lines.append(f"    note: {note}")
    gm = res.gain_margin
    lines.append(f"  verdict: {res.verdict}")
    lines.append("  gain margin:      " + ("- (no phase crossover)" if gm is None else
                                            f"{gm:.4g} ({res.gain_margin_db:+.2f} dB)"
                                            + (" at " + _hz(res.phase_crossover_hz) if
                                               res.phase_crossover_hz is not None else "")))
    lines.append("  phase margin:     " + ("- (no gain crossover)" if res.phase_margin_deg is None else
                                            f"{res.phase_margin_deg:.2f} deg"
                                            + (" at " + _hz(res.gain_crossover_hz) if
                                               res.gain_crossover_hz is not None else "")))
    lines.append(f"  phase crossover:  {_hz(res.phase_crossover_hz)} (-180 deg)")
    lines.append(f"  gain crossover:   {_hz(res.gain_crossover_hz)} (|L| = 1)")
    n_cross = len(res.gain_margins) + len(res.phase_margins)
    if n_cross > 2:
        lines.append(f"  {n_cross} crossings in all (the figures above are the ones closest to the limit, as "
                     f"python-control chooses them" + ("; --json lists every one)" if n_cross > MAX_CROSSINGS_SHOWN
                                                        else "):"))
        if n_cross <= MAX_CROSSINGS_SHOWN:
            lines.extend(f"    gain margin {g:.4g} ({20 * math.log10(g):+.2f} dB) at {_hz(f)}"
                         for g, f in res.gain_margins)
            lines.extend(f"    phase margin {p:.2f} deg at {_hz(f)}" for p, f in res.phase_margins)
        elif res.phase_margins and res.phase_margins[0][1] != res.gain_crossover_hz:
            p, f = res.phase_margins[0]
            lines.append(f"    the lowest gain crossover: phase margin {p:.2f} deg at {_hz(f)}")
    if res.kp_limit is None:
        lines.append(f"  KP at the stability limit: - (none up to KP = {KP_SEARCH_MAX:g})")
    else:
        extra = ""
        kgm = res.kp_times_gain_margin
        if kgm is not None and abs(kgm - res.kp_limit) > 1e-3 * res.kp_limit:
            extra = (f"; KP x gain margin = {kgm:.4g}, which differs because the D gain follows KP"
                     if m.d_tv > 0 else f"; KP x gain margin = {kgm:.4g}")
        beyond = " (beyond the documented 0 < KP <= 2)" if res.kp_limit > KP_RANGE[1] else ""
        lines.append(f"  KP at the stability limit: {res.kp_limit:.4g}{beyond}, oscillating there at "
                     f"{_hz(res.limit_frequency_hz)}{extra}")
    r = res.spectral_radius
    rate = math.log(r) / T if r > 0 else -math.inf
    if r == 0.0:
        lines.append("  closed loop: every pole at z = 0: a small disturbance is gone after a few cycles "
                     "(dead-beat)")
        return "\n".join(lines) + "\n"
    how = "decays" if r < 1 - 1e-6 else "grows" if r > 1 + 1e-6 else "neither grows nor decays"
    rate_text = "" if abs(r - 1.0) <= 1e-6 else \
        f" ({rate:+.1f} 1/s, time constant {abs(1.0 / rate) * 1e3:.1f} ms)"
    lines.append(f"  closed loop: largest pole |z| = {r:.6f} per cycle at {_hz(res.pole_frequency_hz)}: "
                 f"a small disturbance {how}{rate_text}")
    return "\n".join(lines) + "\n"
