"""The ring buffers of the live page's hub (rows indexed by cycle) and the NC program's lines."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def ring_put(data: np.ndarray, cap: int, first: int, block: np.ndarray) -> int:
    """Write ``block`` (rows ``first``, ``first + 1``, ...) into the ring; the rows written so far."""
    if len(block) > cap:
        first += len(block) - cap
        block = block[-cap:]
    idx = (first + np.arange(len(block))) % cap
    data[idx] = block
    return first + len(block)


def ring_since(data: np.ndarray, cap: int, written: int, cursor: int, step: int) -> tuple[int, np.ndarray]:
    start = max(cursor, written - cap)
    if step > 1:
        start += (-start) % step
    if start >= written:
        return max(cursor, written), data[:0]
    idx = np.arange(start, written, step) % cap
    return written, data[idx]


def program_lines(scenario) -> dict[int, str]:
    """NC line number -> its text (for the machine view's "NC block")."""
    text = None
    if scenario.program_text is not None:
        text = scenario.program_text
    elif scenario.program_file is not None:
        try:
            text = Path(scenario.program_file).read_text(encoding="utf-8", errors="replace")
        except OSError:
            return {}
    if text is None:
        return {}
    return {i + 1: line.rstrip() for i, line in enumerate(text.splitlines())}
