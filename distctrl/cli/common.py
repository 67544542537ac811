"""What every ``distctrl`` command shares: the exit codes, error lines, JSON output, the command group.

* :class:`~distctrl.errors.ExitCode`: 0 ok, 1 invalid input (also click's usage errors, which click
  itself would end with 2), 2 a control error aborted the program, 3 the time limit, 130 Ctrl-C.
* :func:`fail`: one ``error: ...`` line on stderr and the exit code; never a traceback.
* :func:`emit_json`: one JSON object on stdout; NaN and infinities become ``null`` (a metric that
  cannot be computed is null, never a number that is wrong).
* :class:`DistctrlGroup`: the top-level group; subcommands are imported when used (the numba, dask
  and matplotlib parts load only for the commands that need them).
"""
from __future__ import annotations

import importlib
import json
import math
import sys
from typing import Any, NoReturn

import click

from ..errors import ExitCode


def fail(message: str, code: ExitCode = ExitCode.INVALID_INPUT) -> NoReturn:
    """Print ``error: message`` on stderr and exit with ``code``."""
    click.echo(f"error: {message}", err=True)
    sys.exit(int(code))


def _finite_or_none(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    if hasattr(value, "item") and callable(value.item) and getattr(value, "shape", None) == ():
        return _finite_or_none(value.item())        # numpy scalars
    return value


def json_text(obj: Any) -> str:
    """The JSON text :func:`emit_json` prints (strict JSON: no NaN / Infinity)."""
    return json.dumps(_finite_or_none(obj), indent=2, allow_nan=False, default=str)


def emit_json(obj: Any) -> None:
    """Print one JSON object on stdout."""
    click.echo(json_text(obj))


class DistctrlGroup(click.Group):
    """The ``distctrl`` group: lazy subcommands and one exit-code table for every command.

    click ends a usage error (unknown option, bad value of a typed option) with 2, which distctrl
    uses for "a control error aborted the program"; here it is 1 like every other invalid input.
    Ctrl-C in a command that does not handle it itself ends with 130 instead of click's "Aborted!" 1.
    """

    def __init__(self, *args, lazy_commands: dict[str, str] | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.lazy_commands = dict(lazy_commands or {})      # name -> "module:attribute"

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(self.lazy_commands))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in self.lazy_commands and cmd_name not in self.commands:
            module, _, attr = self.lazy_commands[cmd_name].partition(":")
            self.add_command(getattr(importlib.import_module(module), attr), cmd_name)
        return super().get_command(ctx, cmd_name)

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except click.UsageError as exc:
            exc.exit_code = int(ExitCode.INVALID_INPUT)
            raise

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            exc.exit_code = int(ExitCode.INVALID_INPUT)
            raise
        except KeyboardInterrupt:
            click.echo("interrupted (Ctrl-C)", err=True)
            raise click.exceptions.Exit(int(ExitCode.INTERRUPTED)) from None
