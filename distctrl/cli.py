"""Command-line interface: ``distctrl COMMAND`` (click). Errors at this edge are messages, exit 1."""
from __future__ import annotations

import sys

import click

from .errors import DistCtrlError


@click.group()
@click.version_option(package_name="distctrl")
def main() -> None:
    """distctrl: CNC distance (height) control — the ISG-kernel control law as a pure cycle core."""


@main.command()
@click.argument("list_file", type=click.Path(dir_okay=False))
@click.option("--all", "show_all", is_flag=True, help="Show every parameter, not only the ones that differ from the defaults.")
def params(list_file: str, show_all: bool) -> None:
    """Load and validate an axis parameter LIST_FILE (kernel format) and print it back."""
    from .params import format_list, load_list

    try:
        pl = load_list(list_file)
    except DistCtrlError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(1)
    for w in pl.warnings:
        click.echo(f"warning: {w}", err=True)
    click.echo(format_list(pl.params, only_changed=not show_all), nl=False)


@main.command()
def demo() -> None:
    """Run the demo job: CONST_DIST and SET_POS over an uneven sheet, with a summary table."""
    from .demo import main as run_demo

    run_demo()


if __name__ == "__main__":
    main()
