"""The first sweep / tune after installing the extras compiles the batch kernels for 30-80 s: it says so
first, in one line on stderr, never on stdout (new-user audit R17, issue 39). A cold cache is made by
telling the commands that no kernel is cached (the kernels then load from the real cache)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

pytest.importorskip("numba")

from distctrl.cli.tune import sweep, tune_cmd  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def _cold(monkeypatch):
    import distctrl.batch.jitcache as jc

    monkeypatch.setattr(jc, "is_cached", lambda dispatcher: False)


@pytest.mark.parametrize("cmd", ["sweep", "tune"])
def test_a_cold_kernel_cache_is_said_first_on_stderr_never_on_stdout(cmd, tmp_path, monkeypatch):
    _cold(monkeypatch)
    sc = str(EXAMPLES / "tune_sheet.toml")
    if cmd == "sweep":
        args = [sc, "--grid", "kp=0.3,0.5", "--local", "--out", str(tmp_path / "s.csv"), "--json"]
        command = sweep
    else:
        args, command = [sc, "--budget", "3", "--local", "--no-robustness", "--out", str(tmp_path / "t"),
                         "--json"], tune_cmd
    res = CliRunner().invoke(command, args)
    assert res.exit_code == 0, res.output
    json.loads(res.stdout)                                   # one object, nothing else
    assert "compiling" not in res.stdout
    lines = [ln for ln in res.stderr.splitlines() if "compiling the batch kernels" in ln]
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("compiling the batch kernels once for this machine (30-80 s")
    assert res.stderr.splitlines()[0] == lines[0]            # first, before the scenario is recorded
