"""``distctrl excite``: the NC program that excites one axis for ``distctrl identify`` (the generator
is :mod:`distctrl.nc.excite`)."""
from __future__ import annotations

import click

from ..nc.excite import Excitation, ExciteError, build
from .common import Finite, check_writable, emit_json, fail


def _range(text: str, what: str, sep: str = "-") -> tuple[float, float]:
    try:
        a, b = text.replace(":", sep).split(sep) if text.count(sep) == 1 or ":" in text else (None, None)
        return float(a), float(b)
    except (TypeError, ValueError):
        fail(f"{what} {text!r}: write FROM{sep}TO, e.g. {'1-150' if sep == '-' else '0.3:7.5'}")


@click.command()
@click.option("--axis", default="Z", show_default=True, type=click.Choice(["X", "Y", "Z", "A", "B", "C"]),
              help="The axis to excite.")
@click.option("--work", required=True, type=Finite(-1e6, 1e6), help="Working height [mm, machine coordinates]: "
              "the steps and the chirp happen here, above a flat sheet.")
@click.option("--safe", required=True, type=Finite(-1e6, 1e6), help="Safe height [mm]: approach, retract, the large step.")
@click.option("--min", "min_pos", required=True, type=Finite(-1e6, 1e6), help="The axis's lower limit [mm]: refused beyond.")
@click.option("--max", "max_pos", required=True, type=Finite(-1e6, 1e6), help="The axis's upper limit [mm]: refused beyond.")
@click.option("--v-max", default=100.0, show_default=True, type=Finite(1e-3, 1e6), help="The axis's velocity [mm/s].")
@click.option("--a-max", default=5000.0, show_default=True, type=Finite(1e-3, 1e8), help="The axis's acceleration [mm/s²].")
@click.option("--cycle-ms", default=1.0, show_default=True, type=Finite(0.05, 100.0), help="The CNC cycle [ms].")
@click.option("--steps", "step", default=0.3, show_default=True, type=Finite(0.0, 100.0),
              help="Step size [mm] (recommended 0.2-0.5); 0: no steps.")
@click.option("--step-count", default=10, show_default=True, type=click.IntRange(1, 1000),
              help="Steps up and down around the working height, every 0.5 s.")
@click.option("--large-step", default=3.0, show_default=True, type=Finite(0.0, 1000.0),
              help="One large step at the safe height [mm]; 0: none.")
@click.option("--chirp", default="1-150", show_default=True, help="Chirp band FROM-TO [Hz]; 'none': no chirp.")
@click.option("--chirp-seconds", default=20.0, show_default=True, type=Finite(0.5, 600.0),
              help="Duration of the chirp [s]: the band is swept linearly in this time.")
@click.option("--amplitude", default=0.05, show_default=True, type=Finite(0.0, 100.0),
              help="Chirp amplitude [mm] (recommended 0.02-0.05).")
@click.option("--ramp", default=None, help="Slow ramp FROM:TO [mm, machine coordinates] over the sensor's range.")
@click.option("--ramp-speed", default=0.3, show_default=True, type=Finite(0.0, 1000.0),
              help="Speed of the slow ramp [mm/s] (recommended 0.2-0.5).")
@click.option("--surface", default=None, type=Finite(-1e6, 1e6),
              help="The sheet's height [mm, machine coordinates]: refuses a program with any height at or "
              "below it (safe height, large step, ramp, retract; the working height by 10x the chirp "
              "amplitude, a resonance's ringing).")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="The NC program to write.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: out, blocks, seconds, warnings.")
def excite(axis, work, safe, min_pos, max_pos, v_max, a_max, cycle_ms, step, step_count, large_step, chirp,
           chirp_seconds, amplitude, ramp, ramp_speed, surface, out, as_json):
    """Write the NC program (ISG dialect) that excites AXIS for `distctrl identify`: steps, a chirp, a
    slow ramp, with a safe approach and retract, distance control off. Refuses a program beyond
    the axis limits given (docs/identify.md, docs/commissioning.md)."""
    chirp_band = None if chirp.strip().lower() == "none" else _range(chirp, "--chirp")
    e = Excitation(axis=axis, work=work, safe=safe, min_pos=min_pos, max_pos=max_pos, a_max=a_max, v_max=v_max,
                   cycle_time=cycle_ms * 1e-3, step=step or None, step_count=step_count, large_step=large_step,
                   chirp=chirp_band, chirp_seconds=chirp_seconds, amplitude=amplitude,
                   ramp=_range(ramp, "--ramp", ":") if ramp else None, ramp_speed=ramp_speed, surface=surface)
    try:
        prog = build(e)
    except ExciteError as exc:
        fail(str(exc))
    text, warnings = prog.text, prog.warnings
    check_writable(out, "--out")
    with open(out, "w", encoding="utf-8") as f:
        f.write(text)
    blocks = sum(1 for line in text.splitlines() if line and not line.startswith((";", "%")))
    for w in warnings:
        click.echo(f"warning: {w}", err=True)
    result = {"command": "excite", "outcome": "ok", "out": out, "blocks": blocks,
              "seconds": round(prog.seconds, 3), "warnings": warnings}
    if as_json:
        emit_json(result)
    else:
        click.echo(f"written: {out} ({blocks} blocks, about {prog.seconds:.1f} s); run it with distance "
                   f"control off, recording with "
                   f"distctrl machine record, then distctrl identify")
