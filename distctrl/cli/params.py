"""``distctrl params LIST_FILE``: load, validate and print a parameter list (axis or channel list)."""
from __future__ import annotations

import click

from ..control.controller import AxisDistanceController
from ..errors import DistCtrlError, ParameterError
from ..params import format_list, load_list
from ..params.channel import CHANNEL_LIST, load_channel_list
from ..params.listfile import AXIS_LIST, list_entries
from ..sim.scenario import CYCLE_TIME_MAX, CYCLE_TIME_MIN
from .common import Finite, emit_json, fail


#: keys that only a channel list (3D distance control, FCT-M3 §12.8) has
_CHANNEL_KEY_PREFIXES = ("dist_ctrl[", "configuration.")

def _list_kind(path: str) -> str:
    """'channel' when the list's first parameter key is a channel key, else 'axis'."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for raw in f:
                line = raw.split("#", 1)[0].strip()
                if line:
                    return "channel" if line.startswith(_CHANNEL_KEY_PREFIXES) else "axis"
    except OSError:
        pass
    return "axis"

@click.command("params")
@click.argument("list_file", type=click.Path(dir_okay=False))
@click.option("--all", "show_all", is_flag=True, help="Show every parameter, not only the ones that differ from the defaults.")
@click.option("--cycle-time", default=0.001, show_default=True, type=Finite(CYCLE_TIME_MIN, CYCLE_TIME_MAX),
              help="GEO cycle time (s) the list is checked against (the low-pass cut-off must lie below 1/(2T)).")
@click.option("--kind", type=click.Choice(["auto", "axis", "channel"]), default="auto", show_default=True,
              help="An axis list (P-AXIS-, FCT-M3 §9) or a channel list of 3D distance control (P-CHAN-, "
                   "FCT-M3 §12.8); auto: by the first key (dist_ctrl[..] or configuration.* = channel).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: kind, file, parameters, warnings.")
def params(list_file: str, show_all: bool, cycle_time: float, kind: str, as_json: bool) -> None:
    """Load and validate a parameter LIST_FILE (kernel format, axis or channel list) and print it back."""

    kind = _list_kind(list_file) if kind == "auto" else kind
    try:
        if kind == "channel":
            pl = load_channel_list(list_file)
            checked, fmt = pl.params.to_axis_parameters(), CHANNEL_LIST
            key, fg_id = "dist_ctrl[0].low_pass_filter_fg_f0", "P-CHAN-00817"
        else:
            pl = load_list(list_file)
            checked, fmt = pl.params, AXIS_LIST
            key, fg_id = "kenngr.distc.low_pass_filter_fg_f0", "P-AXIS-00508"
        try:
            AxisDistanceController(checked, cycle_time)        # what only the cycle time can decide
        except ParameterError as exc:
            fg = exc.param_id == "P-AXIS-00508"        # the low-pass cut-off against Nyquist
            message = str(exc).replace("P-AXIS-00508", fg_id) if fg else str(exc)
            raise ParameterError(message, file=list_file, line=pl.lines.get(key) if fg else None,
                                 key=key if fg else exc.key, param_id=fg_id if fg else exc.param_id,
                                 value=exc.value, allowed=exc.allowed) from None
    except DistCtrlError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot read {list_file}: {exc.strerror or exc}")
    if as_json:
        emit_json({"file": list_file, "kind": kind, "cycle_time_s": cycle_time, "valid": True,
                   "only_changed": not show_all, "warnings": list(pl.warnings),
                   "parameters": list_entries(pl.params, only_changed=not show_all, fmt=fmt)})
        return
    for w in pl.warnings:
        click.echo(f"warning: {w}", err=True)
    click.echo(format_list(pl.params, only_changed=not show_all, fmt=fmt), nl=False)
