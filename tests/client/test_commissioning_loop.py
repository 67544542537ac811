"""Issue 28's whole commissioning loop against ``distctrl serve`` (its ServedMachine, run faster than
real time): a plant the client does not know (a 52 Hz resonance, a probe 3 cycles late with noise)
is excited by ``distctrl excite``'s program, recorded over ADS by ``distctrl machine record``,
identified, tuned on the fitted twin, written by ``distctrl machine write --yes``; on the served
machine the tracking error of the reference run falls and the loop stays stable; the backup
restores the old values.

The served program waits for ``V.E.GO`` (written over ADS, port 851) before each part and sets
``V.E.DONE`` after it: reference run (old values), excitation, reference run (tuned values), a short
activation that adopts the restored values.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from .conftest import CTRL_C_ABLE, pyads, serve

HERE = Path(__file__).parent / "loop"
ROOT = Path(__file__).resolve().parents[2]
SPEED = 3.0

REFERENCE = """G0 X0 Z31.5
Z[DIST_CTRL ON CONST_DIST SET_DIST=1]
G1 X160 F9000
Z[DIST_CTRL OFF]
G0 Z40
G0 X0"""


T0 = [time.monotonic()]


def mark(what: str) -> None:
    print(f"{time.monotonic() - T0[0]:7.1f} s  {what}", file=sys.stderr)


def distctrl(*args, check=True):
    """The command in this process (click's runner): its exit code, stdout and stderr."""
    from click.testing import CliRunner

    from distctrl.cli import main

    r = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    if check:
        assert r.exit_code == 0, (args, r.exit_code, r.stdout[-2000:], r.stderr[-2000:])
    mark(" ".join(str(a) for a in args[:2]))
    return r


def distctrl_child(*args):
    """The command in a child process with one BLAS thread: identify's least squares wait on OpenBLAS's
    spinning threads on a loaded 2-core machine (105 s instead of 9 s measured at a load average of 25)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "distctrl", *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=900)
    assert r.returncode == 0, (args, r.returncode, r.stdout[-2000:], r.stderr[-2000:])
    mark(" ".join(str(a) for a in args[:2]))
    return r


def loop_program(excite_nc: str) -> str:
    body = [ln for ln in excite_nc.splitlines() if ln and not ln.startswith("%") and ln.split()[-1] != "M30"]
    parts = ["%LOOP", "G90 G0 X0 Y0 Z40"]
    parts += ["#WAIT FOR V.E.GO == 1", REFERENCE, "V.E.DONE = 1"]
    parts += ["#WAIT FOR V.E.GO == 2", *body, "V.E.DONE = 2"]
    parts += ["#WAIT FOR V.E.GO == 3", REFERENCE, "V.E.DONE = 3"]
    parts += ["#WAIT FOR V.E.GO == 4", "G0 Z31.5", "Z[DIST_CTRL ON CONST_DIST SET_DIST=1]", "#TIME 0.05",
              "Z[DIST_CTRL OFF]", "G0 Z40", "V.E.DONE = 4", "M30"]
    return "\n".join(parts) + "\n"


class Plc:
    def __init__(self, sm):
        self.conn = pyads.Connection(sm.net_id, 851, sm.host)
        self.conn.open()
        self.conn.set_timeout(5000)

    def go(self, n: int) -> None:
        self.conn.write_by_name("V.E.GO", float(n), pyads.PLCTYPE_LREAL)

    def done(self) -> float | None:
        try:
            return self.conn.read_by_name("V.E.DONE", pyads.PLCTYPE_LREAL)
        except pyads.ADSError:            # a busy machine: a late answer is asked again
            return None

    def wait_done(self, n: int, timeout: float = 300.0) -> None:
        deadline = time.monotonic() + timeout
        while self.done() != n:
            assert time.monotonic() < deadline, f"the served program did not reach DONE = {n}"
            time.sleep(0.05)


def sync_notifications(sm) -> int:
    """The cycle-synchronous notifications the served machine runs now (all connections)."""
    with sm.lock:
        return sum(1 for conn in sm.server._sync_conns() for n in list(conn.notifications.values()) if n.every)


def reference_run(target, plc, n: int) -> dict:
    """One reference run recorded over ADS: tracking error (target_deviation) while ACTIVE."""
    from distctrl.client.axes import Unit
    from distctrl.client.recorder import Recorder, make_signal

    unit = Unit("axis", 3, "Z")
    rec = Recorder(target, unit, [make_signal("deviation", 1e-4), make_signal("state", 1e-4)], max_delay_s=0.02)
    rec.start()
    try:
        plc.go(n)
        plc.wait_done(n)
        time.sleep(0.2)
    finally:
        rec.stop()
    r = rec.result()
    dev, state = r.data[:, 1], r.data[:, 2]
    active = state == 2
    assert r.lost_total == 0 and active.sum() > 500, (r.lost, active.sum())
    d = dev[active]
    settled = d[300:]          # after the approach (1.5 -> 1 mm): the sheet's wave and its 0.5 mm step
    return {"rms": float(np.sqrt(np.mean(d ** 2))), "max": float(np.max(np.abs(d))),
            "settled_rms": float(np.sqrt(np.mean(settled ** 2))),
            "errors": int(np.sum((state >= 6) & (state <= 12))),
            "tail_rms": float(np.sqrt(np.mean(d[-300:] ** 2)))}


def test_whole_commissioning_loop(tmp_path):
    from distctrl.client.axes import Unit, read_parameters
    from distctrl.client.target import Target
    from distctrl.sim.scenario import load_scenario

    T0[0] = time.monotonic()
    # 1. excite: the program for identify, within the axis limits
    excite_nc = tmp_path / "excite.nc"
    distctrl("excite", "--axis", "Z", "--work", 31.5, "--safe", 40, "--min", 25, "--max", 50, "--v-max", 300,
             "--a-max", 20000, "--steps", 0.3, "--step-count", 4, "--chirp", "1-150", "--chirp-seconds", 2,
             "--amplitude", 0.04, "--ramp", "31.0:32.0", "--ramp-speed", 0.5, "--large-step", 2,
             "--surface", 30, "--out", excite_nc)
    (tmp_path / "loop.nc").write_text(loop_program(excite_nc.read_text()))
    for f in ("plant.toml", "plant.lis"):
        (tmp_path / f).write_text((HERE / f).read_text())
    sm = serve(load_scenario(tmp_path / "plant.toml"), speed=SPEED)
    ads = ["--ads", sm.net_id, "--ip", sm.host, "--timeout", "5"]
    try:
        target = Target(sm.net_id, 551, sm.host, timeout=5.0).open()
        plc = Plc(sm)
        z = Unit("axis", 3, "Z")
        old = read_parameters(target, z)

        # 2. the reference run with the old values
        before = reference_run(target, plc, 1)
        mark(f'reference run 1 {before}')

        # 3. machine record of the excitation (ended by Ctrl-C once the program says it is done)
        rec_csv = tmp_path / "excite_rec.csv"
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.Popen([sys.executable, "-m", "distctrl", "machine", "record", *ads, "--axis", "Z=3",
                                 "--seconds", "600", "--signals", "command,actual,sensor", "--out", str(rec_csv),
                                 "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                **CTRL_C_ABLE)
        try:
            deadline = time.monotonic() + 120     # until its 3 notifications run (a busy machine: seconds)
            while sync_notifications(sm) < 3:
                assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
                time.sleep(0.1)
            time.sleep(0.2)
            plc.go(2)
            plc.wait_done(2, timeout=300)
            time.sleep(0.3)
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 130, (proc.returncode, out, err)
        mark('machine record')
        recorded = json.loads(out)
        assert recorded["interrupted"] and recorded["lost_total"] == 0 and recorded["late"] == 0, recorded
        assert recorded["seconds"] > 5.0, recorded

        # the served NC plays the chirp at its written rate (issue 28): the recorded command reaches the top
        # of the 1-150 Hz band (one block per cycle; before, ~3 cycles per block, it stopped near 50 Hz)
        rec = np.genfromtxt(rec_csv, delimiter=",", names=True)
        cmd = rec["Zcommand"] - 31.5                     # (not `z`: that is the axis unit read below)
        nz = np.flatnonzero(np.abs(cmd) > 1e-9)
        a, b = nz[:-1], nz[1:]
        up = (cmd[a] < 0) & (cmd[b] > 0) & (np.abs(cmd[a]) < 0.05) & (np.abs(cmd[b]) < 0.05)
        f_top = np.sort(1.0 / np.diff(rec["t"][a[up]]))[-5:]
        assert np.median(f_top) > 120.0, f_top

        if os.environ.get("DISTCTRL_LOOP_KEEP"):          # keep the recording for a look at it
            import shutil
            for f in (rec_csv, rec_csv.with_name(rec_csv.name + ".meta.json")):
                shutil.copy(f, os.environ["DISTCTRL_LOOP_KEEP"])
        # 4. identify the plant from the recording, with the reference as the template
        for f in ("reference.toml", "reference.nc"):
            (tmp_path / f).write_text((HERE / f).read_text())
        fitted = tmp_path / "fitted"
        r = distctrl_child("identify", rec_csv, "--command", "Z.command", "--actual", "Z.actual", "--sensor", "Z.sensor",
                     "--actual-sampled", "start", "--surface", 30.0, "--template", tmp_path / "reference.toml",
                     "--out", fitted, "--json")
        ident = json.loads(r.stdout)
        drive = ident["drive"]
        assert drive["resonance_hz"] == pytest.approx(52.0, rel=0.15), drive
        assert ident["sensor"]["delay"] == pytest.approx(0.003, abs=0.0015), ident["sensor"]

        # 5. tune on the fitted twin
        tuned = tmp_path / "tuned"
        distctrl_child("tune", fitted / "fitted.toml", "--budget", 40, "--local", "--no-robustness", "--out", tuned)

        # 6. machine write: the plan, then --yes. tuned-objects.lis keeps the machine's filter (issue 39);
        # an older tune writes only tuned.lis, which machine write refuses when its filter differs
        lis = tuned / "tuned-objects.lis"
        if not lis.exists():
            lis = tuned / "tuned.lis"
            r = distctrl("machine", "write", *ads, "--axis", "Z=3", lis, "--json", check=False)
            if r.exit_code == 1 and "changes the filter" in r.stderr:
                pytest.skip("tune chose another filter and wrote no tuned-objects.lis: machine write refused "
                            "tuned.lis, as it must (issue 39, M3)")
        plan = json.loads(distctrl("machine", "write", *ads, "--axis", "Z=3", lis, "--json").stdout)
        assert plan["outcome"] == "planned" and plan["changes"], plan
        assert read_parameters(target, z) == old               # nothing written without --yes
        wrote = json.loads(distctrl("machine", "write", *ads, "--axis", "Z=3", lis, "--yes", "--json").stdout)
        assert wrote["outcome"] == "written", wrote
        backup = Path(wrote["backup"])
        assert backup.is_file()
        new = {c["parameter"]: c["new"] for c in wrote["changes"]}

        # 7. the reference run with the tuned values (adopted on its activation): better and stable
        after = reference_run(target, plc, 3)
        mark(f'reference run 2 {after}')
        now = read_parameters(target, z)
        assert all(now[k] == pytest.approx(v) for k, v in new.items()), (now, new)
        assert after["errors"] == 0
        assert after["rms"] < before["rms"], (before, after, new)
        # tune keeps gain margin >= 2 and phase margin >= 30 deg on the twin and its variants within identify's
        # tolerances (docs/tuning.md), so it gives up part of the tracking gain for safety: 0.060 -> 0.050 mm
        # here (0.040 mm without that constraint)
        assert after["settled_rms"] < 0.95 * before["settled_rms"], (before, after, new)
        assert after["tail_rms"] < 0.05, after

        # 8. restore the backup; the next activation adopts the old values again
        restored = json.loads(distctrl("machine", "write", *ads, "--axis", "Z=3", backup, "--yes", "--json").stdout)
        assert restored["outcome"] == "written"
        plc.go(4)
        plc.wait_done(4)
        back = read_parameters(target, z)
        assert all(back[k] == pytest.approx(old[k]) for k in new), (back, old)
        target.close()
        plc.conn.close()
    finally:
        sm.stop()
