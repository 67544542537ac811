"""install_component (distctrl/linuxcnc/hal_env.py): LinuxCNC's module directory is one per machine, shared
by every checkout that builds distctrl's components; an installed module built from another source (an
older or newer checkout, whatever its file times) is rebuilt, the same source is not; `build` says which.
HalSession never touches a HAL it did not start (new-user audit M6) and says when it waits for the lock
(R1)."""
from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from distctrl.linuxcnc import hal_env
from distctrl.linuxcnc.hal_env import HalSession, LinuxCNCError

COMP = '''component probe_dc "a probe";
pin out float out;
function _;
license "GPL";
;;
FUNCTION(_) { out = %s; }
'''


def test_a_module_built_from_another_source_is_rebuilt_whatever_the_file_times(tmp_path, monkeypatch):
    src_dir, mod_dir = tmp_path / "src", tmp_path / "mod"
    src_dir.mkdir()
    mod_dir.mkdir()
    monkeypatch.setattr(hal_env, "HAL_DIR", src_dir)
    monkeypatch.setattr(hal_env, "MODULE_DIR", mod_dir)
    src = src_dir / "probe_dc.comp"
    src.write_text(COMP % "1.0")
    target = hal_env.install_component("probe_dc")
    first = target.read_bytes()
    built = target.stat().st_mtime_ns
    assert hal_env.install_component("probe_dc").stat().st_mtime_ns == built      # the same source: kept
    # another checkout's source, older than the installed module (as a checkout made before it was built)
    src.write_text(COMP % "2.0")
    os.utime(src, (1_000_000_000, 1_000_000_000))
    assert hal_env.install_component("probe_dc").read_bytes() != first


# ---- the bench never touches a HAL it did not start (new-user audit M6, R1; issue 39) ----------------



REAL_LOCK = Path(tempfile.gettempdir()) / "distctrl-linuxcnc" / "session.lock"


@contextmanager
def _machine_lock():
    """The machine-wide HAL lock, as every distctrl HAL session takes it: while a test plays "another
    HAL" (one it starts itself), no bench or test of another checkout runs a HAL on this machine."""
    REAL_LOCK.parent.mkdir(mode=0o755, exist_ok=True)
    with open(REAL_LOCK, "a+") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        yield


@pytest.fixture
def private_run_dir(tmp_path, monkeypatch):
    """The session under test takes its lock in a private directory (the test holds the real one) but
    talks to the machine's HAL (the real rtapi_app socket)."""
    env = hal_env.hal_environment()
    if "RTAPI_FIFO_PATH" in env:
        monkeypatch.setenv("RTAPI_FIFO_PATH", env["RTAPI_FIFO_PATH"])
        monkeypatch.setenv("RTAPI_UID", env["RTAPI_UID"])
    run = tmp_path / "run"
    monkeypatch.setattr(hal_env, "_RUN_DIR", run)
    return run


def _unload_ours() -> None:
    """halrun -U of the HAL a test started itself, and wait until its rtapi_app has gone."""
    subprocess.run(["halrun", "-U"], env=hal_env.hal_environment(), stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=120)
    for _ in range(600):
        if not [p for p, name in hal_env.hal_processes() if name == "rtapi_app"]:
            return
        time.sleep(0.05)


def _halcmd(*args: str) -> subprocess.CompletedProcess:
    with tempfile.TemporaryFile("w+") as out:     # rtapi_app inherits halcmd's stdout: not a pipe
        p = subprocess.run(["halcmd", *args], env=hal_env.hal_environment(), stdin=subprocess.DEVNULL,
                           stdout=out, stderr=subprocess.STDOUT, timeout=120)
        out.seek(0)
        p.stdout = out.read()
    return p


def test_the_bench_refuses_a_hal_it_did_not_start_and_leaves_it_running(private_run_dir):
    """A running LinuxCNC's HAL (played here by a HAL this test starts outside any session) is neither
    stopped nor unloaded: the session refuses in one line naming rtapi_app and its pid (on main it ran
    `halrun -U` and the other HAL's component was gone)."""
    with _machine_lock():
        try:
            assert _halcmd("loadrt", "and2", "names=not-distctrls-and").returncode == 0
            with pytest.raises(LinuxCNCError) as err:
                with HalSession(lock_timeout=5.0, foreign_grace=1.0):
                    pass
            msg = str(err.value)
            assert "\n" not in msg and "did not start" in msg
            assert re.search(r"rtapi_app \(pid \d+\)", msg), msg
            assert "not-distctrls-and.out" in _halcmd("show", "pin").stdout      # still there
        finally:
            _unload_ours()


def test_a_running_linuxcnc_is_refused_by_name_and_pid(private_run_dir, tmp_path):
    fake = tmp_path / "milltask"                    # LinuxCNC's task process, by its name
    shutil.copy("/bin/sleep", fake)
    proc = subprocess.Popen([str(fake), "60"])
    try:
        for _ in range(200):                        # its name is in /proc once it has exec'd
            if (proc.pid, "milltask") in hal_env.hal_processes():
                break
            time.sleep(0.05)
        refused = rf"milltask \(pid {proc.pid}\).*quit LinuxCNC"
        with _machine_lock(), pytest.raises(LinuxCNCError, match=refused):
            with HalSession(lock_timeout=5.0, foreign_grace=1.0):
                pass
    finally:
        proc.kill()
        proc.wait()


def test_a_leftover_of_its_own_killed_session_is_unloaded_and_said(private_run_dir):
    """Only what it can prove is its own: the recorded rtapi_app (pid and start time), its recorder gone."""
    said = []
    with _machine_lock():
        try:
            assert _halcmd("loadrt", "and2", "names=left-behind").returncode == 0
            rtapi = [pid for pid, name in hal_env.hal_processes() if name == "rtapi_app"]
            assert len(rtapi) == 1
            private_run_dir.mkdir(parents=True, exist_ok=True)
            (private_run_dir / "session.json").write_text(json.dumps({
                "rtapi_pid": rtapi[0], "rtapi_start": hal_env._proc_starttime(rtapi[0]),
                "owner_pid": 2 ** 22 + 7, "owner_start": 1}))          # a recorder that no longer runs
            with HalSession(lock_timeout=5.0, notify=said.append, foreign_grace=1.0) as hs:
                assert "left-behind" not in hs.cmd("show pin")
                hs.cmd("loadrt and2 names=ours")
            assert any("killed distctrl session left behind" in s and str(rtapi[0]) in s for s in said)
            assert not [p for p, name in hal_env.hal_processes() if name == "rtapi_app"]   # ours unloaded
            assert not (private_run_dir / "session.json").exists()
        finally:
            _unload_ours()


def test_waiting_for_the_lock_says_for_what_and_how_long(private_run_dir, capfd):
    """R1: a wait for the HAL lock is said at once (the lock's path, its holder's pid, the limit)."""
    private_run_dir.mkdir(parents=True)
    with open(private_run_dir / "session.lock", "a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        held.write(f"{os.getpid()}\n")
        held.flush()
        with pytest.raises(LinuxCNCError, match="for more than 0.5 s"):
            with HalSession(lock_timeout=0.5):
                pass
        assert (private_run_dir / "session.lock").read_text() == f"{os.getpid()}\n"   # the holder's, kept
    err = capfd.readouterr().err
    assert "waiting for another HAL session" in err
    assert str(private_run_dir / "session.lock") in err and f"pid {os.getpid()}" in err and "0.5 s" in err


def test_a_build_without_root_names_the_command_that_works_with_sudo(tmp_path, monkeypatch):
    """sudo resets PATH: `sudo distctrl` does not find a venv's distctrl; the message gives one that does."""
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "probe_dc.comp").write_text(COMP % "4.0")
    (tmp_path / "not-a-dir").write_text("")
    monkeypatch.setattr(hal_env, "HAL_DIR", tmp_path / "src")
    monkeypatch.setattr(hal_env, "MODULE_DIR", tmp_path / "not-a-dir" / "modules")
    with pytest.raises(LinuxCNCError) as err:
        hal_env.install_component("probe_dc")
    assert f"sudo {sys.executable} -m distctrl linuxcnc build" in str(err.value)
