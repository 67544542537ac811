"""The per-cycle path is optimised for speed (issue 15, bench/bench_run.py); behaviour must not change.

Every trace value of a few example runs is fingerprinted bit for bit (SHA-256 of the float64 trace
array, the column names, the events and the metrics), against the fingerprints recorded before
the speed work of issue 15. A speed change that alters one bit of one trace value fails here.

A deliberate change of behaviour (a model, a law, a scenario) changes a fingerprint: check the
traces, then print the new fingerprints with ``python tests/sim/test_run_fingerprint.py`` and
put them into FINGERPRINTS with the commit that explains the change.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from distctrl.sim.runner import run

SCN = Path(__file__).resolve().parents[2] / "examples" / "scenarios"

#: scenario -> (trace rows, SHA-256 of the run's trace and outcome); recorded on main c93d848; plasma_thc
#: again when its noise stopped counting as an oscillation (the same trace, no warning 900032); all four
#: again when the metrics got excluded_off_sheet_cycles / excluded_process_cycles (audit M5; the traces
#: are bit-identical, plasma_thc's error no longer counts the 40 cycles over its kerf: RMS 2.41 -> 0.081 mm)
FINGERPRINTS = {
    "const_dist_sheet": (4750,
                         "8a71ee09029dbd414d0cf124b10b0913b582e20231b69bc1ba4cb3014fc971e0"),
    "plasma_thc": (6834,
                         "a3e9218b1a86c95329e993e60d5de2527d25a2fc6eed5b536202cce06996694d"),
    "capacitive_edge": (3779,
                         "b81bafcfb095fb961e5858c0202d2490f5933dbbb470829cac82910d449bb2f4"),
    "resonant_z": (3434,
                         "5699471b04b9a8d440c0c178367c7713a6bbfc70fa07a9d8286d1f979bcc67d7"),
}


def fingerprint(name: str) -> tuple[int, str]:
    r = run(SCN / f"{name}.toml")
    data = np.ascontiguousarray(r.trace.data, dtype=np.float64)
    h = hashlib.sha256(data.tobytes())
    h.update(json.dumps({"columns": list(r.trace.columns), "errors": r.errors, "warnings": r.warnings,
                         "metrics": r.metrics, "cycles": r.cycles, "outcome": r.outcome,
                         "final_state": r.final_state}, sort_keys=True, default=repr).encode())
    return data.shape[0], h.hexdigest()


@pytest.mark.parametrize("name", sorted(FINGERPRINTS))
def test_trace_is_bit_identical_to_the_recorded_one(name):
    rows, digest = fingerprint(name)
    assert (rows, digest) == FINGERPRINTS[name], (
        f"{name}: the run's trace or outcome changed (rows {rows}, fingerprint {digest}); a speed change "
        "must not change behaviour (see the module docstring for a deliberate change)")


if __name__ == "__main__":
    for n in sorted(FINGERPRINTS):
        print(f'    "{n}": {fingerprint(n)},')
