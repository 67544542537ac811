"""The PLC task runs its programs in order (distctrl/plc/chain.py)."""
from __future__ import annotations

from distctrl.plc.chain import PlcChain, chain


def test_chain_runs_the_present_programs_in_order():
    seen = []

    def a(m, k):
        seen.append(("a", k))

    def b(m, k):
        seen.append(("b", k))

    assert chain() is None and chain(None, None) is None
    assert chain(None, a, None) is a
    task = chain(a, None, b)
    assert isinstance(task, PlcChain)
    task(object(), 3)
    assert seen == [("a", 3), ("b", 3)]
