"""Compile the batch kernels into numba's disk cache now, at install time (``make demo`` / ``make test``).

``python -m distctrl.batch.warm`` compiles every kernel a sweep, a tune and the batch API use (the
closed-loop kernels of :mod:`distctrl.batch.closed_loop` with the argument types ``run_batch`` passes,
the SET_POS kernels of :mod:`distctrl.batch.kernel` and the metrics pass of
:mod:`distctrl.batch.metrics_kernel`), so that the first ``distctrl sweep`` on a
fresh machine loads them (well under a second) instead of compiling for tens of seconds. It says on
stderr what it does; kernels already cached for the current sources are only loaded. Without numba
(``make demo`` installs the package without it) it says so and does nothing. Exit code 0 either way.
"""
from __future__ import annotations

import sys
import time


def _say(message: str) -> None:
    print(f"distctrl: {message}", file=sys.stderr, flush=True)


#: the compiling line (``python -m distctrl.batch.warm``, and the first sweep / tune when the cache is cold)
COMPILING = "compiling the batch kernels once for this machine (30-80 s; cached in {where}) ..."
_STATE = {"announced": False}


def _entries() -> tuple:
    """The kernels a sweep and a tune run (what :func:`warm` compiles)."""
    # the batch kernels import numba: loaded only when warming or running them
    from . import closed_loop as CL
    from . import kernel as K
    from . import metrics_kernel as MK

    return (CL.run_blocks, CL._closed_loop_batch, K.run_setpos_loop, K.run_setpos_loop_into,
            K.run_setpos_batch, MK.chunk_metrics)


def _example_loop(n: int = 16):
    """A closed loop of ``n`` cycles without a scenario (no sets packed)."""
    # the batch kernels import numba: loaded only when warming or running them
    import numpy as np

    from . import closed_loop as CL
    from .layout import PL_LEN, PL_RES, PL_SENSOR, SENSOR_DISTANCE

    plant = np.zeros(PL_LEN)
    plant[PL_SENSOR] = SENSOR_DISTANCE          # no probe to build (there is no scenario here)
    plant[PL_RES] = 0.0
    inputs = CL.LoopInputs(scenario=None, axis="Z", cycle_time=1e-3, n_cycles=n, k_on=0, mode=CL.MODE_SET_POS,
                           set_value=0.0, prog=np.zeros(n), surface=np.zeros(n), noise=np.zeros(n), plant=plant,
                           params=None)
    return inputs


def _example_inputs(n: int = 16):
    """:func:`_example_loop` and two packed sets (MOVING_AVERAGE for the vector blocks, EXPO_MEAN for the
    scalar loop): the arguments :func:`warm` compiles with."""
    # the batch kernels import numba: loaded only when warming or running them
    from ..base.kinds import FilterType
    from ..params.axis import AxisParameters
    from . import closed_loop as CL

    inputs = _example_loop(n)
    base = AxisParameters(enabled=True)
    sets = [base.replace(filter_type=FilterType.MOVING_AVERAGE), base.replace(filter_type=FilterType.EXPO_MEAN)]
    return inputs, CL.pack_sets(inputs, sets)


def _metrics_arguments(n: int = 16) -> tuple:
    """Arguments of :func:`distctrl.batch.metrics_kernel.chunk_metrics` of the types a sweep passes."""
    # the batch kernels import numba: loaded only when warming or running them
    import numpy as np

    from . import metrics_kernel as MK

    z, one = np.zeros(2), np.ones(2)
    return (np.zeros((2, n)), np.ones((2, n)), np.ones(n), 0, 0, 1e-3, 0.05, 1, 1, True, one, one, one, one,
            np.array([True, False]), one, z, one, np.empty((2, MK.N_FIG)), np.empty((2, n)), np.empty((2, n)))


def run_signatures() -> tuple:
    """``(kernel, argument types)`` of every kernel a sweep and a tune dispatch, as they dispatch them:
    the closed loop's vector blocks (:func:`distctrl.batch.closed_loop.run_blocks`, what ``run_batch``
    passes) and the metrics pass. Neither runs the SET_POS kernels nor the scalar-only loop
    (tests/tuning/test_cold_kernels.py compares this with what a sweep and a tune load)."""
    # the batch kernels import numba: loaded only when warming or running them
    import numpy as np

    from . import closed_loop as CL
    from . import metrics_kernel as MK
    from .layout import PACKED_LEN
    from .soa import BLOCK

    # the types alone matter here, not the values: arrays of the sweep's dtypes and layouts (packed rows
    # float64, block plan int64, as soa.plan_blocks makes them), no set packed (a sweep's sets go through
    # the columns, never through pack_sets: tests/tuning/test_sweep_golden.py)
    inputs, k = _example_loop(), 2
    n = inputs.n_cycles
    packed = np.zeros((k, PACKED_LEN))
    lanes, counts, rest = np.zeros((1, BLOCK), dtype=np.int64), np.ones(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
    blocks = (packed, lanes, counts, rest, inputs.plant, inputs.prog, inputs.surface, inputs.noise,
              np.empty((k, n)), np.empty((k, n)), np.empty((k, 2), dtype=np.int64))
    return tuple((d, tuple(d.typeof_pyval(a) for a in args))
                 for d, args in ((CL.run_blocks, blocks), (MK.chunk_metrics, _metrics_arguments())))


def is_cold() -> bool:
    """True when a kernel a sweep or a tune dispatches (:func:`run_signatures`) has, for the argument
    types it is given there, neither compiled code in this process nor a fresh disk-cache entry (the
    run compiles it); False without numba (nothing to compile). Kernels the run does not dispatch
    (the SET_POS ones) do not count: a sweep leaves them uncached, and the next one does not compile."""
    # the batch kernels import numba: loaded only when warming or running them
    from . import numba_available

    if not numba_available():
        return False
    # numba's caching machinery: loaded only with the kernels
    from .jitcache import is_cached

    return not all(is_cached(d, sig) for d, sig in run_signatures())


def announce_if_cold(say) -> bool:
    """Say :data:`COMPILING` (``say``: one line on stderr) when :func:`is_cold`; remembered, so that the
    evaluator does not say it again (:meth:`distctrl.tuning.runner.Evaluator.prepare_kernels`)."""
    if not is_cold():
        return False
    # the batch kernels import numba: loaded only when warming or running them
    from . import closed_loop as CL
    from .jitcache import cache_dir

    say(COMPILING.format(where=cache_dir(CL.run_blocks) or "memory only (no writable cache folder)"))
    _STATE["announced"] = True
    return True


def announced() -> bool:
    """True once :func:`announce_if_cold` said the compiling line in this process."""
    return _STATE["announced"]


def warm() -> bool:
    """Compile (or load) the kernels; False when numba is missing."""
    # the batch kernels import numba: loaded only when warming or running them
    from . import numba_available

    if not numba_available():
        _say("numba is not installed: no batch kernels to compile (distctrl sweep / tune need "
             "`pip install 'distctrl[batch]'`)")
        return False
    from ..control import law
    from . import closed_loop as CL
    from . import kernel as K
    from . import metrics_kernel as MK              # the sweep's metrics pass
    from .jitcache import cache_dir, is_cached

    fresh = all(is_cached(e) for e in _entries())
    where = cache_dir(CL.run_blocks) or "memory only (no writable cache folder)"
    if fresh:
        _say(f"the batch kernels are compiled already (cache: {where}); loading them")
    else:
        _say(COMPILING.format(where=where))
    t0 = time.perf_counter()
    inputs, packed = _example_inputs()
    CL.run_batch(inputs, packed, return_errors=True)
    CL.run_batch(inputs, packed, vectorised=False)
    K.compile_kernels()
    MK.chunk_metrics(*_metrics_arguments())
    assert law.FC_LEN == packed.shape[1] - CL.Q_LEN
    _say(f"batch kernels ready in {time.perf_counter() - t0:.1f} s")
    return True


def main() -> int:
    warm()
    return 0


if __name__ == "__main__":
    sys.exit(main())
