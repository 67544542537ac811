"""The repository's scripts (bench/, tools/) loaded as modules in tests: they are files beside the package,
not modules of it."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_script(relative: str, name: str | None = None, *, registered: bool = False, beside: bool = False):
    """Run ``ROOT / relative`` as a module named ``name`` (default: the file's stem) and return it.

    ``registered``: put it in ``sys.modules`` first (dataclasses look their module up while the file runs);
    ``beside``: the script imports modules of its own folder (put on ``sys.path`` once)."""
    path = ROOT / relative
    if beside and str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(name or path.stem, path)
    module = importlib.util.module_from_spec(spec)
    if registered:
        sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
