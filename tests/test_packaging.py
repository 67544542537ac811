"""pyproject.toml: no deprecated fields (a fresh `make test` prints no setuptools deprecation banner)
and the field's libraries the project relies on are declared."""
from __future__ import annotations

from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib          # type: ignore[no-redef]

PYPROJECT = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text(encoding="utf-8"))


def test_the_license_is_an_spdx_expression_not_the_deprecated_table():
    """setuptools >= 77 (PEP 639) deprecates `license = { text = ... }`; the string form needs it."""
    assert PYPROJECT["project"]["license"] == "MIT"
    assert any(r.replace(" ", "").startswith("setuptools>=77") for r in PYPROJECT["build-system"]["requires"])
    assert not any("License ::" in c for c in PYPROJECT["project"].get("classifiers", []))


def test_python_control_is_a_dependency():
    """Frequency-domain analysis (distctrl margins) uses python-control, the field's library."""
    assert any(d.replace(" ", "").startswith("control>=") for d in PYPROJECT["project"]["dependencies"])
