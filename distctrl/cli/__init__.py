"""Command-line interface: ``distctrl COMMAND`` (click). The group is :mod:`.main`; every command is one
module of this package (docs/architecture.md "Where to add a CLI command"); :mod:`.common` holds what
every command shares (exit codes, error lines, JSON output, numeric option types)."""
from .main import LAZY_COMMANDS, main

__all__ = ["main", "LAZY_COMMANDS"]
