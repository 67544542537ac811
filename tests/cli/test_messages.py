"""The style of what the command line says (new-user audit R8): every error is one line starting
``error:`` (click's usage errors too, with the exit code docs/cli.md gives them), and the extras have one
name each, ``[batch]`` for numba/dask and ``[ads]`` for pyads, in every message and comment."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.errors import ExitCode

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("argv, named", [
    (["serve", "x.toml", "--port", "70000"], "--port"),
    (["nothere"], "nothere"),
    (["run", "--bogus", "x.toml"], "--bogus"),
    (["excite", "--work", "nan", "--safe", "1", "--min", "0", "--max", "2", "--out", "x.nc"], "--work"),
    (["machine", "show"], "--ads"),
])
@pytest.mark.parametrize("as_json", [False, True])
def test_a_usage_error_is_one_error_line_with_exit_1(argv, named, as_json):
    r = CliRunner().invoke(main, argv + (["--json"] if as_json else []))
    assert r.exit_code == ExitCode.INVALID_INPUT, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and named in lines[0], r.stderr
    assert "--help" in lines[0]                         # where to read more
    if as_json and argv[0] != "nothere":
        d = json.loads(r.stdout)
        assert d["outcome"] == "error" and d["error"] == lines[0][len("error: "):]


def test_no_message_or_comment_names_an_old_extra_or_a_bare_pip_install():
    """[fast] and [tune] are the former names of [batch] (pyproject.toml keeps them as aliases)."""
    bad = re.compile(r"\[(fast|tune)\]|pip install (pyads|numba|dask|pyarrow)\b")
    hits = []
    for p in [*sorted((ROOT / "distctrl").rglob("*.py")), ROOT / "Makefile"]:
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if bad.search(line):
                hits.append(f"{p.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not hits, "\n".join(hits)


def test_no_error_line_starts_with_a_capital_error():
    """click.ClickException and friends print 'Error: ...'; distctrl's lines are 'error: ...'."""
    hits = []
    for p in sorted((ROOT / "distctrl").rglob("*.py")):
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"""echo\(\s*f?["']Error:""", line):
                hits.append(f"{p.relative_to(ROOT)}:{n}")
    assert not hits, hits


def test_a_click_exception_of_a_command_is_one_error_line():
    import click

    from distctrl.cli.common import DistctrlGroup

    @click.group(cls=DistctrlGroup)
    def grp():
        pass

    @grp.command()
    def boom():
        raise click.ClickException("no axis 'Z'")

    r = CliRunner().invoke(grp, ["boom"])
    assert r.exit_code == 1 and r.stderr == "error: no axis 'Z'\n", r.stderr
