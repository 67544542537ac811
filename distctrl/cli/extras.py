"""Which extra of the distribution installs an optional dependency (pyproject.toml's
``[project.optional-dependencies]``; README "Install"): a missing one is one line naming the extra,
never a traceback. This module imports nothing that an extra installs (the command line uses it before
click is known to be there)."""
from __future__ import annotations

__all__ = ["EXTRA_OF", "missing_dependency"]

#: top-level module -> the extra that installs it
EXTRA_OF = {
    "click": "sim", "rich": "sim", "lark": "sim", "tomli": "sim", "matplotlib": "sim", "control": "sim",
    "jinja2": "sim",
    "bokeh": "ui", "tornado": "ui",
    "pyads": "ads",
    "numba": "batch", "dask": "batch", "distributed": "batch",
    "pyarrow": "parquet",
}


def missing_dependency(exc: ImportError) -> str | None:
    """The one-line message for an optional dependency that is not installed, or None when ``exc`` is
    not about one of them (a real error, re-raised by the caller)."""
    name = (getattr(exc, "name", None) or "").split(".")[0]
    extra = EXTRA_OF.get(name)
    if not isinstance(exc, ModuleNotFoundError) or extra is None:
        return None
    return (f"this needs {name}, which is not installed: pip install 'distctrl[{extra}]' "
            "(or 'distctrl[all]' for everything)")
