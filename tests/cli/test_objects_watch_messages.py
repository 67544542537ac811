"""`distctrl objects --watch` as the new-user audit of 2026-12-07 met it (issue 39):

* R2: a port with nothing listening gave two AdsLib log lines and "ADSError: Target port not found";
  now the one line `machine show` gives (a bounded TCP connect first), and no library line on stderr,
  also none ("Info: connection closed by remote") after a successful --watch;
* R10: `--axis Z` without a SCENARIO said only "no axis 'Z'"; now it says how the axes are named then
  and that --axis 2 or the SCENARIO works, and --axis 2 does.
"""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCN = ROOT / "examples" / "scenarios"

pytest.importorskip("pyads")


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def distctrl(*args):
    """The command in its own process: AdsLib writes its log lines to file descriptor 2 directly."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("DISTCTRL_ADS_LOG", None)
    return subprocess.run([sys.executable, "-m", "distctrl", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=120)


@pytest.fixture(scope="module")
def served():
    from distctrl.ads.devices import serve_over_ads
    from distctrl.sim.scenario import load_scenario

    sm = serve_over_ads(load_scenario(SCN / "serve_z.toml"), host="127.0.0.1", port=0, net_id="127.0.0.1.1.1",
                        discovery_port=None)
    sm.start()
    yield sm, sm.services["ads"].server.port
    sm.stop()


def test_nothing_listening_is_the_one_not_reachable_line():
    port = closed_port()
    r = distctrl("objects", "--watch", "--port", port, "--count", 1)
    assert r.returncode == 1, r
    assert r.stderr.splitlines() == [r.stderr.strip()], r.stderr          # one line, nothing from AdsLib
    assert f"127.0.0.1:{port} not reachable" in r.stderr and "serve --port" in r.stderr, r.stderr
    assert "Socket" not in r.stderr and "ADSError" not in r.stderr


def test_a_successful_watch_leaves_no_library_line(served):
    _, port = served
    r = distctrl("objects", str(SCN / "serve_z.toml"), "--watch", "--port", port, "--count", 1, "--axis", "Z",
                 "--json")
    assert r.returncode == 0, r
    assert r.stderr == "", r.stderr
    assert json.loads(r.stdout)["refresh"] == 1


def test_axis_name_without_scenario_says_how_the_axes_are_named(served):
    from click.testing import CliRunner

    from distctrl.cli import main

    _, port = served
    res = CliRunner().invoke(main, ["objects", "--watch", "--port", str(port), "--count", "1", "--axis", "Z"])
    assert res.exit_code == 1
    msg = res.stderr.strip()
    assert "\n" not in msg and "axis1" in msg and "axis2" in msg and "--axis 2" in msg and "SCENARIO" in msg, msg
    res = CliRunner().invoke(main, ["objects", "--watch", "--port", str(port), "--count", "1", "--axis", "2",
                                    "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert {o["axis"] for o in doc["objects"]} == {"2 axis2"}
