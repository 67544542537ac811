"""Command-line interface: ``distctrl COMMAND`` (click). The group is :mod:`.main`; every command is one
module of this package (docs/architecture.md "Where to add a CLI command"); :mod:`.common` holds what
every command shares (exit codes, error lines, JSON output, numeric option types).

The command line comes with the extra ``[sim]`` (``pip install 'distctrl[sim]'``); without it the
``distctrl`` script says so in one line (:mod:`.extras`)."""
from __future__ import annotations

import sys

from .blas import limit_blas_threads
from .extras import missing_dependency

limit_blas_threads()      # before anything imports numpy: one OpenBLAS thread (blas.py, issue 26)

try:
    from .main import LAZY_COMMANDS, main
except ModuleNotFoundError as _exc:           # click & co. are the [sim] extra's: one line, no traceback
    _message = missing_dependency(_exc)
    if _message is None:
        raise
    LAZY_COMMANDS: dict = {}

    def main() -> None:
        """The ``distctrl`` script without its dependencies: one line and exit code 1."""
        sys.stderr.write(f"error: the distctrl command: {_message}\n")
        raise SystemExit(1)

__all__ = ["main", "LAZY_COMMANDS"]
