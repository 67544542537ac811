"""The sweep plot's legend tells the truth (new-user audit M1): the colour the title calls "better" is
the colour of the best set, computed from the lines actually drawn."""
from __future__ import annotations

import re

import numpy as np

from distctrl.tuning.runner import SweepResult, plot_sweep


def _luminance(rgba) -> float:
    r, g, b = rgba[:3]
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def _parallel_result() -> SweepResult:
    rng = np.random.default_rng(1)
    n = 40
    kp = rng.uniform(0.1, 1.9, n)
    d_tv = rng.uniform(0.0, 0.01, n)                 # irregular: parallel coordinates, not a heatmap
    rms = 0.05 + (kp - 0.7) ** 2 + rng.uniform(0, 0.01, n)
    return SweepResult({"kp": kp, "d_tv": d_tv, "rms_error": rms})


def test_the_colour_the_title_calls_better_is_the_best_sets_colour():
    res = _parallel_result()
    fig = plot_sweep(res)
    ax = fig.axes[0]
    title = ax.get_title()
    m = re.search(r"(dark|light|bright|yellow|purple) = better", title)
    assert m, title
    lines = ax.get_lines()
    assert len(lines) == len(res)
    y = np.asarray(res["rms_error"])
    # the line of a set ends at its normalised metric value: find the best and the worst set's lines
    ends = np.array([ln.get_ydata()[-1] for ln in lines])
    best = lines[int(np.argmin(ends))]
    worst = lines[int(np.argmax(ends))]
    assert np.isclose(ends.min(), 0.0) and np.isclose(ends.max(), 1.0) and y.argmin() != y.argmax()
    lb, lw = _luminance(best.get_color()), _luminance(worst.get_color())
    if m.group(1) in ("dark", "purple"):
        assert lb < lw, (title, best.get_color(), worst.get_color())
    else:
        assert lb > lw, (title, best.get_color(), worst.get_color())


def test_parallel_coordinates_have_a_colour_bar_naming_the_metric():
    fig = plot_sweep(_parallel_result())
    labels = [a.get_ylabel() for a in fig.axes[1:]]
    assert any("rms_error" in s for s in labels), labels


def test_sweep_table_and_csv_print_the_values_used_shortest(tmp_path):
    """Parameter columns print repr-shortest (the value used, all its digits, no 0.8999999999999999)."""
    from distctrl.tuning.space import parse_grid

    kp = parse_grid("kp=0.1:1.5:8")["kp"]
    res = SweepResult({"kp": kp, "kalman_sigma": [1234.5] * 4 + [1000.0] * 4, "cost": np.linspace(1, 2, 8),
                       "rms_error": np.linspace(1, 2, 8)})
    text = res.render(8, plain=True)
    for v in ("0.9", "1.1", "1234.5"):
        assert v in text.split(), (v, text)
    assert "0.8999999999999999" not in text
    csv_text = res.write(tmp_path / "s.csv").read_text()
    assert "0.9," in csv_text and "0.8999999999999999" not in csv_text


def _every_parameter_result(n: int = 60) -> SweepResult:
    """A random sweep's table: every parameter column varies (the audit's plot of --random 1024)."""
    from distctrl.tuning.runner import PARAM_COLUMNS

    rng = np.random.default_rng(3)
    data = {}
    for c in PARAM_COLUMNS:
        data[c] = (rng.choice(["MOVING_AVERAGE", "EXPO_MEAN", "LOWPASS"], n) if c == "filter_type"
                   else rng.uniform(0.1, 1.9, n))
    data["rms_error"] = rng.uniform(0.05, 0.2, n)
    return SweepResult(data)


def test_parallel_coordinates_axis_labels_do_not_overlap():
    """New-user audit R5: the axis names ran into one string (n_cyclessmoothing_factorkalman_sigma...).
    The labels' extents, as matplotlib's renderer lays them out, are disjoint and inside the figure."""
    fig = plot_sweep(_every_parameter_result())
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    labels = [t for t in ax.get_xticklabels() if t.get_text()]
    assert len(labels) >= 10, [t.get_text() for t in labels]
    boxes = [t.get_window_extent(renderer) for t in labels]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), (labels[i].get_text(), labels[j].get_text())
    whole = fig.bbox
    for t, b in zip(labels, boxes):
        assert b.x0 >= whole.x0 - 1 and b.x1 <= whole.x1 + 1 and b.y0 >= whole.y0 - 1, t.get_text()
