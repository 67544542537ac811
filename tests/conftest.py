"""Hypothesis profile of the whole suite.

``make test`` (and CI) runs every property test derandomized: the examples are a fixed function of
the test, so a green run stays green and a failure reproduces on any machine. Random seeds broke
CI twice before this profile. ``make stress`` (``DISTCTRL_STRESS=1``) keeps random exploration, with
more examples (tests/reliability/conftest.py). No per-example deadline: a loaded CI machine may
stall one example for longer than hypothesis's default 200 ms without anything being wrong.
"""
from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("distctrl-ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("distctrl-stress", deadline=None, print_blob=True)
settings.load_profile("distctrl-stress" if os.environ.get("DISTCTRL_STRESS", "") not in ("", "0")
                      else "distctrl-ci")
