"""Run the benchmark suite: in this process, or on a dask.distributed cluster (an embedded
``LocalCluster``, or ``scheduler="tcp://host:8786"``), and judge it against issue 41's check and goals.

:func:`run_suite` returns a :class:`BenchmarkResult`: one row per run (the run's keys, its outcome and
the figures of :mod:`.metrics`), the contestants (run and not run), :func:`reproduction_check` (the drive
lag issue 41 measured on main) and :func:`goals` (issue 41's control-quality targets, each met, not met
or not measured, with the figure).
"""
from __future__ import annotations

import importlib.util
import math
import os
from dataclasses import dataclass, field

from ...errors import DistCtrlError
from .contestants import run_contestant
from .metrics import FIGURES, measure
from .output import plot_plate, write_csv
from .suite import CONTESTANT_TEXT, CONTESTANTS, NOT_RUN_CONTESTANTS, RunSpec, SuiteParams, runs

__all__ = ["BenchmarkResult", "run_one", "run_suite", "reproduction_check", "goals", "ISSUE_41_FIGURES",
           "CHECK_TOLERANCE_MM"]

#: issue 41's figures measured on main: 2 degree ramp, 30 m/min, laser list of the examples, capacitive
#: sensor with 2 um noise, drive kv 60; steady error (mm) without and with velocity feed-forward 1
ISSUE_41_FIGURES = {0.0: 0.326, 1.0: 0.035}
#: how close the benchmark must reproduce them (mm)
CHECK_TOLERANCE_MM = 0.01


def run_one(spec: RunSpec) -> dict:
    """One run: its keys, outcome, control errors and figures (a plain dict, JSON-ready)."""
    track = run_contestant(spec)
    row = {"plate": spec.plate, "process": spec.process, "sensor": spec.sensor,
           "feedforward": spec.feedforward,
           "feed_m_min": spec.feed, "contestant": spec.contestant, "outcome": track.outcome,
           "errors": track.errors}
    row.update(measure(track, spec, spec.plate_obj()))
    return row


def _run_many(specs: list) -> list:
    return [run_one(s) for s in specs]


@dataclass
class BenchmarkResult:
    params: SuiteParams
    quick: bool
    rows: list
    mode: str
    workers: int
    missing: dict = field(default_factory=dict)      # contestant -> why it could not run here
    check: dict = field(default_factory=dict)
    goal_rows: list = field(default_factory=list)

    def contestants(self) -> list[dict]:
        ran = sorted({r["contestant"] for r in self.rows}, key=list(CONTESTANT_TEXT).index)
        return ([{"name": c, "run": True, "what": CONTESTANT_TEXT[c], "why_not": None} for c in ran]
                + [{"name": c, "run": False, "what": None, "why_not": why}
                   for c, why in {**self.missing, **NOT_RUN_CONTESTANTS}.items()])

    @property
    def exit_code(self) -> int:
        return 4 if self.check.get("ok") is False else 0

    def plot(self, path=None, plate: str = "ramp_2deg"):
        """The figure of one plate (its headline figure against the feed), saved too with ``path``."""
        fig = plot_plate(self, plate)
        if path is not None:
            fig.savefig(path, dpi=90)
        return fig

    def to_csv(self, path) -> None:
        """One line per run (:data:`~.output.CSV_COLUMNS`)."""
        write_csv(self, path)

    def to_dict(self) -> dict:
        return {"command": "benchmark", "outcome": "completed" if self.exit_code == 0 else "check_failed",
                "exit_code": self.exit_code, "quick": self.quick, "mode": self.mode, "workers": self.workers,
                "params": {k: list(v) if isinstance(v, tuple) else v for k, v in vars(self.params).items()},
                "contestants": self.contestants(), "figures": list(FIGURES), "check": self.check,
                "goals": self.goal_rows, "runs": self.rows}


def _chunks(specs: list, size: int) -> list[list]:
    return [specs[i:i + size] for i in range(0, len(specs), size)]


def run_suite(params: SuiteParams | None = None, *, quick: bool = False, plates: tuple | None = None,
              processes: tuple = ("laser", "plasma"), mode: str = "local", scheduler: str | None = None,
              workers: int | None = None, progress=None) -> BenchmarkResult:
    """Run the suite (``quick``: the smoke test's few runs). ``mode="local"`` runs in this process;
    ``"cluster"`` on an embedded LocalCluster of ``workers`` processes (default: the CPU count), or on
    the cluster of ``scheduler``. ``progress(done, total)`` is called as runs finish."""
    params = params or SuiteParams()
    missing = {}
    if importlib.util.find_spec("simple_pid") is None:
        missing["simple_pid"] = "simple-pid is not installed here (pip install simple-pid)"
    contestants = tuple(c for c in CONTESTANTS if c not in missing)
    specs = runs(params, quick=quick, plates_only=plates, processes=processes, contestants=contestants)
    if not specs:
        raise DistCtrlError("benchmark: no run selected (check --plates and --process)")
    if scheduler:
        mode = "cluster"
    if mode == "local":
        rows = []
        for i, s in enumerate(specs):
            rows.append(run_one(s))
            if progress:
                progress(i + 1, len(specs))
        n_workers = 1
    else:
        rows, n_workers = _run_cluster(specs, scheduler, workers, progress)
    result = BenchmarkResult(params, quick, rows, mode, n_workers, missing)
    result.check = reproduction_check(rows)
    result.goal_rows = goals(rows)
    return result


def _run_cluster(specs, scheduler, workers, progress) -> tuple[list, int]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed      # the [batch] extra
    except ImportError as exc:
        raise DistCtrlError("benchmark --mode cluster needs dask.distributed: pip install 'distctrl[batch]' "
                            f"({exc})") from None
    cluster = None
    try:
        if scheduler:
            client = Client(scheduler, timeout="20s")
        else:
            n = workers or os.cpu_count() or 1
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
    except (OSError, TimeoutError) as exc:
        raise DistCtrlError(f"cannot reach the dask scheduler {scheduler or '(local)'}: {exc}") from None
    try:
        n_workers = len(client.scheduler_info().get("workers", {})) or 1
        # about eight tasks per worker: the long (slow-feed) runs spread over the workers
        parts = _chunks(specs, max(1, math.ceil(len(specs) / (8 * n_workers))))
        futures = client.map(_run_many, parts, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        done = [None] * len(parts)
        finished = 0
        for fut in as_completed(futures):
            done[index[fut.key]] = fut.result()
            finished += len(parts[index[fut.key]])
            if progress:
                progress(finished, len(specs))
        return [row for part in done for row in part], n_workers
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _find(rows, **keys) -> list:
    return [r for r in rows if all(r.get(k) == v for k, v in keys.items())]


def reproduction_check(rows: list) -> dict:
    """Issue 41's table, measured again: the 2 degree ramp at 30 m/min, laser 1 kHz, the examples' list,
    without and with feed-forward; ``ok`` None when the suite did not run it."""
    items = []
    for ff, expected in ISSUE_41_FIGURES.items():
        found = _find(rows, plate="ramp_2deg", process="laser", sensor="1kHz", feedforward=ff,
                      feed_m_min=30.0, contestant="distctrl_examples")
        got = found[0]["steady_mean_mm"] if found else None
        ok = None if got is None else abs(abs(got) - expected) <= CHECK_TOLERANCE_MM
        items.append({"feedforward": ff, "issue_41_mm": expected,
                      "measured_mm": None if got is None else abs(got),
                      "drive_lag_mm": None if not found or found[0]["drive_lag_mm"] is None
                      else abs(found[0]["drive_lag_mm"]), "ok": ok})
    oks = [i["ok"] for i in items if i["ok"] is not None]
    return {"what": "2 deg ramp, 30 m/min, laser 1 kHz, distctrl_examples: |steady mean error| against "
                    f"issue 41's figures within {CHECK_TOLERANCE_MM} mm", "items": items,
            "ok": (all(oks) if oks else None)}


def _worst(rows, key) -> tuple:
    """The largest |figure| of ``rows`` and the run it comes from (None, None: no run has it)."""
    have = [r for r in rows if r.get(key) is not None]
    if not have:
        return None, None
    r = max(have, key=lambda r: abs(r[key]))
    return abs(r[key]), r


def _where(r) -> str | None:
    if r is None:
        return None
    return (f"{r['plate']}, {r['process']} {r['sensor']}, ff {r['feedforward']:g}, "
            f"{r['feed_m_min']:g} m/min, {r['contestant']}")


def goals(rows: list) -> list[dict]:
    """Issue 41's control-quality targets, judged on the contestants run (issue 41 sets them for
    distctrl tuned, which is not run yet: here for the examples' list with feed-forward 1, 1 ms, 2 um).
    Each: ``goal``, ``limit``, ``unit``, ``value`` (the worst run's), ``met`` (None: not measured),
    ``where`` (the worst run)."""
    dc = [r for r in rows if r["contestant"] in ("distctrl_examples", "distctrl_examples_pf")]
    pf = [r for r in rows if r["contestant"] == "distctrl_examples_pf"]
    ff1 = [r for r in dc if r["feedforward"] == 1.0 and r["contestant"] == "distctrl_examples"]
    laser1k = [r for r in ff1 if r["process"] == "laser" and r["sensor"] == "1kHz"]
    out = []

    def goal(text, rows_used, key, limit, unit, scale=1.0):
        value, worst = _worst(rows_used, key)
        value = None if value is None else value * scale
        out.append({"goal": text, "limit": limit, "unit": unit, "value": value,
                    "met": None if value is None else value <= limit, "where": _where(worst)})

    goal("2 deg ramp at 30 m/min: steady |error|", _find(laser1k, plate="ramp_2deg", feed_m_min=30.0),
         "steady_mean_mm", 0.01, "mm")
    goal("0.5 mm waviness at 20 m/min: sd", _find(laser1k, plate="wavy", feed_m_min=20.0), "steady_sd_mm",
         0.02, "mm")
    goal("flat sheet: sd (worst feed)", _find(laser1k, plate="flat"), "steady_sd_mm", 0.005, "mm")
    goal("process functions on: time below 50 % of the set distance over metal (any plate, feed)", pf,
         "time_below_half_s", 0.0, "s")
    goal("plasma warp: false locks", [x for x in pf if x["process"] == "plasma" and x["plate"] == "warp"],
         "locks_at_feed", 0, "")
    plain = ("flat", "ramp_2deg", "ramp_5deg", "warp")
    goal("plasma steady |error| (flat, ramps, warp; at 6 V/mm)",
         [x for x in ff1 if x["process"] == "plasma" and x["plate"] in plain], "steady_mean_mm", 1.0, "V",
         scale=6.0)
    goal("approach: undershoot", dc, "approach_undershoot_mm", 0.0, "mm")
    never = [x for x in dc if x["approach_time_s"] is None]
    if never:      # a run that never came within 0.1 mm: not met, and no time to show
        out.append({"goal": "approach: in position within 0.1 mm", "limit": 0.3, "unit": "s", "value": None,
                    "met": False, "where": _where(never[0]), "note": f"{len(never)} runs never in position"})
    else:
        goal("approach: in position within 0.1 mm", dc, "approach_time_s", 0.3, "s")
    out.append({"goal": "distctrl tuned beats plasmac tuned on every plasma plate and feed", "limit": None,
                "unit": "", "value": None, "met": None, "where": None, "note": "neither is run yet"})
    return out
