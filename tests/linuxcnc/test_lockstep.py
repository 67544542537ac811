"""The lock-step gate (distctrl/linuxcnc/hal/distctrl_lockstep.comp) in halrun: a period the plant does
not answer is counted as late, and a wait given up after the timeout as missed - never hidden."""
from __future__ import annotations

import time

from distctrl.linuxcnc.hal_env import HalSession, install_component


def _counts(hs):
    """seq, late, missed from one halcmd call (the thread keeps running between calls)."""
    out = {}
    for line in hs.cmd("show pin distctrl-lockstep.0").splitlines():
        parts = line.split()
        if len(parts) >= 5 and parts[-1].rsplit(".", 1)[-1] in ("seq", "late", "missed"):
            out[parts[-1].rsplit(".", 1)[-1]] = int(parts[3], 0)
    return out


def test_the_gate_counts_late_and_missed_periods_when_nobody_answers():
    install_component("distctrl_lockstep")
    with HalSession() as hs:
        hs.cmd("loadrt threads name1=servo-thread period1=1000000", "loadrt distctrl_lockstep",
               "addf distctrl-lockstep.0.wait servo-thread", "addf distctrl-lockstep.0.post servo-thread",
               "setp distctrl-lockstep.0.timeout 0.01", "setp distctrl-lockstep.0.enable 1", "start")
        deadline = time.monotonic() + 20.0
        c = _counts(hs)
        while c["missed"] < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
            c = _counts(hs)
        # period 1 ran (ack 0 == seq 0), every later one waited for an answer that never came
        assert c["missed"] >= 3
        assert c["late"] >= c["missed"] - 1       # the same wait counts both (missed first)
        assert c["seq"] >= c["missed"]


def test_the_gate_runs_free_when_disabled():
    install_component("distctrl_lockstep")
    with HalSession() as hs:
        hs.cmd("loadrt threads name1=servo-thread period1=1000000", "loadrt distctrl_lockstep",
               "addf distctrl-lockstep.0.wait servo-thread", "addf distctrl-lockstep.0.post servo-thread", "start")
        deadline = time.monotonic() + 20.0
        c = _counts(hs)
        while c["seq"] < 50 and time.monotonic() < deadline:
            time.sleep(0.05)
            c = _counts(hs)
        assert c["seq"] >= 50 and c["late"] == 0 and c["missed"] == 0
