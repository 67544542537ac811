"""The batch kernels are compiled at install time (issue 27): ``make demo`` / ``make test`` run
``python -m distctrl.batch.warm``, after which a sweep's first call compiles nothing."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[2]


def test_the_makefile_warms_the_kernel_cache_when_it_installs():
    text = (ROOT / "Makefile").read_text()
    warm = re.findall(r"^\t\$\(PY\) -m distctrl\.batch\.warm\b", text, flags=re.M)
    assert warm, "no `$(PY) -m distctrl.batch.warm` recipe line in the Makefile"
    for target in ("demo:", "test:"):
        line = next(li for li in text.splitlines() if li.startswith(target))
        assert "$(WARM_STAMP)" in line, f"{target} does not depend on the warm stamp"


def test_warm_compiles_or_loads_every_kernel_a_sweep_needs_and_says_so(capsys):
    from distctrl.batch import closed_loop as CL
    from distctrl.batch import kernel as K
    from distctrl.batch.jitcache import is_cached
    from distctrl.batch.warm import warm

    assert warm() is True
    err = capsys.readouterr().err
    assert re.search(r"distctrl: (compiling the batch kernels once|the batch kernels are compiled already)", err)
    assert "batch kernels ready in" in err
    for entry in (CL.run_blocks, CL._closed_loop_batch, K.run_setpos_loop, K.run_setpos_batch):
        assert is_cached(entry), entry.__name__


def test_a_sweep_after_warm_compiles_no_new_variant_of_the_metrics_pass():
    """The sweep's metrics pass gets the argument types warm() compiled (a read-only ``wanted`` or
    ``adaptive`` array is another numba type: the first sweep after ``make demo`` compiled for 2-3 s)."""
    import numpy as np

    from distctrl.batch import closed_loop as CL
    from distctrl.batch import metrics_kernel as MK
    from distctrl.batch.warm import warm
    from distctrl.tuning.metrics import compute_metrics, limits_from_packed, wanted_distance

    assert warm() is True
    before = set(MK.chunk_metrics.signatures)
    inputs = CL.prepare(ROOT / "examples" / "scenarios" / "tune_sheet.toml", cycles=400)
    packed = CL.pack_sets(inputs, [inputs.params] * 3)
    offset, distance = CL.run_batch(inputs, packed, cycles=400)
    for wanted in (wanted_distance(inputs, 400), float(inputs.set_value)):
        compute_metrics(offset, distance, wanted, inputs.cycle_time, inputs.k_on, limits_from_packed(packed))
    assert set(MK.chunk_metrics.signatures) == before
