"""The jinja2 environment of the workbench's HTML pages (the run report, the trace report, the
identify report): templates in ``distctrl/workbench/templates/``, shipped as package data.

Autoescaping is on: every ``{{ value }}`` is escaped unless it is markup (a macro's output). The
escaping is :func:`html.escape` with ``quote=True`` (``'`` → ``&#x27;``, ``"`` → ``&quot;``), the same
as the pages had before they moved to templates, applied through the environment's ``finalize``
(markupsafe's own escape writes ``&#39;`` and ``&#34;``, which would change every page).
``StrictUndefined``: a name missing from a template's context is an error, not an empty string.
"""
from __future__ import annotations

import functools
import html
import math
import os
from typing import Any

import numpy as np
from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup

__all__ = ["render", "environment", "escape", "fmt"]


def escape(value: Any) -> Markup:
    """``value`` as escaped text (:func:`html.escape`, quotes too); markup passes unchanged."""
    if hasattr(value, "__html__"):
        return Markup(value.__html__())
    return Markup(html.escape(str(value), quote=True))


def fmt(value: Any, digits: int = 6) -> str:
    """A value as text: floats with ``digits`` significant digits, None as an en dash."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return "NaN"
        return f"{v:.{digits}g}"
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


@functools.lru_cache(maxsize=1)
def environment() -> Environment:
    env = Environment(loader=PackageLoader("distctrl.workbench", "templates"), autoescape=True,
                      finalize=escape, undefined=StrictUndefined, keep_trailing_newline=True,
                      auto_reload=False)
    env.filters["fmt"] = fmt
    return env


def render(template: str, **context: Any) -> str:
    """The template ``distctrl/workbench/templates/<template>`` rendered with ``context``."""
    return environment().get_template(template).render(**context)
