"""Reliability suites (issue 8): short in ``make test``, long in ``make stress``.

``DISTCTRL_STRESS=1`` (set by ``make stress``) selects the long hypothesis profile and the long
loop counts; ``stress_scale()`` gives the factor for hand-written loops. Each suite reports its
figures (inputs tried, outcome classes, violations) through :func:`record_figures`; they are
written to ``$DISTCTRL_FIGURES`` (a directory) if set, and always printed in the ``-s`` output.
"""
from __future__ import annotations

import json
import os
from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, settings

STRESS = os.environ.get("DISTCTRL_STRESS", "") not in ("", "0")

settings.register_profile("reliability-short", max_examples=60, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("reliability-stress", max_examples=3000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
#: use as a decorator: ``@RELIABILITY`` (hypothesis settings for this run's length)
RELIABILITY = settings.get_profile("reliability-stress" if STRESS else "reliability-short")


def stress_scale(short: int, long: int) -> int:
    """Loop count for hand-written loops: ``short`` in make test, ``long`` in make stress."""
    return long if STRESS else short


_FIGURES: dict[str, Counter] = {}


def tally(suite: str, **counts: int) -> None:
    """Add counts to a suite's figures (accumulated over the whole pytest run)."""
    _FIGURES.setdefault(suite, Counter()).update(counts)


def record_figures() -> dict[str, dict[str, int]]:
    return {suite: dict(counter) for suite, counter in _FIGURES.items()}


def pytest_sessionfinish(session, exitstatus):  # noqa: ARG001 - pytest hook signature
    figures = record_figures()
    if not figures:
        return
    target = os.environ.get("DISTCTRL_FIGURES")
    if target:
        path = Path(target)
        path.mkdir(parents=True, exist_ok=True)
        (path / "reliability.json").write_text(json.dumps(figures, indent=2, sort_keys=True) + "\n")
    detail = ("tr_", "rule_", "hit_", "state_", "fault_", "error_")   # per-kind counts: in the JSON only
    for suite, counts in sorted(figures.items()):
        main = {k: v for k, v in counts.items() if not k.startswith(detail)}
        more = len(counts) - len(main)
        print(f"\n[reliability] {suite}: " + ", ".join(f"{k}={v}" for k, v in sorted(main.items()))
              + (f" (+{more} per-kind counts with DISTCTRL_FIGURES)" if more else ""))
