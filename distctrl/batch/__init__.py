"""Batch evaluation of the control law: the law of :mod:`distctrl.control.law` compiled with numba.

Importing this package never imports numba; :mod:`distctrl.batch.kernel` does (and raises a clear
ImportError when numba is missing). Check first with :func:`numba_available`.
"""
from __future__ import annotations

from importlib import import_module

_KERNEL_EXPORTS = ("run_setpos_loop", "run_setpos_loop_into", "run_setpos_batch", "pack_params",
                   "register_law", "compile_kernels")
__all__ = ["numba_available", *_KERNEL_EXPORTS]


def numba_available() -> bool:
    """True when numba can be imported (the batch kernel can be used). Imports numba if so."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def __getattr__(name):
    if name in _KERNEL_EXPORTS:
        return getattr(import_module(f"{__name__}.kernel"), name)
    raise AttributeError(name)
