"""Filter workbench (`distctrl filters`): specs, the synthetic obstacle, metrics, recordings, plot, CLI."""
from __future__ import annotations

import csv
import math
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from distctrl.control.filters import FilterConfig
from distctrl.base.kinds import FilterType
from distctrl.errors import DistCtrlError
from distctrl.trace import Trace
from distctrl.workbench.filters import (DEFAULT_SPECS, FilterResult, FilterSpecError, RecordingError,
                                        RecordingWarning, WorkbenchError, WorkbenchWarning, compare,
                                        default_configs, find_edges, format_table, load_recording,
                                        obstacle_signal, parse_filter_spec, plot_overlay, signal_noise_rms,
                                        write_results_csv)
from distctrl.cli.filters import filters

T = 0.001
MA = FilterType.MOVING_AVERAGE


def one(cfg: FilterConfig, x, t, edges, cycle_time=T) -> FilterResult:
    (r,) = compare(x, t, [cfg], cycle_time, edges)
    return r


# ----------------------------------------------------------------------------------------------- specs

def test_a_value_list_expands_into_one_config_per_value():
    cfgs = parse_filter_spec("MOVING_AVERAGE:n_cycles=10,20,40")
    assert [c.filter_type for c in cfgs] == [MA] * 3
    assert [c.n_cycles for c in cfgs] == [10, 20, 40]
    assert all(isinstance(c.n_cycles, int) for c in cfgs)


def test_a_value_list_runs_until_the_next_key():
    cfgs = parse_filter_spec("KALMAN_MA:n_cycles=30,kalman_sigma=100,1000")
    assert [(c.filter_type, c.n_cycles, c.kalman_sigma) for c in cfgs] == [
        (FilterType.KALMAN_MA, 30, 100.0), (FilterType.KALMAN_MA, 30, 1000.0)]


def test_several_lists_give_the_cartesian_product():
    cfgs = parse_filter_spec("KALMAN_EXPO:n_cycles=10,20,kalman_sigma=10,100,smoothing_factor=0.3")
    assert [(c.n_cycles, c.kalman_sigma, c.smoothing_factor) for c in cfgs] == [
        (10, 10.0, 0.3), (10, 100.0, 0.3), (20, 10.0, 0.3), (20, 100.0, 0.3)]


def test_aliases_case_blanks_and_several_specs():
    a = parse_filter_spec(" expo_mean : n_cycles = 30 , smooth_fact = 0.1 , 0.3 ")
    assert [(c.filter_type, c.n_cycles, c.smoothing_factor) for c in a] == [
        (FilterType.EXPO_MEAN, 30, 0.1), (FilterType.EXPO_MEAN, 30, 0.3)]
    b = parse_filter_spec("KALMAN_MA:n_cycles=30,sigma=1000;LOWPASS:low_pass_filter_order=2,low_pass_filter_fg_f0=30")
    assert [c.filter_type for c in b] == [FilterType.KALMAN_MA, FilterType.LOWPASS]
    assert b[0].kalman_sigma == 1000.0 and (b[1].order, b[1].fg_f0) == (2, 30.0)


def test_lowpass_default_and_unnamed_parameters_keep_the_config_defaults():
    (lp,) = parse_filter_spec("LOWPASS:order=2,fg_f0=30")
    assert (lp.filter_type, lp.order, lp.fg_f0) == (FilterType.LOWPASS, 2, 30.0)
    (d,) = parse_filter_spec("DEFAULT")
    assert d == FilterConfig(FilterType.DEFAULT)
    (ma,) = parse_filter_spec("MOVING_AVERAGE")
    assert ma == FilterConfig(MA)


def test_the_default_comparison_has_nine_configs_at_the_documents_values():
    labels = [c.label() for c in default_configs(T)]
    assert len(labels) == 9 and len(set(labels)) == 9
    assert "KALMAN_MA(n_cycles=30, kalman_sigma=1000)" in labels          # FCT-M3 §4.4
    assert "KALMAN_MA(n_cycles=20, kalman_sigma=1000)" in labels          # FCT-M3 §9.3
    assert "KALMAN_EXPO(n_cycles=30, smoothing_factor=0.3, kalman_sigma=1000)" in labels   # §4.5


def test_the_default_comparison_shows_the_documented_kalman_behaviour_on_the_obstacle():
    """FCT-M3 §4.4.1 / TF5200 §4.4.1 / P-AXIS-00783 on the built-in 2.8 mm obstacle (noise free): each
    Kalman filter reacts sooner than the moving average of the same n, overshoots, more with n, and
    more with sigma."""
    t, x, e = obstacle_signal(noise_std=0.0)
    r = {res.label: res for res in compare(x, t, default_configs(T), T, e)}
    for n in (20, 30):
        ma = r[f"MOVING_AVERAGE(n_cycles={n})"]
        for sigma in (4, 1000):
            k = r[f"KALMAN_MA(n_cycles={n}, kalman_sigma={sigma})"]
            assert k.dead_time_s < ma.dead_time_s and k.delay_s < ma.delay_s
            assert k.overshoot_mm > 0.5 and ma.overshoot_mm == 0.0
        assert r[f"KALMAN_MA(n_cycles={n}, kalman_sigma=1000)"].overshoot_mm > \
            r[f"KALMAN_MA(n_cycles={n}, kalman_sigma=4)"].overshoot_mm
    assert r["KALMAN_MA(n_cycles=30, kalman_sigma=1000)"].overshoot_mm > \
        r["KALMAN_MA(n_cycles=20, kalman_sigma=1000)"].overshoot_mm
    expo = r["EXPO_MEAN(n_cycles=30, smoothing_factor=0.3)"]
    kexpo = r["KALMAN_EXPO(n_cycles=30, smoothing_factor=0.3, kalman_sigma=1000)"]
    assert kexpo.delay_s < expo.delay_s and kexpo.overshoot_mm > 0.1


@pytest.mark.parametrize("text, words", [
    ("", ["syntax"]),
    ("   ", ["syntax"]),
    ("FOO", ["unknown filter type", "MOVING_AVERAGE", "KALMAN_EXPO"]),
    ("PASS", ["unknown filter type"]),
    ("MOVING_AVERAGE:", ["nothing after", "n_cycles"]),
    ("MOVING_AVERAGE:10", ["before any key"]),
    ("MOVING_AVERAGE:n_cycles=", ["empty value", "0 <= n < 100"]),
    ("MOVING_AVERAGE:n_cycles=10,", ["empty value"]),
    ("MOVING_AVERAGE:n_cycles=abc", ["not a number", "0 <= n < 100"]),
    ("MOVING_AVERAGE:n_cycles=2.5", ["not an integer"]),
    ("MOVING_AVERAGE:n_cycles=nan", ["not finite"]),
    ("MOVING_AVERAGE:n_cycles=100", ["P-AXIS-00413", "0 <= n < 100"]),
    ("MOVING_AVERAGE:n_cycle=10", ["unknown key", "did you mean n_cycles", "allowed keys"]),
    ("MOVING_AVERAGE:order=2", ["no effect on MOVING_AVERAGE", "allowed keys for MOVING_AVERAGE: n_cycles"]),
    ("MOVING_AVERAGE:n_cycles=1,n_cycles=2", ["given twice"]),
    ("DEFAULT:n_cycles=5", ["no effect on DEFAULT", "n = 4"]),
    ("EXPO_MEAN:smoothing_factor=0", ["P-AXIS-00784", "0 < value <= 1"]),
    ("KALMAN_MA:sigma=0.5", ["P-AXIS-00783", "1 <= value <= 10000"]),
    ("LOWPASS:order=7", ["P-AXIS-00507", "0..6"]),
    ("LOWPASS:order=2,fg_f0=0", ["fg_f0", "Nyquist"]),
])
def test_bad_specs_raise_a_distctrl_error_that_says_what_is_allowed(text, words):
    with pytest.raises(FilterSpecError) as info:
        parse_filter_spec(text)
    assert isinstance(info.value, DistCtrlError) and isinstance(info.value, ValueError)
    msg = str(info.value)
    for w in words:
        assert w in msg, msg


def test_the_cutoff_is_checked_against_nyquist_when_the_cycle_time_is_known():
    assert parse_filter_spec("LOWPASS:order=2,fg_f0=600")[0].fg_f0 == 600.0      # no cycle time: later
    with pytest.raises(FilterSpecError, match="Nyquist"):
        parse_filter_spec("LOWPASS:order=2,fg_f0=600", cycle_time=T)
    with pytest.raises(FilterSpecError, match="P-AXIS-00508"):       # and compare() checks it too
        t, x, e = obstacle_signal()
        compare(x, t, parse_filter_spec("LOWPASS:order=2,fg_f0=600"), T, e)


# ----------------------------------------------------------------------------------------------- signal

def test_obstacle_signal_edges_height_and_timing():
    t, x, edges = obstacle_signal(noise_std=0.0)
    assert t.size == x.size == 1500 and np.allclose(np.diff(t), T)
    assert edges.tolist() == [0.5, 1.0]
    top = (t >= 0.5) & (t < 1.0)
    assert np.all(x[top] == 2.8) and np.all(x[~top] == 0.0)
    t2, x2, e2 = obstacle_signal(0.002, noise_std=0.0, flat_before=0.2, top=0.3, flat_after=0.1, height=-2.8,
                                 level=5.0)
    assert np.allclose(np.diff(t2), 0.002) and np.allclose(e2, [0.2, 0.5]) and t2.size == 300
    assert x2.min() == pytest.approx(2.2) and x2.max() == 5.0


def test_obstacle_signal_with_ramps_has_its_edges_at_the_ramp_middle():
    t, x, edges = obstacle_signal(noise_std=0.0, ramp_time=0.02)
    i1, i2 = np.searchsorted(t, edges)
    assert x[i1] == pytest.approx(1.4) and x[i2] == pytest.approx(1.4)
    assert x[i1 - 11] == 0.0 and x[i1 + 11] == pytest.approx(2.8)


def test_obstacle_signal_noise_is_seeded_gaussian_with_the_given_std():
    t, clean, _ = obstacle_signal(noise_std=0.0)
    _, x, _ = obstacle_signal()
    assert np.std(x - clean) == pytest.approx(0.05, rel=0.10)
    assert np.array_equal(x, obstacle_signal()[1])                      # seed 1 by default
    assert not np.array_equal(x, obstacle_signal(seed=2)[1])
    _, x3, _ = obstacle_signal(noise_std=0.2, seed=5)
    assert np.std(x3 - clean) == pytest.approx(0.2, rel=0.10)


@pytest.mark.parametrize("kw", [{"cycle_time": 0.0}, {"noise_std": -1.0}, {"top": 0.0}, {"ramp_time": 0.6}])
def test_obstacle_signal_rejects_bad_arguments(kw):
    with pytest.raises(WorkbenchError, match="allowed"):
        obstacle_signal(**kw)


# ----------------------------------------------------------------------------------------------- metrics

@pytest.mark.parametrize("n", [4, 10, 11, 20, 40])
def test_moving_average_on_a_noise_free_step_has_delay_n_half_and_no_overshoot(n):
    t, x, e = obstacle_signal(noise_std=0.0)
    r = one(FilterConfig(MA, n_cycles=n), x, t, e)
    assert abs(r.delay_s / T - n / 2) <= 1.0 + 1e-9
    assert r.delay_s == pytest.approx((n / 2 - 1) * T, abs=1e-12)     # (j+1)/n reaches 1/2 at j = n/2 - 1
    assert 0.0 <= r.dead_time_s < r.delay_s
    assert r.overshoot_mm == pytest.approx(0.0, abs=1e-12) and r.overshoot_pct == pytest.approx(0.0, abs=1e-9)
    assert r.noise_rms == pytest.approx(0.0, abs=1e-12)
    assert r.label == f"MOVING_AVERAGE(n_cycles={n})" and r.output.shape == x.shape


@pytest.mark.parametrize("cfg", [FilterConfig(MA, n_cycles=1), FilterConfig(FilterType.LOWPASS, order=0),
                                 FilterConfig(FilterType.EXPO_MEAN, n_cycles=10, smoothing_factor=1.0)])
def test_pass_through_has_no_delay_and_the_raw_noise(cfg):
    t, x, e = obstacle_signal(noise_std=0.0)
    r = one(cfg, x, t, e)
    assert r.delay_s == 0.0 and r.dead_time_s == 0.0 and r.overshoot_mm == 0.0
    t, x, e = obstacle_signal()
    r = one(cfg, x, t, e)
    assert np.array_equal(r.output, x) and r.delay_s == 0.0
    assert r.noise_rms == pytest.approx(0.05, rel=0.10)
    assert r.noise_rms == pytest.approx(signal_noise_rms(x, t, e, 50))


def test_metrics_follow_the_sign_of_the_step():
    up = obstacle_signal(noise_std=0.0)
    down = obstacle_signal(noise_std=0.0, height=-2.8, level=5.0)
    cfg = FilterConfig(FilterType.LOWPASS, order=2, fg_f0=30)
    a, b = one(cfg, up[1], up[0], up[2]), one(cfg, down[1], down[0], down[2])
    assert a.delay_s == pytest.approx(b.delay_s) and a.dead_time_s == pytest.approx(b.dead_time_s)
    assert a.overshoot_mm == pytest.approx(b.overshoot_mm)
    # a second-order Butterworth overshoots a step by about 4.3 %
    assert 3.5 < a.overshoot_pct < 5.5 and a.overshoot_mm == pytest.approx(a.overshoot_pct / 100 * 2.8)


def test_a_ramp_edge_is_measured_from_its_middle():
    t, x, e = obstacle_signal(noise_std=0.0, ramp_time=0.02)
    assert one(FilterConfig(MA, n_cycles=1), x, t, e).delay_s == pytest.approx(0.0, abs=1e-12)
    assert one(FilterConfig(MA, n_cycles=11), x, t, e).delay_s == pytest.approx(5 * T, abs=1e-9)


def test_moving_average_noise_falls_like_one_over_root_n():
    t, x, e = obstacle_signal(noise_std=0.1)
    for n in (4, 16, 64):
        r = one(FilterConfig(MA, n_cycles=n), x, t, e)
        assert r.noise_rms == pytest.approx(0.1 / math.sqrt(n), rel=0.25)


def test_without_edges_noise_is_measured_against_a_moving_median_and_step_metrics_are_nan():
    t, x, _ = obstacle_signal(height=0.0)                              # flat plane, noise only
    results = compare(x, t, [FilterConfig(MA, n_cycles=1), FilterConfig(MA, n_cycles=20)], T)
    assert results[0].noise_rms == pytest.approx(0.05, rel=0.15)
    assert results[1].noise_rms < results[0].noise_rms / 2
    for r in results:
        assert all(math.isnan(v) for v in (r.delay_s, r.dead_time_s, r.overshoot_mm, r.overshoot_pct))


def test_edges_without_a_step_warn_and_give_nan():
    t, x, e = obstacle_signal(height=0.0)
    with pytest.warns(WorkbenchWarning, match="no step"):
        r = one(FilterConfig(MA, n_cycles=10), x, t, e)
    assert math.isnan(r.delay_s) and math.isfinite(r.noise_rms)


@pytest.mark.parametrize("edges", [[2.0], [-1.0], [float("nan")]])
def test_edges_outside_the_signal_are_an_error(edges):
    t, x, _ = obstacle_signal()
    with pytest.raises(WorkbenchError, match="outside the signal"):
        compare(x, t, [FilterConfig(MA)], T, edges)


def test_compare_rejects_mismatched_or_non_finite_input():
    t, x, e = obstacle_signal()
    with pytest.raises(WorkbenchError, match="equal lengths"):
        compare(x[:-1], t, [FilterConfig(MA)], T, e)
    x[3] = np.nan
    with pytest.raises(WorkbenchError, match="finite"):
        compare(x, t, [FilterConfig(MA)], T, e)


def test_find_edges_recovers_the_obstacle():
    t, x, e = obstacle_signal()
    assert np.allclose(find_edges(t, x), e, atol=2 * T)
    t, x, e = obstacle_signal(height=-2.8, level=5.0, ramp_time=0.01, noise_std=0.1, seed=4)
    assert np.allclose(find_edges(t, x), e, atol=3 * T)
    t, x, _ = obstacle_signal(height=0.0)
    assert find_edges(t, x) == []


# ----------------------------------------------------------------------------------------------- the documents' claims

def _noise_delay(specs: str):
    t, x, e = obstacle_signal()
    rs = compare(x, t, parse_filter_spec(specs, T), T, e)
    return [r.noise_rms for r in rs], [r.delay_s for r in rs]


def strictly(seq, falling=False):
    return all((b < a) if falling else (b > a) for a, b in zip(seq, seq[1:]))


def test_moving_average_more_n_less_noise_more_delay():
    noise, delay = _noise_delay("MOVING_AVERAGE:n_cycles=5,10,20,40")
    assert strictly(noise, falling=True) and strictly(delay)


def test_expo_mean_more_n_less_noise_more_delay_and_larger_alpha_less_smoothing_less_delay():
    noise, delay = _noise_delay("EXPO_MEAN:n_cycles=5,10,20,40,smoothing_factor=0.05")
    assert strictly(noise, falling=True) and strictly(delay)
    noise, delay = _noise_delay("EXPO_MEAN:n_cycles=30,smoothing_factor=0.05,0.1,0.3,0.7")
    assert strictly(noise) and strictly(delay, falling=True)


@pytest.mark.parametrize("kind", ["KALMAN_MA", "KALMAN_EXPO"])
def test_kalman_larger_sigma_less_noise_and_more_n_less_noise_more_delay(kind):
    alpha = ",smoothing_factor=0.3" if kind == "KALMAN_EXPO" else ""
    noise, _ = _noise_delay(f"{kind}:n_cycles=20,kalman_sigma=1,10,100,1000{alpha}")
    assert strictly(noise, falling=True)
    noise, delay = _noise_delay(f"{kind}:n_cycles=3,10,30,kalman_sigma=100{alpha.replace('0.3', '0.1')}")
    assert strictly(noise, falling=True) and strictly(delay)


def test_lowpass_lower_cutoff_less_noise_more_delay():
    noise, delay = _noise_delay("LOWPASS:order=2,fg_f0=100,30,10")
    assert strictly(noise, falling=True) and strictly(delay)


def test_every_filter_of_the_default_comparison_smooths():
    t, x, e = obstacle_signal()
    raw = signal_noise_rms(x, t, e, 50)
    for r in compare(x, t, default_configs(T), T, e):
        assert r.noise_rms < raw and 0.0 <= r.dead_time_s <= r.delay_s


# ----------------------------------------------------------------------------------------------- recordings

def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def obstacle_csv(path, ms_um=True, sep=",", decimal="."):
    t, x, e = obstacle_signal()
    rows = [f"sample{sep}time_ms{sep}dist_um"] if ms_um else [f"sample{sep}t{sep}d"]
    for i, (ti, xi) in enumerate(zip(t, x)):
        tv, xv = (ti * 1e3, xi * 1e3) if ms_um else (ti, xi)
        rows.append(f"s{i}{sep}{repr(float(tv)).replace('.', decimal)}{sep}{repr(float(xv)).replace('.', decimal)}")
    write(path, "\n".join(rows) + "\n")
    return t, x, e


def test_load_a_csv_recording_in_ms_and_um(tmp_path):
    t, x, e = obstacle_csv(tmp_path / "rec.csv")
    for kw in ({"time_column": "time_ms", "value_column": "dist_um"}, {}):    # named, or first two numeric
        rec = load_recording(tmp_path / "rec.csv", time_unit="ms", value_unit="um", **kw)
        assert rec.time_column == "time_ms" and rec.value_column == "dist_um"
        np.testing.assert_allclose(rec.t, t, atol=1e-12)
        np.testing.assert_allclose(rec.values, x, atol=1e-12)
        assert rec.cycle_time == pytest.approx(T) and rec.warnings == () and len(rec) == t.size
    # the recording gives the same comparison as the signal itself
    direct = compare(x, t, default_configs(T), T, e)
    loaded = compare(rec.values, rec.t, default_configs(rec.cycle_time), rec.cycle_time, e)
    for a, b in zip(direct, loaded):
        assert a.delay_s == pytest.approx(b.delay_s, abs=1e-9) and a.noise_rms == pytest.approx(b.noise_rms)


def test_semicolons_with_a_decimal_comma_and_increments(tmp_path):
    t, x, _ = obstacle_csv(tmp_path / "rec.csv", ms_um=False, sep=";", decimal=",")
    rec = load_recording(tmp_path / "rec.csv", value_unit="inc", mm_per_increment=1e-4)
    np.testing.assert_allclose(rec.t, t, atol=1e-12)
    np.testing.assert_allclose(rec.values, x * 1e-4, atol=1e-15)


def test_a_single_value_column_uses_the_given_cycle_time(tmp_path):
    f = write(tmp_path / "v.csv", "dist\n" + "\n".join(str(v) for v in (1.0, 1.1, 0.9, 1.0)) + "\n")
    rec = load_recording(f, cycle_time=0.002)
    assert rec.time_column is None and np.allclose(rec.t, [0, 0.002, 0.004, 0.006])
    with pytest.raises(RecordingError, match="cycle time"):
        load_recording(f)


def test_a_file_without_header_row_names_its_columns(tmp_path):
    rec = load_recording(write(tmp_path / "n.csv", "0,1\n1,2\n2,4\n"), time_unit="ms")
    assert (rec.time_column, rec.value_column) == ("column 1", "column 2")
    assert rec.cycle_time == pytest.approx(1e-3) and rec.values.tolist() == [1.0, 2.0, 4.0]


def test_a_non_uniform_sample_interval_warns(tmp_path):
    t = np.cumsum(np.r_[0.0, np.full(99, 1.0), 1.05])
    f = write(tmp_path / "j.csv", "t,d\n" + "".join(f"{a},{b}\n" for a, b in zip(t, np.zeros(t.size))))
    with pytest.warns(RecordingWarning, match="1 %"):
        rec = load_recording(f, time_unit="ms")
    assert rec.cycle_time == pytest.approx(1e-3) and len(rec.warnings) == 1
    g = write(tmp_path / "k.csv", "t,d\n" + "".join(f"{i * 1.005e-3},0\n" for i in range(50)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_recording(g).warnings == ()


@pytest.mark.parametrize("text, kw, words", [
    (None, {}, ["no such file"]),
    ("t,d\n0,1\n1,2\n2,3\n", {"value_column": "dist"}, ["no value column 'dist'", "columns: t, d"]),
    ("t,dist\n0,1\n1,2\n2,3\n", {"value_column": "dst"}, ["did you mean dist"]),
    ("t,d\n0,1\n1,x\n2,3\n", {"value_column": "d"}, [":3:", "column 'd'", "'x' is not a number"]),
    ("t,d\n0,1\n1,2\n1,3\n", {}, [":4:", "not strictly increasing"]),
    ("t,d\n0,1\n1,2\n2\n", {}, [":4:", "1 cells", "2 columns"]),
    ("label,d\na,1\nb,2\nc,3\n", {}, ["1 numeric column", "allowed"]),
    ("t,d\n0,1\n1,2\n", {}, ["2 samples", "at least 3"]),
    ("t,d\n0,1\n1,2\n2,3\n", {"time_unit": "min"}, ["time unit 'min'", "allowed: s, ms"]),
    ("t,d\n0,1\n1,2\n2,3\n", {"value_unit": "inch"}, ["value unit 'inch'", "allowed: mm, um"]),
    ("t,d\n0,1\n1,2\n2,3\n", {"value_unit": "inc"}, ["mm_per_increment"]),
    ("", {}, ["empty file"]),
])
def test_recording_errors_name_the_file_and_what_is_allowed(tmp_path, text, kw, words):
    f = tmp_path / "bad.csv"
    if text is not None:
        write(f, text)
    with pytest.raises(RecordingError) as info:
        load_recording(f, **kw)
    msg = str(info.value)
    assert str(f) in msg
    for w in words:
        assert w in msg, msg


def test_load_a_distctrl_trace_csv(tmp_path):
    t, x, _ = obstacle_signal()
    tr = Trace(["t", "Z.act", "Z.dc.sensor"], np.column_stack((t, 30.0 + x, -x)),
               units={"t": "s", "Z.act": "mm", "Z.dc.sensor": "mm"}, meta={"cycle_time": T})
    tr.to_csv(tmp_path / "run.csv")
    rec = load_recording(tmp_path / "run.csv")                           # the one *.dc.sensor column
    assert rec.value_column == "Z.dc.sensor" and rec.time_column == "t"
    np.testing.assert_array_equal(rec.values, -x)
    assert rec.cycle_time == pytest.approx(T)
    rec = load_recording(tmp_path / "run.csv", value_column="Z.act")
    np.testing.assert_array_equal(rec.values, 30.0 + x)
    with pytest.raises(RecordingError, match="no value column 'Z.dc.sensr'.*did you mean Z.dc.sensor"):
        load_recording(tmp_path / "run.csv", value_column="Z.dc.sensr")


def test_a_trace_column_in_um_is_converted(tmp_path):
    tr = Trace(["t", "probe"], [[0.0, 1000.0], [0.001, 2000.0], [0.002, 1500.0]], units={"t": "s", "probe": "um"})
    tr.to_csv(tmp_path / "p.csv")
    rec = load_recording(tmp_path / "p.csv", value_column="probe")
    np.testing.assert_allclose(rec.values, [1.0, 2.0, 1.5])
    with pytest.raises(RecordingError, match="name the value column"):
        load_recording(tmp_path / "p.csv")


# ----------------------------------------------------------------------------------------------- table, csv, plot

def test_format_table_lists_every_config_with_its_metrics():
    t, x, e = obstacle_signal()
    rs = compare(x, t, default_configs(T), T, e)
    for plain in (False, True):
        text = format_table(rs, title="obstacle", plain=plain)
        assert "obstacle" in text and "noise RMS [mm]" in text and "delay 50 % [ms]" in text
        for r in rs:
            assert r.label in text and f"{r.noise_rms:.4f}" in text and f"{r.delay_s * 1e3:.2f}" in text
    rs = compare(x, t, default_configs(T), T)                           # no edges: dashes
    assert " - " in format_table(rs, plain=True)


def test_write_results_csv(tmp_path):
    t, x, e = obstacle_signal()
    rs = compare(x, t, parse_filter_spec("MOVING_AVERAGE:n_cycles=10;LOWPASS:order=2,fg_f0=30", T), T, e)
    write_results_csv(rs, tmp_path / "out" / "m.csv")
    rows = list(csv.DictReader((tmp_path / "out" / "m.csv").read_text(encoding="utf-8").splitlines()))
    assert [r["label"] for r in rows] == [r.label for r in rs]
    assert rows[0]["n_cycles"] == "10" and rows[0]["fg_f0"] == "" and rows[1]["order"] == "2"
    assert float(rows[0]["delay_s"]) == rs[0].delay_s


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".svg", b"<?xml")])
def test_plot_overlay_writes_the_file_with_labelled_axes_and_one_line_per_config(tmp_path, suffix, magic):
    t, x, e = obstacle_signal()
    rs = compare(x, t, default_configs(T), T, e)
    out = tmp_path / "plots" / f"f{suffix}"
    fig = plot_overlay(t, x, rs, path=out, edges=e, title="filters")
    assert out.read_bytes()[:5].startswith(magic)
    assert len(fig.axes) == 2                                           # overview + zoom on the rising edge
    labels = [r.label for r in rs]
    for ax in fig.axes:
        assert ax.get_xlabel() == "t [s]" and ax.get_ylabel() == "distance [mm]"
        assert sorted(ln.get_label() for ln in ax.get_lines() if ln.get_label() in labels) == sorted(labels)
        raw = [ln for ln in ax.get_lines() if ln.get_label() == "raw signal"]
        assert len(raw) == 1
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        assert sorted(float(ln.get_xdata()[0]) for ln in dashed) == e.tolist()
    legend = [tx.get_text() for tx in fig.axes[0].get_legend().get_texts()]
    assert set(labels) <= set(legend) and "raw signal" in legend
    lo, hi = fig.axes[1].get_xlim()
    assert lo < e[0] < hi and hi - lo < 0.5


def test_plot_overlay_without_edges_and_bad_suffix(tmp_path):
    t, x, _ = obstacle_signal()
    rs = compare(x, t, default_configs(T), T)
    fig = plot_overlay(t, x, rs)
    assert len(fig.axes) == 1
    with pytest.raises(WorkbenchError, match=r"allowed: \.png, \.svg"):
        plot_overlay(t, x, rs, path=tmp_path / "f.jpg")


# ----------------------------------------------------------------------------------------------- CLI

def invoke(*args):
    """``distctrl filters ARGS`` through the command group (its exit-code table: a usage error is 1)."""
    from distctrl.cli import main

    return CliRunner().invoke(main, ["filters", *args])


def test_cli_default_run_prints_a_table_with_all_configs():
    res = invoke()
    assert res.exit_code == 0, res.output
    assert "built-in obstacle signal" in res.output and "raw noise RMS" in res.output
    for cfg in default_configs(T):
        assert cfg.label() in res.output


def test_cli_specs_plot_and_csv(tmp_path):
    png, table = tmp_path / "o.png", tmp_path / "o.csv"
    res = invoke("MOVING_AVERAGE:n_cycles=10,20", "KALMAN_MA:n_cycles=30,sigma=100", "--plot", str(png),
                 "--csv", str(table))
    assert res.exit_code == 0, res.output
    assert png.read_bytes()[:4] == b"\x89PNG" and str(png) in res.output
    rows = list(csv.DictReader(table.read_text(encoding="utf-8").splitlines()))
    assert [r["label"] for r in rows] == ["MOVING_AVERAGE(n_cycles=10)", "MOVING_AVERAGE(n_cycles=20)",
                                          "KALMAN_MA(n_cycles=30, kalman_sigma=100)"]


@pytest.mark.parametrize("args, words", [
    (["MOVING_AVERAGE:n_cycles=abc"], ["error:", "not a number", "allowed"]),
    (["NOPE:n_cycles=3"], ["error:", "unknown filter type"]),
    (["LOWPASS:order=2,fg_f0=600"], ["error:", "Nyquist"]),
    (["--recording", "does/not/exist.csv"], ["error:", "no such file"]),
    (["--plot", "x.jpg"], ["error:", ".png"]),
    (["--edge", "soon"], ["error:", "--edge 'soon'"]),
    (["--cycle-time", "0"], ["error:", "--cycle-time", "0.0<x<=10.0"]),      # the option's range (click)
])
def test_cli_bad_input_exits_1_with_the_message(args, words):
    res = invoke(*args)
    assert res.exit_code == 1
    for w in words:
        assert w in res.output, res.output


def test_cli_on_a_recording_in_ms_and_um_with_edges(tmp_path):
    obstacle_csv(tmp_path / "rec.csv")
    res = invoke("MOVING_AVERAGE:n_cycles=10", "--recording", str(tmp_path / "rec.csv"), "--time-unit", "ms",
                 "--value-unit", "um", "--edge", "0.5", "--edge", "1.0")
    assert res.exit_code == 0, res.output
    assert "column 'dist_um'" in res.output and "edges: 0.5, 1 s" in res.output
    t, x, e = obstacle_signal()
    r = one(FilterConfig(MA, n_cycles=10), x, t, e)
    assert f"{r.delay_s * 1e3:.2f}" in res.output and f"{r.noise_rms:.4f}" in res.output
    res = invoke("MOVING_AVERAGE:n_cycles=10", "--recording", str(tmp_path / "rec.csv"), "--time-unit", "ms",
                 "--value-unit", "um", "--edge", "auto")
    assert res.exit_code == 0 and f"{r.delay_s * 1e3:.2f}" in res.output
    res = invoke("--recording", str(tmp_path / "rec.csv"), "--time-unit", "ms", "--value-unit", "um")
    assert res.exit_code == 0 and "delay and overshoot need --edge" in res.output


def test_cli_bad_unit_of_a_recording_exits_1(tmp_path):
    obstacle_csv(tmp_path / "rec.csv")
    res = invoke("--recording", str(tmp_path / "rec.csv"), "--value-unit", "inch")
    assert res.exit_code == 1 and "value unit 'inch'" in res.output


def test_cli_help_lists_the_default_set_the_command_runs():
    """M3 (new-user audit): the help listed MOVING_AVERAGE n=10,20,40 ... while the command ran
    DEFAULT_SPECS (9 configurations). The help is made from DEFAULT_SPECS."""
    res = invoke("--help")
    assert res.exit_code == 0
    text = " ".join(res.output.split())
    for spec in DEFAULT_SPECS:
        assert spec in text, spec
    assert f"{len(default_configs(0.001))} configurations" in text
    assert "n=10,20,40" not in text


def test_cli_reads_a_parquet_trace_as_its_csv_twin(tmp_path):
    """R5: `filters --recording x.parquet` said "x.parquet:15: 2 cells, the header has 1 columns"."""
    pytest.importorskip("pyarrow")
    import json

    from distctrl.trace import Trace
    from distctrl.trace.parquet import to_parquet

    t, x, _ = obstacle_signal(0.001, noise_std=0.02, seed=3)
    tr = Trace(["t", "Z.dc.sensor"], np.column_stack([t, x]), units={"t": "s", "Z.dc.sensor": "mm"})
    tr.to_csv(tmp_path / "r.csv")
    to_parquet(tr, tmp_path / "r.parquet")
    a = invoke("MOVING_AVERAGE:n_cycles=10", "--recording", str(tmp_path / "r.csv"), "--edge", "auto", "--json")
    b = invoke("MOVING_AVERAGE:n_cycles=10", "--recording", str(tmp_path / "r.parquet"), "--edge", "auto", "--json")
    assert a.exit_code == 0 and b.exit_code == 0, b.output
    ja, jb = json.loads(a.stdout), json.loads(b.stdout)
    assert ja["results"] == jb["results"] and ja["edges_s"] == jb["edges_s"] and ja["edges_s"]


def test_a_filter_result_answers_to_dict_as_the_json_entry():
    from distctrl.workbench.filters import results_dicts

    t, x, e = obstacle_signal()
    rs = compare(x, t, parse_filter_spec("DEFAULT;KALMAN_MA:n_cycles=10,kalman_sigma=100", T), T, e)
    assert [r.to_dict() for r in rs] == results_dicts(rs)
    assert rs[0].to_dict()["params"] == {"n_cycles": 4}
    assert rs[1].to_dict()["params"] == {"n_cycles": 10, "kalman_sigma": 100.0}


def test_a_filter_result_plots_itself_on_its_signal_and_exports_its_output_as_csv(tmp_path):
    """Like python-control's results: a FilterResult keeps the signal it ran on, so it plots itself
    (plot_overlay of this one result, Agg canvas) and writes its time series as CSV."""
    t, x, e = obstacle_signal()
    (r,) = compare(x, t, parse_filter_spec("MOVING_AVERAGE:n_cycles=20", T), T, e)
    fig = r.plot(tmp_path / "one.png")
    assert (tmp_path / "one.png").read_bytes()[:4] == b"\x89PNG"
    assert type(fig.canvas).__name__ == "FigureCanvasAgg"
    assert len(fig.axes) == 2                                           # overview + zoom on the rising edge
    for ax in fig.axes:
        labels = [ln.get_label() for ln in ax.get_lines()]
        assert len(labels) == 4 and {"raw signal", r.label} <= set(labels)   # raw, output, the two edges
    assert fig._suptitle.get_text() == r.label
    without = compare(x, t, parse_filter_spec("MOVING_AVERAGE:n_cycles=20", T), T)[0].plot()
    assert len(without.axes) == 1 and len(without.axes[0].get_lines()) == 2
    r.to_csv(tmp_path / "one.csv")
    rows = list(csv.reader((tmp_path / "one.csv").open()))
    assert rows[0] == ["t_s", "signal_mm", "output_mm"] and len(rows) == 1 + t.size
    back = np.array(rows[1:], dtype=float)
    assert np.array_equal(back[:, 0], t) and np.array_equal(back[:, 1], x) and np.array_equal(back[:, 2], r.output)
