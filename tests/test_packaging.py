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


def test_jinja2_is_a_dependency():
    """The HTML reports (distctrl/workbench/report.py, identify/output.py) render jinja2 templates."""
    assert any(d.replace(" ", "").startswith("jinja2>=") for d in PYPROJECT["project"]["dependencies"])


def test_the_workbench_templates_are_package_data():
    """Every file in distctrl/workbench/templates/ matches a package-data pattern (else a wheel ships
    without them and every report fails with TemplateNotFound)."""
    from fnmatch import fnmatch

    root = Path(__file__).resolve().parents[1] / "distctrl" / "workbench"
    patterns = PYPROJECT["tool"]["setuptools"]["package-data"]["distctrl.workbench"]
    files = sorted(p.relative_to(root).as_posix() for p in (root / "templates").iterdir() if p.is_file())
    assert files, "no templates found"
    assert [f for f in files if not any(fnmatch(f, pat) for pat in patterns)] == []
