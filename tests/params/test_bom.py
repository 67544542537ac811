"""Text files saved with a UTF-8 byte-order mark (Windows editors) read like the same file without it
(new-user audit R3: a parameter list with a BOM was refused with "unknown parameter key
'\\ufeffkenngr.distc.kp'")."""
from __future__ import annotations

from pathlib import Path

import pytest

from distctrl.params.external_variables import load_external_variables
from distctrl.params.channel import CHANNEL_LIST
from distctrl.params.listfile import load_list

EX = Path(__file__).resolve().parents[2] / "examples"
BOM = b"\xef\xbb\xbf"


def _variants(tmp_path: Path, src: Path) -> list[Path]:
    """The file as it is, with a BOM, and with a BOM and CRLF line ends."""
    data = src.read_bytes()
    out = []
    crlf = data.replace(b"\n", b"\r\n")
    for name, body in (("plain", data), ("bom", BOM + data), ("bom_crlf", BOM + crlf)):
        p = tmp_path / f"{name}{src.suffix}"
        p.write_bytes(body)
        out.append(p)
    return out


@pytest.mark.parametrize("name, fmt", [("scenarios/z_plasma_plate.lis", None), ("axis_z_9_3.lis", None),
                                       ("channel_3d_12_8_3.lis", CHANNEL_LIST)])
def test_a_parameter_list_with_a_bom_loads_like_without(tmp_path, name, fmt):
    kw = {} if fmt is None else {"fmt": fmt}
    plain, *with_bom = [load_list(p, **kw) for p in _variants(tmp_path, EX / name)]
    for lst in with_bom:
        assert lst.params == plain.params


def test_a_latin1_list_with_a_bom_like_prefix_still_loads(tmp_path):
    """A Latin-1 comment after a BOM: the BOM is skipped, the rest read as Latin-1."""
    src = (EX / "scenarios" / "z_plasma_plate.lis").read_bytes()
    p = tmp_path / "l1.lis"
    p.write_bytes(BOM + b"# Abst\xe4nde\n" + src)
    q = tmp_path / "plain.lis"
    q.write_bytes(src)
    assert load_list(p).params == load_list(q).params


def test_an_external_variable_list_with_a_bom_loads_like_without(tmp_path):
    files = _variants(tmp_path, EX / "external_variables_12_8_4.lis")
    plain, *with_bom = [load_external_variables(p) for p in files]
    for v in with_bom:
        assert v == plain
