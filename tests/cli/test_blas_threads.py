"""The command line runs OpenBLAS with one thread (issue 26): identify's least squares on 2 cores shared
with other work took 105 s with OpenBLAS's default thread pool (one thread per core, spinning while
they wait for each other) against 9 s with one thread. The limit is an environment default set by the
command line's entry module before anything imports numpy; a value the user set is kept.

Checked in a child process (numpy reads the setting once, when it loads OpenBLAS): the thread count
OpenBLAS itself reports (``openblas_get_num_threads`` of the library numpy loaded), not a timing.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PROBE = r"""
import ctypes, json, os, sys
import distctrl.cli                     # the entry module of the distctrl script (and python -m distctrl)
import numpy
numpy.linalg.lstsq(numpy.ones((50, 3)), numpy.ones(50), rcond=None)   # OpenBLAS is loaded and initialised
libs = []
with open("/proc/self/maps") as fh:
    for line in fh:
        parts = line.split()
        if len(parts) >= 6 and "openblas" in parts[-1].lower() and ".so" in parts[-1] and parts[-1] not in libs:
            libs.append(parts[-1])
threads, lib = None, None
for path in libs:
    dll = ctypes.CDLL(path)
    for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads"):
        fn = getattr(dll, name, None)
        if fn is not None:
            threads, lib = int(fn()), path
            break
    if lib:
        break
print(json.dumps({"threads": threads, "env": os.environ.get("OPENBLAS_NUM_THREADS"), "lib": lib}))
"""


def _probe(**env_extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    env.update(PYTHONPATH=str(ROOT), **env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=120,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_command_line_limits_openblas_to_one_thread():
    r = _probe()
    assert r["env"] == "1"
    if r["threads"] is None:                       # pragma: no cover - a numpy without OpenBLAS
        pytest.skip(f"no OpenBLAS thread count readable ({r['lib']})")
    assert r["threads"] == 1


def test_a_thread_count_the_user_set_is_kept():
    r = _probe(OPENBLAS_NUM_THREADS="2")
    assert r["env"] == "2"
    if r["threads"] is not None and (os.cpu_count() or 1) >= 2:
        assert r["threads"] == 2
