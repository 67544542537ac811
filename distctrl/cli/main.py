"""The ``distctrl`` command group (click): every command is a module of this package, imported when it is
used (:data:`LAZY_COMMANDS`). Errors at this edge are messages; the exit codes are one table for every
command (:class:`~distctrl.errors.ExitCode`, docs/run.md)."""
from __future__ import annotations

import click

from .common import DistctrlGroup

#: command name -> "module:attribute" of its click command; the module is imported when the command is used
LAZY_COMMANDS = {
    "benchmark": "distctrl.cli.benchmark:benchmark",
    "calibrate": "distctrl.cli.calibrate:calibrate_cmd",
    "demo": "distctrl.cli.demo:demo_cmd",
    "diag": "distctrl.cli.diag:diag",
    "excite": "distctrl.cli.excite:excite",
    "filters": "distctrl.cli.filters:filters",
    "identify": "distctrl.cli.identify:identify_cmd",
    "linuxcnc": "distctrl.cli.linuxcnc:linuxcnc",
    "machine": "distctrl.cli.machine:machine",
    "margins": "distctrl.cli.margins:margins",
    "objects": "distctrl.cli.objects:objects",
    "params": "distctrl.cli.params:params",
    "plot": "distctrl.cli.plot:plot",
    "run": "distctrl.cli.run:run",
    "serve": "distctrl.cli.serve:serve",
    "step": "distctrl.cli.step:step",
    "sweep": "distctrl.cli.tune:sweep",
    "tune": "distctrl.cli.tune:tune_cmd",
    "ui": "distctrl.cli.serve:ui_cmd",
}


@click.group(cls=DistctrlGroup, lazy_commands=LAZY_COMMANDS)
@click.version_option(package_name="distctrl")
def main() -> None:
    """distctrl: CNC distance (height) control — the ISG-kernel control law as a pure cycle core."""


if __name__ == "__main__":
    main()
