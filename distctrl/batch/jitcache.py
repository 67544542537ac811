"""The compiled kernels are cached on disk once per machine, and know what they are compiled from.

numba's ``cache=True`` saves a kernel's machine code beside its source file (``__pycache__/*.nbi``
index and ``*.nbc`` data; git ignores ``__pycache__/``), or, when that folder cannot be written (an
installed, read-only package), in the user's cache folder (``~/.cache/numba`` or ``$XDG_CACHE_HOME``);
``NUMBA_CACHE_DIR`` moves it anywhere. The next process loads it in well under a second instead of
compiling for tens of seconds.

numba checks the freshness of a cached kernel by the content of the *one* file that defines it. The
kernels here are made of more: the law (:mod:`distctrl.control.law`) and the plant
(:mod:`distctrl.sim.physics`) are compiled into them, and their constants (error IDs, column
layouts) are frozen in. :func:`cached` therefore keys the cache on the content of every file the
kernels are built from (:data:`SOURCES`): a change of the law recompiles, never reuses stale code.
"""
from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

from numba.core.caching import CompileResultCacheImpl, FunctionCache

__all__ = ["SOURCES", "sources_stamp", "cached", "is_cached", "cache_dir"]

_PKG = Path(__file__).resolve().parents[1]          # the distctrl package
#: the files (relative to the distctrl package; globs allowed) the compiled kernels are made of
SOURCES = ("base/*.py", "batch/*.py", "control/*.py", "sim/physics.py", "errors/__init__.py")


@functools.lru_cache(maxsize=None)
def _file_hash(path: str, mtime_ns: int, size: int) -> bytes:   # keyed on stat: re-hashed after a change
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).digest()


def sources_stamp() -> str:
    """sha256 over the names and contents of the :data:`SOURCES` files."""
    h = hashlib.sha256()
    for pattern in SOURCES:
        for p in sorted(_PKG.glob(pattern)):
            st = p.stat()
            h.update(p.relative_to(_PKG).as_posix().encode())
            h.update(_file_hash(str(p), st.st_mtime_ns, st.st_size))
    return h.hexdigest()


class _Locator:
    """numba's locator (where the cache lives) with a source stamp over all of :data:`SOURCES`."""

    def __init__(self, inner):
        self._inner = inner

    def get_source_stamp(self):
        return (self._inner.get_source_stamp(), sources_stamp())

    def __getattr__(self, name):
        return getattr(self._inner, name)


class _Impl(CompileResultCacheImpl):
    def __init__(self, py_func):
        super().__init__(py_func)
        self._locator = _Locator(self._locator)


class KernelCache(FunctionCache):
    """numba's per-function cache, stamped with :func:`sources_stamp`."""

    _impl_class = _Impl


def cached(dispatcher):
    """Decorator over ``@njit(cache=True, ...)``: the dispatcher's on-disk cache, keyed on all of
    :data:`SOURCES` (module docstring). Without a place to write (no locator), numba's own cache stays."""
    try:
        dispatcher._cache = KernelCache(dispatcher.py_func)
    except RuntimeError:           # pragma: no cover - numba found no writable cache location
        pass
    return dispatcher


def is_cached(dispatcher, argtypes: tuple | None = None) -> bool:
    """True when the dispatcher has compiled code in this process, or a fresh entry in its disk cache
    (for the current sources and numba version): using it will not compile. ``argtypes`` (numba types,
    as the dispatcher types the arguments of a call): for exactly that signature; None: for any."""
    if argtypes is None and dispatcher.signatures:
        return True
    if argtypes is not None and tuple(argtypes) in dispatcher.overloads:
        return True
    cache = getattr(dispatcher, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    if cache_file is None:
        return False
    try:
        index = cache_file._load_index()
        if argtypes is None:
            return bool(index)
        # numba's own key of a cached overload: the signature and this machine's code generator
        return cache._index_key(tuple(argtypes), dispatcher.targetctx.codegen()) in index
    except Exception:              # noqa: BLE001 - an unreadable index is a miss
        return False


def cache_dir(dispatcher) -> str | None:
    """The folder the dispatcher's compiled code is cached in (None: no disk cache)."""
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "cache_path", None)
    return os.fspath(path) if path else None
