"""Messages name the option (or argument) and what was expected (new-user audit R9)."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.cli import main
from distctrl.trace import Trace


def _one_error_line(r) -> str:
    assert r.exit_code == 1, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert "Traceback" not in r.output
    return lines[0]


@pytest.mark.parametrize("argv, words", [
    (["serve", "x.toml", "--allow", "not-a-net"], ["--allow", "'not-a-net'", "network", "127.0.0.0/8"]),
    (["serve", "x.toml", "--net-id", "1.2.3"], ["--net-id", "'1.2.3'", "6 numbers", "127.0.0.1.1.1"]),
    (["serve", "x.toml", "--net-id", "1.2.3.4.5.300"], ["--net-id", "0..255"]),
    (["ui", "x.toml", "--allow", "10.0.0.0/33"], ["--allow", "'10.0.0.0/33'"]),
])
def test_serve_names_the_option_and_what_it_takes(argv, words):
    line = _one_error_line(CliRunner().invoke(main, argv))
    for w in words:
        assert w in line, (w, line)


def test_serve_accepts_an_address_and_a_network(tmp_path):
    """The types take what they took before: an address, a network with host bits, IPv6."""
    from distctrl.cli.common import AMS_NET_ID, NETWORK

    assert NETWORK.convert("192.168.1.7", None, None) == "192.168.1.7"
    assert NETWORK.convert("10.1.2.3/8", None, None) == "10.1.2.3/8"
    assert NETWORK.convert("::1", None, None) == "::1"
    assert AMS_NET_ID.convert("5.12.34.56.1.1", None, None) == "5.12.34.56.1.1"


def test_step_given_a_trace_says_it_takes_a_scenario(tmp_path):
    rec = tmp_path / "excite_rec.csv"
    rec.write_text("t,Z.command,Z.actual,Z.sensor\n0,1,1,1\n")
    line = _one_error_line(CliRunner().invoke(main, ["step", str(rec)]))
    assert "step takes a scenario (.toml), not a trace" in line and "excite_rec.csv" in line, line


def test_demo_names_the_folder_it_cannot_make_and_the_option(tmp_path):
    (tmp_path / "out").write_text("a file where the folder should be")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        r = CliRunner().invoke(main, ["demo", "--json"])
    finally:
        os.chdir(cwd)
    line = _one_error_line(r)
    assert "out/demo" in line and "--out" in line and "Not a directory" in line, line
    assert json.loads(r.stdout)["outcome"] == "error"


def test_filters_on_a_machine_record_trace_uses_or_suggests_the_columns_it_has(tmp_path):
    """A `machine record` trace has Z.sensor, not Z.dc.sensor: the message suggested Z.dc.sensor."""
    t = np.arange(2000) * 1e-3
    rows = np.column_stack([t, np.full_like(t, 31.0), np.full_like(t, 31.0), 1.0 + 0.01 * np.sin(50 * t)])
    one = tmp_path / "rec.csv"
    Trace(["t", "Z.command", "Z.actual", "Z.sensor"], rows, units={"t": "s", "Z.command": "mm",
          "Z.actual": "mm", "Z.sensor": "mm"}).to_csv(one)
    r = CliRunner().invoke(main, ["filters", "--recording", str(one), "--json"])
    assert r.exit_code == 0, r.output
    assert "Z.sensor" in json.loads(r.stdout)["source"]
    two = tmp_path / "rec2.csv"
    rows2 = np.column_stack([rows, rows[:, 3]])
    Trace(["t", "Z.command", "Z.actual", "Z.sensor", "X.sensor"], rows2).to_csv(two)
    line = _one_error_line(CliRunner().invoke(main, ["filters", "--recording", str(two)]))
    assert "--value-column" in line and "dc.sensor" not in line and "Z.sensor" in line, line
