"""V.E. variable names as the PLC programs use them: one spelling with the ``V.E.`` prefix."""
from __future__ import annotations

__all__ = ["ve_name"]


def ve_name(name: str) -> str:
    """``name`` with the ``V.E.`` prefix (given with or without it, in any case)."""
    return name if name[:4].upper() == "V.E." else f"V.E.{name}"
