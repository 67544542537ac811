"""The recorder's assembly of notification samples (distctrl.client.recorder): gaps are counted and
left NaN, late samples counted and not used, the rows where every signal runs."""
from __future__ import annotations

import math
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from distctrl.client.axes import Unit
from distctrl.client.recorder import Recorder, make_signal, summary

TICK = 10_000                                   # 1 ms in FILETIME ticks
ROOT = Path(__file__).resolve().parents[2]


def recorder() -> Recorder:
    rec = Recorder(target=None, unit=Unit("axis", 3, "Z"),
                   signals=[make_signal("command", 1e-4), make_signal("state", 1e-4)])
    rec.by_handle = {11: 0, 12: 1}
    return rec


def nm(mm: float) -> bytes:
    return struct.pack("<q", int(round(mm * 1e8)))


def test_gaps_are_nan_and_counted_late_samples_not_used():
    rec = recorder()
    t0 = 1_000_000
    for k in range(10):
        if k != 4:                                  # cycle 4 of the command is lost
            rec.raw.append((11, t0 + k * TICK, nm(30.0 + k * 0.01)))
        rec.raw.append((12, t0 + k * TICK, struct.pack("<I", 2)))
    rec.raw.append((11, t0 + 2 * TICK, nm(99.0)))   # late: a stamp not after the last one
    r = rec.result()
    assert r.rows == 10 and r.lost == {"command": 1, "state": 0} and r.late == 1
    assert math.isnan(r.data[4, 1]) and r.data[3, 1] == 30.03 and r.data[2, 1] == 30.02
    assert np.allclose(r.data[:, 0], np.arange(10) * 0.001)
    assert summary(r)["complete"] is False


def test_only_the_rows_where_every_signal_runs():
    rec = recorder()
    t0 = 5_000_000
    for k in range(10):
        rec.raw.append((11, t0 + k * TICK, nm(1.0)))
        if k >= 3:                                  # the second notification started 3 cycles later
            rec.raw.append((12, t0 + k * TICK, struct.pack("<I", 0)))
    r = rec.result()
    assert r.rows == 7 and r.lost_total == 0 and r.first_stamp == t0 + 3 * TICK
    assert summary(r)["complete"] is True


def test_ctrl_c_keeps_what_was_recorded(tmp_path):
    """machine record ended by SIGINT: exit code 130, the trace written (a served machine in a child)."""
    from .conftest import CTRL_C_ABLE, serve
    from distctrl.sim.scenario import load_scenario

    sm = serve(load_scenario(ROOT / "examples" / "scenarios" / "serve_z.toml"))
    try:
        out = tmp_path / "rec.csv"
        proc = subprocess.Popen([sys.executable, "-m", "distctrl", "machine", "record", "--ads", sm.net_id,
                                 "--ip", sm.host, "--axis", "Z=2", "--seconds", "300", "--out", str(out), "--json"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env=dict(os.environ, PYTHONPATH=str(ROOT)), **CTRL_C_ABLE)
        try:
            deadline = time.monotonic() + 120
            while sm.server.connections == 0 or not any(c for c in sm.server._sync_conns()):
                assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
                time.sleep(0.1)
            time.sleep(1.0)
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 130, (stdout, stderr)
        assert '"interrupted": true' in stdout and out.is_file()
        assert "Traceback" not in stderr
    finally:
        sm.stop()
