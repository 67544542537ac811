"""bench/compare_instructions.py: its harness runs every case in a checkout (here this one, without
valgrind, which only counts what the harness does), and the per-cycle arithmetic is right."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

from tests.scripts import load_script

ROOT = pathlib.Path(__file__).resolve().parents[2]


cmp = load_script("bench/compare_instructions.py")


@pytest.mark.parametrize("case", sorted(cmp.SIZES))
def test_the_harness_runs_each_case_in_a_checkout(case, tmp_path):
    size = cmp.SIZES[case][0] if case.startswith("run") else 200
    proc = subprocess.run([sys.executable, "-c", cmp.HARNESS, str(ROOT), case, str(size)], capture_output=True,
                          text=True, env={**os.environ, "CMP_TMP": str(tmp_path)}, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    cycles = int(proc.stdout.split("cycles")[-1])
    assert cycles == size if not case.startswith("run") else cycles > 1000


def test_every_group_names_known_cases():
    assert {c for g in cmp.GROUPS.values() for c in g} == set(cmp.SIZES)


def test_instructions_per_cycle_drops_the_start_up(monkeypatch):
    # the short and the long workload share the start-up: only the extra cycles are counted
    counts = {0: (5_000_000, 1000), 2: (5_000_000 + 2 * 1000 * 90_000, 1000)}
    monkeypatch.setattr(cmp, "count", lambda checkout, case, size, tmp: counts[size])
    assert cmp.per_cycle("x", "run_rigid", "/tmp")["instructions_per_cycle"] == 90_000
    counts = {2_000: (7_000_000, 2000), 8_000: (7_000_000 + 6_000 * 1_000, 8000)}
    monkeypatch.setattr(cmp, "count", lambda checkout, case, size, tmp: counts[size])
    assert cmp.per_cycle("x", "served", "/tmp")["instructions_per_cycle"] == 1_000
