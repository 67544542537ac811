"""Text files as people save them: UTF-8 with or without a byte-order mark (Windows editors write one),
or Latin-1 (ISG editors). Every reader of a list, a scenario or an NC program decodes with
:func:`decode_text`, so a BOM is never read as a first character of a key (new-user audit R3)."""
from __future__ import annotations

import codecs
import os
from pathlib import Path

__all__ = ["decode_text", "read_text"]


def decode_text(data: bytes, fallback: str | None = "latin-1") -> str:
    """``data`` as text: a UTF-8 BOM skipped, then UTF-8, else ``fallback`` (None: the
    UnicodeDecodeError is raised, its positions counted after the BOM)."""
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        if fallback is None:
            raise
        return data.decode(fallback)


def read_text(path: str | os.PathLike, fallback: str | None = "latin-1") -> str:
    """The file's text (:func:`decode_text`); OSError as :meth:`Path.read_bytes` raises it."""
    return decode_text(Path(path).read_bytes(), fallback)
