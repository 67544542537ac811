"""``distctrl diag SCENARIO``: the diagnosis block of distance control (FCT-M3 Fig. 56 layout)."""
from __future__ import annotations

import click

from ..errors import DistCtrlError
from ..objects.diag import diag_3d, diag_axis
from ..sim.machine import Machine
from ..sim.runner import load_program
from ..sim.scenario import load_scenario
from .common import Finite, emit_json, fail


@click.command("diag", short_help="The diagnosis block of distance control (layout of FCT-M3 Fig. 56).")
@click.argument("scenario", type=click.Path(dir_okay=False))
@click.option("--seconds", default=1.0, show_default=True, type=Finite(min=0.0, max=3600.0),
              help="Run the scenario this long first [s].")
@click.option("--axis", "axis_filter", help="Only this axis (name).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: the blocks with every value as a number and its unit.")
def diag(scenario: str, seconds: float, axis_filter: str | None, as_json: bool) -> None:
    """The diagnosis block of distance control (FCT-M3 Fig. 56 layout) after running SCENARIO
    for --seconds: parameters in use, state, set values, offset, sensor, filter, limits, last error."""

    try:
        sc = load_scenario(scenario)
        machine = Machine(sc, load_program(sc))
        for _ in range(int(round(seconds / sc.cycle_time))):
            machine.step()
    except DistCtrlError as exc:
        fail(str(exc))
    events = [ev for _, ev in machine.events]
    blocks = []
    if machine.ch3d is not None and axis_filter is None:
        blocks.append(diag_3d(machine.channel3d_values(), sc.channel_params, channel=1, events=events))
    axes = [n for n in machine.dc_axes if axis_filter in (None, n)]
    if not axes and not blocks:
        fail(f"no distance-controlled axis {axis_filter or ''}".rstrip())
    blocks += [diag_axis(machine.controllers[n], machine.outputs[n], n,
                         axis_index=machine.axis_names.index(n) + 1, events=events) for n in axes]
    if as_json:
        emit_json({"scenario": scenario, "seconds": seconds, "blocks": [b.to_dict() for b in blocks]})
        return
    for b in blocks:
        click.echo(b.text())
