"""One OpenBLAS thread for the command line (issue 26).

``distctrl identify`` fits by least squares on tens of thousands of rows; numpy's OpenBLAS starts one
thread per core for them, and on a machine whose cores are busy with other work those threads spin
waiting for each other: 105 s wall for an identification that takes 9 s with one thread (2 cores,
under load). The other commands gain nothing from BLAS threads either (small matrices; tune and
batch run their own processes). threadpoolctl, which could change the pool at run time, is not a
dependency, so the limit is the environment default ``OPENBLAS_NUM_THREADS=1`` set by the entry module
of the ``distctrl`` script (:mod:`distctrl.cli`, also ``python -m distctrl``) before anything imports
numpy: OpenBLAS reads it once, when numpy loads it. A value the user set is kept. Programs that call
:func:`distctrl.workbench.identify.identify` themselves set it in their own environment (docs/identify.md).

This module imports nothing but :mod:`os`.
"""
from __future__ import annotations

import os

__all__ = ["BLAS_THREADS", "limit_blas_threads"]

#: the OpenBLAS thread count of the command line (unless the user set OPENBLAS_NUM_THREADS)
BLAS_THREADS = "1"


def limit_blas_threads() -> str:
    """Set ``OPENBLAS_NUM_THREADS`` to :data:`BLAS_THREADS` unless it is set; the value in force. Has an
    effect only before numpy is imported."""
    return os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS)
