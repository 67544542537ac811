"""pyproject.toml: no deprecated fields (a fresh `make test` prints no setuptools deprecation banner),
the field's libraries the project relies on are declared, and the control law installs and works with
numpy and scipy alone (the rest are extras: [sim], [ui], [ads], [batch], [parquet], [all])."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
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


EXTRAS = PYPROJECT["project"]["optional-dependencies"]


def _names(requirements) -> set[str]:
    """The distribution names of requirement strings ("numpy>=1.24" -> "numpy")."""
    out = set()
    for r in requirements:
        name = r.split(";")[0].strip()
        for sep in "<>=![ ":
            name = name.split(sep)[0]
        out.add(name.lower())
    return out


def test_python_control_is_a_dependency_of_the_sim_extra():
    """Frequency-domain analysis (distctrl margins) uses python-control, the field's library."""
    assert any(d.replace(" ", "").startswith("control>=") for d in EXTRAS["sim"])


def test_jinja2_is_a_dependency_of_the_sim_extra():
    """The HTML reports (distctrl/workbench/report.py, identify/output.py) render jinja2 templates."""
    assert any(d.replace(" ", "").startswith("jinja2>=") for d in EXTRAS["sim"])


def test_the_core_installs_numpy_and_scipy_only():
    """`pip install distctrl` gives the control law (README "Install"): numpy and scipy, nothing else."""
    assert _names(PYPROJECT["project"]["dependencies"]) == {"numpy", "scipy"}


def test_the_extras_carry_the_rest():
    """[sim]: the machine and the command line; [ui]: Bokeh; [ads]: pyads; [batch]: numba and dask;
    [parquet]: pyarrow; [all]: every one of them."""
    assert {"click", "rich", "lark", "matplotlib", "control", "jinja2", "tomli"} <= _names(EXTRAS["sim"])
    assert "bokeh" in _names(EXTRAS["ui"]) and "pyads" in _names(EXTRAS["ads"])
    assert {"numba", "dask"} <= _names(EXTRAS["batch"]) and "pyarrow" in _names(EXTRAS["parquet"])
    assert EXTRAS["all"] == ["distctrl[sim,ui,ads,batch,parquet]"]
    for extra in ("ui", "ads", "batch"):                 # each of these runs through the command line
        assert "distctrl[sim]" in EXTRAS[extra]


def test_every_extra_the_command_line_names_exists():
    """A missing dependency's message names an extra of pyproject.toml (distctrl/cli/extras.py)."""
    from distctrl.cli.extras import EXTRA_OF

    assert set(EXTRA_OF.values()) <= set(EXTRAS)
    for module, extra in EXTRA_OF.items():
        installed = _names(EXTRAS[extra]) | {n for e in EXTRAS[extra] if e.startswith("distctrl[")
                                             for n in _names(EXTRAS[e[len("distctrl["):-1]])}
        assert module in installed | {"tornado", "distributed"}, (module, extra)   # bokeh's and dask's own


#: an import hook that makes every optional dependency look not installed
_BLOCK = textwrap.dedent("""
    import importlib.abc, sys
    BLOCKED = {blocked!r}

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)

    sys.meta_path.insert(0, Block())
""")
OPTIONAL = ("click", "rich", "lark", "matplotlib", "bokeh", "tornado", "control", "numba", "dask",
            "distributed", "pyarrow", "pyads", "jinja2")
ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, *args: str, blocked=OPTIONAL) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", _BLOCK.format(blocked=set(blocked)) + textwrap.dedent(code),
                           *args], capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)


def test_the_control_law_works_without_any_extra():
    """The core (base, errors, params, control) imports and runs cycles with numpy and scipy only:
    SET_POS 30, ON over a surface 0.5 mm higher than programmed (%DIST_1), through a low-pass filter."""
    r = _python("""
        import sys
        from distctrl.control import Action, AxisDistanceController, Command, CycleInput, CycleOutput, FilterType
        from distctrl.control import law
        from distctrl.errors import ErrorId
        from distctrl.params import AxisParameters
        from distctrl import base

        p = AxisParameters(enabled=True, v_max=100.0, a_max=20000.0, max_act_value_change=1e6,
                           max_pos=50.0, min_pos=-50.0, filter_type=FilterType.LOWPASS,
                           low_pass_filter_fg_f0=100.0)
        c = AxisDistanceController(p, 0.001)
        inp, out = CycleInput(programmed_position=40.0, actual_position=40.0), CycleOutput()
        surface, actual = 30.5, 40.0
        inp.commands.extend([Command(set_pos=30.0), Command(Action.ON)])
        for _ in range(2000):
            inp.actual_position = actual
            reading = surface - actual                  # the probe: the sheet below the tool (mm)
            inp.sensor_increments = reading / p.sensor_mm_per_increment * (-1 if p.sensor_sign_reversal else 1)
            c.update(inp, out)
            actual = out.command_position
        assert out.hli_state == base.states.HliState.ACTIVE, out.hli_state
        assert abs(out.offset - 0.5) < 1e-6, out.offset               # the offset follows the surface
        print("offset", round(out.offset, 3))
        print("blocked loaded:", sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
    """)
    assert r.returncode == 0, r.stderr
    assert "blocked loaded: []" in r.stdout


def test_the_command_line_without_its_extra_says_which_to_install():
    """The `distctrl` script without click (the [sim] extra): one line, exit code 1, no traceback."""
    r = _python("from distctrl.cli import main; sys.argv = ['distctrl', '--help']; main()")
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "pip install 'distctrl[sim]'" in r.stderr and "click" in r.stderr


def test_a_command_without_its_extra_says_which_to_install():
    """`distctrl margins` without python-control: one error line naming the extra, exit code 1."""
    r = _python("from distctrl.cli import main; main()", "margins", "examples/scenarios/dist_1.toml",
                blocked=("control",))
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr and "pip install 'distctrl[sim]'" in r.stderr and "control" in r.stderr


def test_the_hal_components_and_lists_are_package_data():
    """Every file in distctrl/linuxcnc/hal/ (the components `linuxcnc build` compiles, the Z list
    `linuxcnc config` starts from) matches a package-data pattern: a wheel without them cannot build."""
    from fnmatch import fnmatch

    root = Path(__file__).resolve().parents[1] / "distctrl" / "linuxcnc"
    patterns = PYPROJECT["tool"]["setuptools"]["package-data"].get("distctrl.linuxcnc", [])
    files = sorted(p.relative_to(root).as_posix() for p in (root / "hal").iterdir() if p.is_file())
    assert files, "no HAL files found"
    assert [f for f in files if not any(fnmatch(f, pat) for pat in patterns)] == []


def test_the_workbench_templates_are_package_data():
    """Every file in distctrl/workbench/templates/ matches a package-data pattern (else a wheel ships
    without them and every report fails with TemplateNotFound)."""
    from fnmatch import fnmatch

    root = Path(__file__).resolve().parents[1] / "distctrl" / "workbench"
    patterns = PYPROJECT["tool"]["setuptools"]["package-data"]["distctrl.workbench"]
    files = sorted(p.relative_to(root).as_posix() for p in (root / "templates").iterdir() if p.is_file())
    assert files, "no templates found"
    assert [f for f in files if not any(fnmatch(f, pat) for pat in patterns)] == []


def test_the_live_page_without_bokeh_says_which_extra_to_install():
    """`distctrl serve --ui` without Bokeh (the [ui] extra): one error line naming it, exit code 1 (before:
    the page's thread died unseen, and the session served on without a page, exit code 0)."""
    r = _python("from distctrl.cli import main; main()", "serve", "examples/scenarios/serve_z.toml", "--ui",
                "--port", "0", "--ui-port", "0", "--no-discovery", "--duration", "0.5", blocked=("bokeh",))
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "Traceback" not in r.stderr and "pip install 'distctrl[ui]'" in r.stderr and "bokeh" in r.stderr
