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
#: again when its noise stopped counting as an oscillation (the same trace, no warning 900032)
FINGERPRINTS = {
    "const_dist_sheet": (4750,
                         "f9194af789ae71ae6cb0b2ef1f98a136108eb9b59feff2804062776248a7aaa7"),
    "plasma_thc": (6834,
                         "14df0c1510b8446ed522e04249993d135b406587ca0e1a985a07ccee348274c2"),
    "capacitive_edge": (3779,
                         "6a2ff952c4ad75968feb7fcabf4b197d9cdc8485392a03f3384cd1eedfaf2495"),
    "resonant_z": (3434,
                         "a7c3a6dc7ab586a0b526c2567cba1519ffe5f4092ba26660f95094b24222ee4a"),
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
