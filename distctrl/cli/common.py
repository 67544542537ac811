"""What every ``distctrl`` command shares: the exit codes, error lines, JSON output, the command group.

* :class:`~distctrl.errors.ExitCode`: 0 ok, 1 invalid input (also click's usage errors, which click
  itself would end with 2), 2 a control error aborted the program, 3 the time limit, 4 a check the
  command makes failed (calibrate's repeatability), 130 Ctrl-C.
* :func:`fail`: one ``error: ...`` line on stderr and the exit code; never a traceback. With
  ``--json`` the same error also goes to stdout as one JSON object (:func:`error_object`, the same
  shape for every command), so a script that always parses stdout gets an answer.
* :func:`emit_json`: one JSON object on stdout; NaN and infinities become ``null`` (a metric that
  cannot be computed is null, never a number that is wrong).
* :class:`Finite` and :class:`IntRange`: the types of every numeric option (a range, and no NaN or
  infinity); tests/test_cli.py walks every command and refuses a numeric option without one.
* :func:`output_error_text`: one line for an OSError on an output path, naming the path and the real
  reason ("Not a directory", "No space left on device").
* :class:`DistctrlGroup`: the top-level group; subcommands are imported when used (the numba, dask
  and matplotlib parts load only for the commands that need them). An ``OSError`` that reaches it (a
  full disk, a read-only place) ends with one ``error:`` line naming the path and exit code 1; so does
  an optional dependency that is not installed, naming the extra that installs it (:mod:`.extras`).
* :func:`check_writable`: an output path is tried before a long run, not after it; :func:`check_output`
  also checks its suffix (the one helper every command's output files go through).
* :func:`freeze_loaded_objects`: what a command has loaded leaves the garbage collector's scans.
"""
from __future__ import annotations

import errno
import gc
import importlib
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import click

from ..errors import DistCtrlError, ExitCode
from ..errors.files import PLOT_SUFFIXES, check_suffix
from .extras import missing_dependency

#: the state of the command line in this process: the command whose ``--json`` was given (set by
#: :class:`DistctrlGroup` from the arguments, so that an error before the command's own code runs,
#: a usage error included, also answers in JSON) and whether a JSON object was printed already
_STATE: dict[str, Any] = {"json_command": None, "emitted": False}


def _json_command() -> str | None:
    """The name of the running command when it was asked for ``--json``, else None."""
    ctx = click.get_current_context(silent=True)
    while ctx is not None:
        if ctx.params.get("as_json"):
            return ctx.info_name or (ctx.command.name if ctx.command else None) or "distctrl"
        ctx = ctx.parent
    return _STATE["json_command"]


def error_object(message: str, code: ExitCode | int = ExitCode.INVALID_INPUT, command: str | None = None) -> dict:
    """The JSON object of a command that ends with an error (every command, the same shape):
    ``{"command": ..., "outcome": "error", "exit_code": 1, "error": "<the stderr line's message>"}``."""
    return {"command": command, "outcome": "error", "exit_code": int(code), "error": message}


def freeze_loaded_objects() -> None:
    """Take the objects made so far (the imported modules, numba, a recorded scenario: they live until the
    command ends) out of the scans of Python's cyclic garbage collector (:func:`gc.freeze`). Each full
    collection walked them all again: a ``sweep`` spent about 0.2 s of its 1 s start in the collector while
    numba loaded its cached kernels (issue 27, bench/bench_sweep.py's fixed cost). A command's process only
    (this is the edge): a library caller's collector is left as it is."""
    gc.freeze()


def fail(message: str, code: ExitCode = ExitCode.INVALID_INPUT) -> NoReturn:
    """Print ``error: message`` on stderr and exit with ``code``; with ``--json`` (and no JSON object
    printed yet) also the :func:`error_object` on stdout."""
    click.echo(f"error: {message}", err=True)
    command = _json_command()
    if command is not None and not _STATE["emitted"]:
        emit_json(error_object(message, code, command))
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
    _STATE["emitted"] = True
    click.echo(json_text(obj))


class Finite(click.FloatRange):
    """A float option's type: ``click.FloatRange`` that also refuses NaN and infinities (a bare
    FloatRange lets ``nan`` through, every comparison with it being false)."""

    name = "float range"

    def convert(self, value, param, ctx):
        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{value!r} is not a finite number; allowed: {self._describe_range()}", param, ctx)
        return rv


IntRange = click.IntRange

#: an axis position or a surface height (mm): any finite coordinate within +-1 km
COORDINATE = Finite(-1e6, 1e6)
#: a TCP/UDP port (0: the system picks a free one)
PORT = click.IntRange(0, 65535)
#: a seed of numpy's random generator
SEED = click.IntRange(0, 2**32 - 1)


class Network(click.ParamType):
    """An address or a network a client may connect from (``--allow``): IPv4 or IPv6, a CIDR
    network with or without host bits. The value stays the text given."""

    name = "address or network"

    def convert(self, value, param, ctx):
        import ipaddress  # only the servers take networks: off the import path of every other command

        try:
            ipaddress.ip_network(str(value), strict=False)
        except ValueError:
            self.fail(f"{value!r} is not an IPv4/IPv6 address or network; allowed: an address (192.168.0.7) "
                      "or a network (127.0.0.0/8, 192.168.0.0/24, ::1)", param, ctx)
        return value


class AmsNetId(click.ParamType):
    """An AMS NetId: 6 numbers 0..255 separated by dots (``127.0.0.1.1.1``). The value stays the text."""

    name = "AMS NetId"

    def convert(self, value, param, ctx):
        parts = str(value).strip().split(".")
        if len(parts) != 6 or not all(p.isdigit() for p in parts):
            self.fail(f"{value!r} is not an AMS NetId; allowed: 6 numbers 0..255 separated by dots, "
                      "e.g. 127.0.0.1.1.1", param, ctx)
        if not all(0 <= int(p) <= 255 for p in parts):
            self.fail(f"{value!r}: each of the AMS NetId's 6 numbers must be 0..255", param, ctx)
        return value


#: ``--allow`` of the servers
NETWORK = Network()
#: ``--net-id`` of the servers
AMS_NET_ID = AmsNetId()


def check_writable(path: str, what: str, directory: bool = False) -> None:
    """Fail at once (exit 1, one line naming the path) when ``path`` cannot be written, before a
    long run is wasted on an output that cannot be saved. Creates missing parent folders like the
    writers do."""
    p = Path(path)
    target = p if directory else p.parent
    try:
        target.mkdir(parents=True, exist_ok=True)
        if directory:
            probe = target / ".distctrl-write-test"
            probe.write_bytes(b"")
            probe.unlink()
        else:
            existed = p.exists()
            with open(p, "ab"):
                pass
            if not existed:
                os.unlink(p)
    except OSError as exc:
        fail(output_error_text(exc, path, what))


def check_output(path: str | None, what: str, allowed: Sequence[str] = (), directory: bool = False) -> None:
    """An output given on the command line, before the work: its suffix among ``allowed`` (lower case,
    with the dot; :func:`distctrl.errors.files.check_suffix`) and that it can be written; fails with one
    line (and the --json error object) otherwise. Every command checks its output files with it."""
    if not path:
        return
    if allowed:
        try:
            check_suffix(path, what, allowed)
        except DistCtrlError as exc:
            fail(str(exc))
    check_writable(path, what, directory=directory)


def check_plot_output(path: str | None, check_suffix_of=None) -> None:
    """A ``--plot`` file before the work: :func:`check_output` with the plot suffixes (.png, .svg, .pdf),
    or the check ``check_suffix_of`` (raises a DistCtrlError) of a command that has its own."""
    if path and check_suffix_of is not None:
        try:
            check_suffix_of(path)
        except DistCtrlError as exc:
            fail(str(exc))
    check_output(path, "plot", PLOT_SUFFIXES if check_suffix_of is None else ())


def os_error_reason(exc: OSError, path: str | None = None) -> str:
    """The real reason of an OSError on ``path`` in the system's words: "Not a directory" where
    creating a folder failed because a part of the path is an existing file (mkdir says "File
    exists" then, naming the file), else the error's own words ("No space left on device",
    "Permission denied")."""
    where = path if path is not None else exc.filename
    if exc.errno in (errno.EEXIST, errno.ENOTDIR) and where is not None:
        p = Path(os.fspath(where))
        for part in (p, *p.parents):
            try:
                if part.exists() and not part.is_dir():
                    return f"{os.strerror(errno.ENOTDIR)} ({part} is not a folder)"
            except OSError:
                break
    return exc.strerror or str(exc)


def output_error_text(exc: OSError, path: str | None = None, what: str | None = None) -> str:
    """One line for an OSError on an output: ``cannot write the WHAT PATH: REASON`` (the path given,
    or the error's own filename; the reason from :func:`os_error_reason`). The one helper every
    command uses for a place it cannot write."""
    where = path if path is not None else exc.filename
    head = f"cannot write the {what}" if what else "cannot write"
    if where is None:
        return f"{head}: {os_error_reason(exc)}"
    return f"{head} {where}: {os_error_reason(exc, str(where))}"


def os_error_text(exc: OSError) -> str:
    """One line for an OSError that reached the command group: the path and the real reason."""
    where = exc.filename if exc.filename is not None else None
    if where is None:
        return f"cannot use an output: {exc.strerror or exc}"
    return f"cannot use {where}: {os_error_reason(exc, str(where))}"


def human_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} TB"  # pragma: no cover


def _click_error(exc: click.ClickException) -> NoReturn:
    """click's own errors (a usage error, a bad option value, a ClickException of a command) as distctrl's:
    one ``error:`` line (click prints "Usage: ...", "Try ...", a blank line and "Error: ..."), a usage
    error naming where the help is, the --json error object, and exit code 1 for a usage error (click's
    2 is distctrl's "a control error aborted the program")."""
    message = " ".join(exc.format_message().split())
    code = int(ExitCode.INVALID_INPUT) if isinstance(exc, click.UsageError) else int(exc.exit_code)
    if isinstance(exc, click.UsageError) and exc.ctx is not None:
        message += f" (see {' '.join(['distctrl', *exc.ctx.command_path.split()[1:]])} --help)"
    click.echo(f"error: {message}", err=True)
    if _STATE["json_command"] is not None and not _STATE["emitted"]:
        emit_json(error_object(message, code, _STATE["json_command"]))
    raise click.exceptions.Exit(code)


class DistctrlGroup(click.Group):
    """The ``distctrl`` group: lazy subcommands and one exit-code table for every command.

    click ends a usage error (unknown option, bad value of a typed option) with 2, which distctrl
    uses for "a control error aborted the program", and prints it on four lines; here it is one
    ``error:`` line and exit code 1 like every other invalid input (:func:`_click_error`).
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
            try:
                command = getattr(importlib.import_module(module), attr)
            except ModuleNotFoundError as exc:          # an extra not installed: one line, exit code 1
                message = missing_dependency(exc)
                if message is None:
                    raise
                fail(f"distctrl {cmd_name}: {message}")
            self.add_command(command, cmd_name)
        return super().get_command(ctx, cmd_name)

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except click.ClickException as exc:
            _click_error(exc)

    def invoke(self, ctx: click.Context):
        args = [*getattr(ctx, "_protected_args", ()), *ctx.args]
        if args:
            own = args[1:args.index("--")] if "--" in args else args[1:]
            _STATE["json_command"] = args[0] if "--json" in own else None
        _STATE["emitted"] = False
        try:
            return super().invoke(ctx)
        except click.ClickException as exc:
            _click_error(exc)
        except ModuleNotFoundError as exc:
            # an optional dependency the command needs is not installed: name the extra (pyproject.toml)
            message = missing_dependency(exc)
            if message is None:
                raise
            fail(message)
        except KeyboardInterrupt:
            click.echo("interrupted (Ctrl-C)", err=True)
            raise click.exceptions.Exit(int(ExitCode.INTERRUPTED)) from None
        except BrokenPipeError:
            # the reader of stdout went away (`| head`): nothing more to say to it
            import os

            try:
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            except (OSError, ValueError):
                pass
            raise click.exceptions.Exit(int(ExitCode.OK)) from None
        except OSError as exc:
            # an output that cannot be written (a full disk, a read-only place): one line, no traceback
            fail(os_error_text(exc))
        finally:
            _STATE["json_command"], _STATE["emitted"] = None, False
