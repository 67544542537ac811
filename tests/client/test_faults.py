"""The ADS client against a target that answers garbage, too slowly, not at all, or drops mid-write
(issue 30): one clear line with the ADS error code, in bounded time, and never a half-written
parameter set -- a write completes and verifies, or what was written is restored from the backup."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from distctrl.ads import AdsServer
from distctrl.client.axes import Unit, read_parameters
from distctrl.client.target import MachineError, Target
from distctrl.client.writer import execute, plan_write
from distctrl.errors import ExitCode

from .conftest import free_loopback
from .faults import INITIAL, FaultyLine, MemoryCnc

Z = Unit("axis", 3, "Z")
NEW = "kenngr.distc.kp 0.8\nkenngr.distc.i_tn 0.01\nkenngr.distc.d_tv 0.003\nkenngr.distc.v_max 150000\n"


@pytest.fixture()
def rig():
    cnc = MemoryCnc()
    srv = AdsServer({551: cnc}, host="127.0.0.1", port=0, net_id="127.0.0.1.1.1", check_net_id=False)
    srv.start()
    host = free_loopback()
    line = FaultyLine(host, srv.port)
    try:
        yield cnc, line, host
    finally:
        line.close()
        srv.stop()


def target(host: str, timeout: float = 3.0) -> Target:
    return Target(f"{host}.1.1", 551, host, timeout=timeout, connect_timeout=1.0)


def old_set(cnc) -> dict:
    return {k: cnc.values[k] for k in INITIAL}


@pytest.mark.parametrize("mode", ["silent", "garbage", "slow"])
def test_bad_target_is_one_line_in_bounded_time(rig, mode):
    cnc, line, host = rig
    line.mode = mode
    t0 = time.monotonic()
    with pytest.raises(MachineError) as err:
        with target(host, timeout=0.5) as t:
            read_parameters(t, Z)
    took = time.monotonic() - t0
    msg = str(err.value)
    assert "\n" not in msg and "ADS error 0x" in msg, msg
    assert err.value.code is not None
    assert took < 10, took                         # 0.5 s requests: never a hang


def test_unreachable_host_is_one_line(rig):
    with pytest.raises(MachineError, match="not reachable"):
        target("127.255.255.254", 0.5).open()          # nobody listens there


def test_write_cut_mid_set_is_restored_from_the_backup(rig, tmp_path):
    cnc, line, host = rig
    lis = tmp_path / "tuned.lis"
    lis.write_text(NEW)
    before = old_set(cnc)
    with target(host) as t:
        plan = plan_write(t, Z, lis)
        assert len(plan.changes) == 4
        line.mode, line.cut_after = "cut_at_write", 2         # the 3rd write never reaches the target
        with pytest.raises(MachineError) as err:
            execute(plan, t, tmp_path / "backup.lis", reconnect=lambda: target(host).open())
    assert err.value.exit_code == ExitCode.CHECK_FAILED
    assert "restored from the backup" in str(err.value) and "\n" not in str(err.value)
    assert line.cuts == 1 and len(cnc.writes) >= 2            # two values had been written ...
    assert old_set(cnc) == before                              # ... and are back: no half-written set
    assert (tmp_path / "backup.lis").is_file()


def test_value_refused_mid_set_is_restored(rig, tmp_path):
    cnc, line, host = rig
    lis = tmp_path / "tuned.lis"
    lis.write_text(NEW)
    before = old_set(cnc)
    with target(host) as t:
        plan = plan_write(t, Z, lis)
        plan.changes[-1].new = 7.5                              # kp 7.5: the target answers 0x706
        with pytest.raises(MachineError) as err:
            execute(plan, t, tmp_path / "backup.lis")
    assert "0x706" in str(err.value) and "restored" in str(err.value)
    assert old_set(cnc) == before


def test_garbage_read_back_is_restored(rig, tmp_path, monkeypatch):
    """A target that takes the values but reads back something else fails the verification."""
    cnc, line, host = rig
    lis = tmp_path / "tuned.lis"
    lis.write_text(NEW)
    before = old_set(cnc)
    real_write = cnc.write

    def corrupting(ig, io, data):
        real_write(ig, io, data)
        if cnc.writes[-1][0] == "i_tn" and len(cnc.writes) <= 4:
            cnc.values["DIST_CTRL::i_tn"] = 42.0                # garbage in the object
    monkeypatch.setattr(cnc, "write", corrupting)
    monkeypatch.setattr("distctrl.client.writer.SETTLE", 0.05)
    with target(host) as t:
        plan = plan_write(t, Z, lis)
        with pytest.raises(MachineError, match="reads back 42"):
            execute(plan, t, tmp_path / "backup.lis")
    assert old_set(cnc) == before


def test_complete_write_verifies(rig, tmp_path):
    cnc, line, host = rig
    lis = tmp_path / "tuned.lis"
    lis.write_text(NEW)
    with target(host) as t:
        plan = plan_write(t, Z, lis)
        done = execute(plan, t, tmp_path / "backup.lis")
    assert cnc.values["DIST_CTRL::kp"] == 0.8 and cnc.values["DIST_CTRL_PARAM[0]::v_max"] == 150000
    # every object of this fake reads the written value back: verified, and pending (FCT-M3 §9.4)
    assert {(c.status, c.read_back) for c in plan.changes} == {("pending", "written")}
    assert done["written"] == ["v_max", "d_tv", "i_tn", "kp"]
    text = Path(done["backup"]).read_text()
    assert "kenngr.distc.kp                    0.5" in text


def test_cli_error_is_exactly_one_line_on_stderr(rig, tmp_path):
    """In a real process pyads' AdsLib log lines stay off the terminal: stderr is our one line."""
    import os
    import subprocess
    import sys

    cnc, line, host = rig
    line.mode = "garbage"
    lis = tmp_path / "tuned.lis"
    lis.write_text(NEW)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    env.pop("DISTCTRL_ADS_LOG", None)
    r = subprocess.run([sys.executable, "-m", "distctrl", "machine", "write", "--ads", f"{host}.1.1",
                        "--axis", "Z=3", str(lis), "--yes", "--timeout", "1"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: ADS error 0x745"), r.stderr
    assert old_set(cnc) == {k: v for k, v in INITIAL.items()}
