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


def is_cold() -> bool:
    """True when one of the kernels has neither compiled code in this process nor a fresh disk-cache entry
    (using it compiles); False without numba (nothing to compile)."""
    # the batch kernels import numba: loaded only when warming or running them
    from . import numba_available

    if not numba_available():
        return False
    # numba's caching machinery: loaded only with the kernels
    from .jitcache import is_cached

    return not all(is_cached(e) for e in _entries())


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
    # the batch kernels import numba: loaded only when warming or running them
    import numpy as np

    from ..control import law
    from . import closed_loop as CL
    from . import kernel as K
    from .jitcache import cache_dir, is_cached
    from .layout import PL_LEN, PL_RES, PL_SENSOR, SENSOR_DISTANCE

    entries = (CL.run_blocks, CL._closed_loop_batch, K.run_setpos_loop, K.run_setpos_loop_into,
               K.run_setpos_batch)
    fresh = all(is_cached(e) for e in entries)
    where = cache_dir(CL.run_blocks) or "memory only (no writable cache folder)"
    if fresh:
        _say(f"the batch kernels are compiled already (cache: {where}); loading them")
    else:
        _say(COMPILING.format(where=where))
    t0 = time.perf_counter()
    n = 16
    plant = np.zeros(PL_LEN)
    plant[PL_SENSOR] = SENSOR_DISTANCE          # no probe to build (there is no scenario here)
    plant[PL_RES] = 0.0
    inputs = CL.LoopInputs(scenario=None, axis="Z", cycle_time=1e-3, n_cycles=n, k_on=0, mode=CL.MODE_SET_POS,
                           set_value=0.0, prog=np.zeros(n), surface=np.zeros(n), noise=np.zeros(n), plant=plant,
                           params=None)
    # the batch kernels import numba: loaded only when warming or running them
    from ..base.kinds import FilterType
    from ..params.axis import AxisParameters

    base = AxisParameters(enabled=True)
    sets = [base.replace(filter_type=FilterType.MOVING_AVERAGE), base.replace(filter_type=FilterType.EXPO_MEAN)]
    packed = CL.pack_sets(inputs, sets)          # one set for the vector blocks, one for the scalar loop
    CL.run_batch(inputs, packed, return_errors=True)
    CL.run_batch(inputs, packed, vectorised=False)
    K.compile_kernels()
    from . import metrics_kernel as MK              # the sweep's metrics pass

    z, one = np.zeros(2), np.ones(2)
    MK.chunk_metrics(np.zeros((2, n)), np.ones((2, n)), np.ones(n), 0, 0, 1e-3, 0.05, 1, 1, True, one, one, one,
                     one, np.array([True, False]), one, z, one, np.empty((2, MK.N_FIG)), np.empty((2, n)),
                     np.empty((2, n)))
    assert law.FC_LEN == packed.shape[1] - CL.Q_LEN
    _say(f"batch kernels ready in {time.perf_counter() - t0:.1f} s")
    return True


def main() -> int:
    warm()
    return 0


if __name__ == "__main__":
    sys.exit(main())
