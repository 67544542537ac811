"""Surface model: known values of every feature, vectorised path, normals, config validation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from distctrl.errors import DistCtrlError
from distctrl.errors.config import ConfigError
from distctrl.sim.surface import (Flat, HeightMap, Ramp, Sine, Step, Surface, TiltedPlane,
                                  surface_from_config)

EPS = 1e-9


# --- features: known values -------------------------------------------------------------------------
def test_flat_is_base():
    s = Surface(20.0, [Flat()])
    assert s.height(1.0, 2.0) == 20.0
    assert s.normal(1.0, 2.0) == (0.0, 0.0, 1.0)


def test_step_at_and_around_edge():
    s = Surface(20.0, [Step(at=50.0, height=2.8)])
    assert s.height(50.0 - EPS, 0.0) == 20.0
    assert s.height(50.0, 0.0) == pytest.approx(22.8)  # the edge already has the new height
    assert s.height(50.0 + EPS, 0.0) == pytest.approx(22.8)
    assert s.height(1e6, 0.0) == pytest.approx(22.8)
    assert s.gradient(50.0, 0.0) == (0.0, 0.0)  # vertical edge: slope taken as 0


def test_block_obstacle_of_width():
    s = Surface(0.0, [Step(at=50.0, height=2.8, width=10.0)])
    assert s.height(49.999, 0) == 0.0
    assert s.height(50.0, 0) == 2.8
    assert s.height(55.0, 0) == 2.8
    assert s.height(59.999, 0) == 2.8
    assert s.height(60.0, 0) == 0.0  # footprint [at, at + width)
    assert s.height(70.0, 0) == 0.0


def test_step_with_finite_ramp_edge():
    s = Surface(0.0, [Step(at=10.0, height=2.0, ramp_length=4.0)])
    assert s.height(10.0, 0) == 0.0
    assert s.height(11.0, 0) == pytest.approx(0.5)
    assert s.height(12.0, 0) == pytest.approx(1.0)
    assert s.height(14.0, 0) == pytest.approx(2.0)
    assert s.gradient(12.0, 0) == pytest.approx((0.5, 0.0))
    assert s.gradient(15.0, 0) == (0.0, 0.0)


def test_block_with_ramps_is_symmetric_trapezoid():
    f = Step(at=0.0, height=1.0, width=10.0, ramp_length=2.0)
    assert [f.z(u, 0) for u in (0.0, 1.0, 2.0, 5.0, 8.0, 9.0, 10.0)] == pytest.approx(
        [0.0, 0.5, 1.0, 1.0, 1.0, 0.5, 0.0])
    assert f.gradient(1.0, 0)[0] == pytest.approx(0.5)
    assert f.gradient(9.0, 0)[0] == pytest.approx(-0.5)


def test_step_along_y_ignores_x():
    f = Step(at=5.0, height=-1.0, axis="Y")
    assert f.z(100.0, 4.0) == 0.0
    assert f.z(-100.0, 6.0) == -1.0


def test_ramp():
    f = Ramp(start=0.0, end=10.0, height=1.0, axis="X")
    assert [f.z(u, 0) for u in (-5, 0, 2.5, 10, 20)] == pytest.approx([0, 0, 0.25, 1, 1])
    assert f.gradient(5.0, 0) == pytest.approx((0.1, 0.0))


def test_sine_quarter_wavelength():
    f = Sine(amplitude=0.5, wavelength=40.0)
    assert f.z(0.0, 0) == pytest.approx(0.0, abs=1e-15)
    assert f.z(10.0, 0) == pytest.approx(0.5)
    assert f.z(20.0, 0) == pytest.approx(0.0, abs=1e-12)
    assert f.z(30.0, 0) == pytest.approx(-0.5)
    assert Sine(0.5, 40.0, phase=math.pi / 2).z(0.0, 0) == pytest.approx(0.5)
    assert f.gradient(0.0, 0)[0] == pytest.approx(0.5 * 2 * math.pi / 40.0)
    assert Sine(0.5, 40.0, axis="Y").z(0.0, 10.0) == pytest.approx(0.5)


def test_tilted_plane_slopes_and_angles():
    f = TiltedPlane(sx=0.1, sy=-0.2, x0=10.0)
    assert f.z(20.0, 5.0) == pytest.approx(1.0 - 1.0)
    assert f.gradient(0, 0) == (0.1, -0.2)
    about_y = TiltedPlane.from_angle(45.0, about="Y")  # right-hand rule: +X goes down
    assert about_y.sx == pytest.approx(-1.0) and about_y.sy == 0.0
    about_x = TiltedPlane.from_angle(45.0, about="X")  # +Y goes up
    assert about_x.sy == pytest.approx(1.0) and about_x.sx == 0.0


def test_normal_of_tilted_plane_points_up():
    s = Surface(0.0, [TiltedPlane(sx=1.0, sy=0.0)])
    nx, ny, nz = s.normal(3.0, 4.0)
    assert (nx, ny, nz) == pytest.approx((-1 / math.sqrt(2), 0.0, 1 / math.sqrt(2)))
    assert nx * nx + ny * ny + nz * nz == pytest.approx(1.0)


def test_heightmap_bilinear_2x2():
    hm = HeightMap([0.0, 10.0], [0.0, 20.0], [[0.0, 1.0], [2.0, 4.0]])
    assert hm.z(0, 0) == 0.0 and hm.z(10, 0) == 1.0 and hm.z(0, 20) == 2.0 and hm.z(10, 20) == 4.0
    assert hm.z(5, 10) == pytest.approx(7.0 / 4.0)  # centre: mean of the corners
    assert hm.z(2.5, 0) == pytest.approx(0.25)
    assert hm.z(0, 5) == pytest.approx(0.5)
    # bilinear: (1-tx)(1-ty)z00 + tx(1-ty)z10 + (1-tx)ty z01 + tx ty z11 at tx=0.25, ty=0.75
    assert hm.z(2.5, 15) == pytest.approx(0.25 * 0.25 * 1.0 + 0.75 * 0.75 * 2.0 + 0.25 * 0.75 * 4.0)
    # gradient inside the cell: dz/dx = ((1-ty)(z10-z00) + ty(z11-z01))/dx
    assert hm.gradient(2.5, 15) == pytest.approx(((0.25 * 1 + 0.75 * 2) / 10, (0.75 * 2 + 0.25 * 3) / 20))


def test_heightmap_clamps_outside_grid():
    hm = HeightMap([0.0, 10.0], [0.0, 20.0], [[0.0, 1.0], [2.0, 4.0]])
    assert hm.z(-100, -100) == 0.0
    assert hm.z(100, 100) == 4.0
    assert hm.z(100, 10) == pytest.approx(2.5)  # x clamped to 10, y interpolated
    assert hm.gradient(100, 10) == pytest.approx((0.0, 3.0 / 20))


def test_heightmap_from_csv(tmp_path):
    p = tmp_path / "map.csv"
    p.write_text("# a comment\ny\\x, 0, 10, 20\n0, 0, 1, 2\n\n5, 1, 2, 3\n")
    hm = HeightMap.from_csv(p)
    assert hm.xs.tolist() == [0, 10, 20] and hm.ys.tolist() == [0, 5]
    assert hm.z(15, 2.5) == pytest.approx(2.0)


def test_height_array_matches_scalar(tmp_path):
    hm = HeightMap([0.0, 5.0, 12.0], [-3.0, 4.0], [[0.0, 0.3, -0.2], [0.5, 0.1, 0.4]])
    s = Surface(20.0, [Step(50, 2.8, width=10, ramp_length=1.0), Ramp(0, 100, 1.0, axis="Y"),
                       Sine(0.5, 40.0, phase=0.3), TiltedPlane(0.01, -0.02), hm, Flat()])
    rng = np.random.default_rng(1)
    xs = rng.uniform(-20, 120, 500)
    ys = rng.uniform(-20, 120, 500)
    za = s.height_array(xs, ys)
    assert za.shape == (500,)
    assert za == pytest.approx([s.height(x, y) for x, y in zip(xs, ys)], abs=1e-12)
    grid = s.height_array(np.linspace(0, 100, 11)[None, :], np.linspace(0, 50, 6)[:, None])
    assert grid.shape == (6, 11)


def test_normal_matches_central_differences():
    hm = HeightMap([0.0, 5.0, 12.0], [-3.0, 4.0], [[0.0, 0.3, -0.2], [0.5, 0.1, 0.4]])
    s = Surface(0.0, [Sine(0.5, 40.0), TiltedPlane(0.05, -0.02), hm, Ramp(-10, 10, 2.0, axis="Y")])
    h = 1e-6
    for x, y in [(1.0, 1.0), (7.0, -1.0), (3.3, 2.2)]:
        gx = (s.height(x + h, y) - s.height(x - h, y)) / (2 * h)
        gy = (s.height(x, y + h) - s.height(x, y - h)) / (2 * h)
        n = np.array([-gx, -gy, 1.0]) / math.sqrt(1 + gx * gx + gy * gy)
        assert s.normal(x, y) == pytest.approx(tuple(n), abs=1e-6)


# --- configuration -------------------------------------------------------------------------------
def test_surface_from_config_example(tmp_path):
    (tmp_path / "map.csv").write_text(",0,10\n0,0,0\n10,1,1\n")
    cfg = {"base": 20.0, "features": [
        {"type": "step", "axis": "X", "at": 50.0, "height": 2.8},
        {"type": "sine", "axis": "X", "amplitude": 0.5, "wavelength": 40.0},
        {"type": "heightmap", "file": "map.csv"},
        {"type": "ramp", "axis": "y", "start": 0, "end": 10, "height": 1},
        {"type": "tilted_plane", "angle_deg": 0.0, "about": "X"},
        {"type": "flat"}]}
    s = surface_from_config(cfg, base_dir=tmp_path)
    assert s.height(10.0, 5.0) == pytest.approx(20.0 + 0.5 + 0.5 + 0.5)
    assert s.height(60.0, 10.0) == pytest.approx(20.0 + 2.8 + 0.0 + 1.0 + 1.0, abs=1e-12)
    assert surface_from_config({}).height(0, 0) == 0.0


def _err(cfg, base_dir="."):
    with pytest.raises(ConfigError) as info:
        surface_from_config(cfg, base_dir)
    assert isinstance(info.value, DistCtrlError)
    return str(info.value)


def test_config_error_names_key_value_and_range():
    msg = _err({"features": [{"type": "flat"}, {"type": "sine", "amplitude": 1.0, "wavelength": -4.0}]})
    assert "surface.features[1].wavelength" in msg and "-4.0" in msg and "[1e-06, inf)" in msg


F0 = "surface.features[0]"


@pytest.mark.parametrize("cfg, key, shown", [
    ({"bse": 1.0}, "surface.bse", "base"),
    ({"base": "20"}, "surface.base", "number"),
    ({"base": True}, "surface.base", "number"),
    ({"base": float("nan")}, "surface.base", "finite"),
    ({"features": {"type": "flat"}}, "surface.features", "list"),
    ({"features": [{"type": "bump"}]}, F0 + ".type", "'step'"),
    ({"features": [{"axis": "X"}]}, F0 + ".type", "'sine'"),
    ({"features": [{"type": "step", "at": 1.0}]}, F0 + ".height", "required"),
    ({"features": [{"type": "step", "at": 1.0, "height": 1.0, "hight": 2}]}, F0 + ".hight",
     "ramp_length"),
    ({"features": [{"type": "step", "at": 1.0, "height": 1.0, "axis": "Z"}]}, F0 + ".axis", "'X'"),
    ({"features": [{"type": "step", "at": 1.0, "height": 1.0, "width": 0}]}, F0 + ".width", "(0, inf)"),
    ({"features": [{"type": "step", "at": 1.0, "height": 1.0, "width": 2, "ramp_length": 1.5}]},
     F0 + ".ramp_length", "[0, 1]"),
    ({"features": [{"type": "ramp", "start": 5, "end": 5, "height": 1}]}, F0 + ".end", "(5, inf)"),
    ({"features": [{"type": "sine", "amplitude": -1, "wavelength": 4}]}, F0 + ".amplitude", "[0, inf)"),
    ({"features": [{"type": "tilted_plane", "sx": 0.1, "angle_deg": 3}]}, F0 + ".sx", "not both"),
    ({"features": [{"type": "tilted_plane", "angle_deg": 90}]}, F0 + ".angle_deg", "(-90, 90)"),
    ({"features": [{"type": "tilted_plane", "about": "X"}]}, F0 + ".angle_deg", "angle_deg"),
    ({"features": [{"type": "heightmap", "file": 3}]}, F0 + ".file", "path"),
    ({"features": [{"type": "heightmap", "file": "missing.csv"}]}, F0 + ".file", "readable"),
    ({"features": ["step"]}, "surface.features[0]", "table"),
])
def test_config_errors_name_the_key(cfg, key, shown):
    msg = _err(cfg)
    assert msg.startswith(key + ":") or msg.startswith(key + " ("), msg
    assert shown in msg


def test_heightmap_csv_errors_name_file_and_line(tmp_path):
    (tmp_path / "bad.csv").write_text(",0,10\n0,0,0\n10,1,oops\n")
    msg = _err({"features": [{"type": "heightmap", "file": "bad.csv"}]}, tmp_path)
    assert F0 + ".file" in msg and "bad.csv:3" in msg and "'oops'" in msg
    (tmp_path / "short.csv").write_text(",0,10\n0,0,0\n10,1\n")
    msg = _err({"features": [{"type": "heightmap", "file": "short.csv"}]}, tmp_path)
    assert "short.csv:3" in msg and "2 heights" in msg
    (tmp_path / "order.csv").write_text(",10,0\n0,0,0\n10,1,1\n")
    msg = _err({"features": [{"type": "heightmap", "file": "order.csv"}]}, tmp_path)
    assert "order.csv" in msg and "increasing" in msg


_junk = st.one_of(st.none(), st.booleans(), st.text(max_size=3),
                  st.floats(allow_nan=True, allow_infinity=True),
                  st.integers(-10, 10), st.lists(st.integers(), max_size=2))


@settings(max_examples=150, deadline=None)
@given(key=st.sampled_from(["amplitude", "wavelength", "phase", "axis"]), value=_junk)
def test_config_either_builds_or_names_the_key(key, value):
    feature = {"type": "sine", "amplitude": 0.5, "wavelength": 40.0, key: value}
    cfg = {"features": [{"type": "flat"}, feature]}
    try:
        s = surface_from_config(cfg)
    except ConfigError as exc:
        assert str(exc).startswith(f"surface.features[1].{key}:")
        assert repr(value) in str(exc)
    else:
        assert math.isfinite(s.height(1.0, 2.0))


def test_holes_inside_outside_and_on_the_rim():
    from distctrl.sim.surface import Holes
    h = Holes([[10.0, 0.0], [40.0, 25.0]], diameter=8.0, height=-30.0)
    s = Surface(20.0, [h])
    assert s.height(10.0, 0.0) == -10.0 and s.height(13.9, 0.0) == -10.0      # inside (radius 4)
    assert s.height(14.0, 0.0) == 20.0 and s.height(10.0, 4.1) == 20.0        # the rim and beyond: sheet
    assert s.height(40.0, 28.0) == -10.0 and s.height(25.0, 12.0) == 20.0
    assert s.gradient(10.0, 0.0) == (0.0, 0.0)
    xs, ys = np.meshgrid(np.linspace(0.0, 50.0, 101), np.linspace(-5.0, 30.0, 71))
    want = np.vectorize(s.height)(xs, ys)
    assert np.array_equal(s.height_array(xs, ys), want) and (want < 0).sum() > 50
    assert h.near(10.0, 6.5, 3.0) and not h.near(10.0, 7.5, 3.0)             # rim 4 mm from the centre


def test_holes_from_config_and_their_errors():
    s = surface_from_config({"base": 30.0, "features": [
        {"type": "holes", "centers": [[0.0, 0.0], [20.0, 0.0]], "diameter": 10.0, "height": -40.0}]})
    assert s.height(20.0, 1.0) == -10.0 and s.height(10.0, 0.0) == 30.0
    for holes, key, words in [
            ({"centers": [], "diameter": 5.0, "height": -1.0}, "centers", "non-empty"),
            ({"centers": [[1.0]], "diameter": 5.0, "height": -1.0}, "centers[0]", "pair"),
            ({"centers": [[1.0, "a"]], "diameter": 5.0, "height": -1.0}, "centers[0][1]", "number"),
            ({"centers": [[1.0, 2.0]], "diameter": 0.0, "height": -1.0}, "diameter", "(0, inf)"),
            ({"centers": [[1.0, 2.0]], "diameter": 5.0}, "height", "required")]:
        with pytest.raises(ConfigError) as exc:
            surface_from_config({"features": [{"type": "holes", **holes}]})
        assert exc.value.key == "surface.features[0]." + key and words in str(exc.value), str(exc.value)
