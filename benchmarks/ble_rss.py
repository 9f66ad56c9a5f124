"""BLE RSS alone (no IMU, no start pose) on the position-annotated BLE RSSI set, leave one out.

Five tracks (``../shared/data/ble_rssi``). For each track in turn, the other four are the
development tracks: the grid filter's settings (``[prediction.grid]``: diffusion speed,
per-anchor bias state, persistent-velocity time constant, with ``--window`` / ``--estimate``
what a row holds of an anchor's window / the row's point estimate, with ``--lag`` the share of
the window's reading age compensated along the persistent velocity, and with ``--motion``
the choices of :data:`MOTION_CHOICES`: velocity modes, a per-anchor burst state; the
averaging window of 2 s and no offset gain, the only values any fold chose among 1 / 2 s and
0 / 0.01) and optionally
the channel (``A``, ``eta``, ``sigma`` fitted by least squares to the development tracks'
readings against their true distances, as a site survey would) are chosen there by the mean
p75 of the horizontal error; the held-out track is then tracked once with that choice.
Printed per track: p50 / p75 / p95 of the horizontal error at every truth sample for

* ``random walk``: ``[prediction] no_imu = "random-walk"`` (the Kalman filter; before the grid);
* ``grid, default``: ``hrtls track`` as shipped (no tuning on the held-out track either);
* ``grid, held out``: the leave-one-out choice above, and ``s / run`` the seconds that
  held-out run took (the whole tracker, one process);
* ``grid, held out, before``: the same choice among the candidates without the motion
  choices (one velocity mode, no burst state) and with the ``--window`` / ``--estimate`` keys
  at their first value (the settings before those options) when the flag is given;

with the mean and worst p75 over tracks. Run: ``python benchmarks/ble_rss.py``.
``--smoother`` adds ``grid, held out, smoother``: the held-out choice tracked again with
``[offline] grid_smoother`` (the filter's settings unchanged: not chosen for the smoother), and
``--lag-s L`` (repeatable) ``grid, held out, lag L s``: the same with the fixed-lag smoother
(``[prediction.grid] smoother_lag_s = L``; a latency the user sets, not chosen); with either,
``cover``: the share of truth samples inside the 95 % ellipse of the latest row, per column.
``--default-channel`` leaves the surveyed channel out of the choices (a fifth of the runs);
``--motion`` adds :data:`MOTION_CHOICES` (3.3 times the runs; held out they did worse);
``--window``, ``--estimate`` and ``--lag`` add :data:`EXTRA_CHOICES` (3, 2 and 3 times the
runs).
``--map`` instead scores the radio map (``[prediction.radio_map]``, :mod:`hrtls.fusion.radio_map`)
with the shipped grid settings: for each held-out track the survey is the other four tracks'
readings at their true positions; its length scale and prior spread (:data:`MAP_CHOICES`) are
chosen by the mean p75 of an inner leave-one-out on those four (each scored with the map of
the other three); the held-out track is then tracked once with the map of all four. Last, for
every candidate, each track tracked with the map of the other four (a look at all five tracks,
for the documented default; not held out).
``--grid '{"key": value, ...}'`` (repeatable) instead prints the p75 of every track with those
``[prediction.grid]`` keys over the defaults (all five tracks: a development look, not held out).
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from hrtls.data import Session
from hrtls.data.session import ChannelModel
from hrtls.datasets.ble_rssi import BleRssiTrajectory, load_trajectory
from hrtls.evaluate.metrics import hold_previous, position_errors
from hrtls.fusion.rss_grid import GridParams
from hrtls.pipeline import Tracker, TrackerConfig

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "ble_rssi"
TRACKS = ("rectangular_with_rotation", "rectangular_without_rotation", "straight_01",
          "straight_02", "straight_03")
GRID_CHOICES = {"sigma_speed_m_per_sqrt_s": (0.8, 1.5, 2.0), "average_s": (2.0,),
                "offset_gain": (0.0,), "bias_sigma_db": (0.0, 3.0, 5.0),
                "velocity_time_s": (0.0, 8.0, 16.0)}
"""Candidate ``[prediction.grid]`` settings of the leave-one-out choice, each with every
:data:`MOTION_CHOICES` entry that fits it."""
EXTRA_CHOICES: dict[str, tuple[str, tuple[Any, ...]]] = {
    "window": ("window_statistic", ("mean-db", "mean-power", "median")),
    "estimate": ("point_estimate", ("mean", "median")),
    "lag": ("lag_compensation", (0.0, 0.5, 1.0))}
"""``--window`` / ``--estimate`` / ``--lag``: a ``[prediction.grid]`` key whose values join the
candidates (the first: the setting before the option); without the flag the key keeps its
default."""
FIXED_HEADINGS = {"mode_turn_deg": 45.0, "stopped_mode": True, "mode_switch_per_s": 0.1,
                  "velocity_time_s": 0.0}
MOTION_CHOICES: tuple[dict[str, Any], ...] = (
    {},                                                     # one mode, no burst state
    {"burst_sigma_db": 10.0},                               # per-anchor burst state
    {"stopped_mode": True, "mode_switch_per_s": 0.1},       # persistent velocity or stopped
    {**FIXED_HEADINGS, "mode_speed_m_per_s": 0.5},          # 8 fixed headings or stopped
    {**FIXED_HEADINGS, "mode_speed_m_per_s": 1.0})
"""Velocity modes and burst state added to the candidates: the stopped mode only with a
persistent velocity, the fixed headings (no persistent velocity) only once per other setting."""


MAP_CHOICES: tuple[dict[str, float], ...] = tuple(
    {"length_m": length, "prior_sigma_db": sigma}
    for length in (1.0, 2.0, 4.0, 8.0) for sigma in (3.0, 6.0))
"""Candidate ``[prediction.radio_map]`` settings of the inner leave-one-out."""


def fits(base: dict[str, Any], extra: dict[str, Any]) -> bool:
    """Whether the motion choice ``extra`` goes with ``base`` (no duplicate runs)."""
    if "mode_speed_m_per_s" in extra:
        return base["velocity_time_s"] == 0.0
    return not extra.get("stopped_mode") or base["velocity_time_s"] > 0.0


CHI2_2_95 = 5.991
"""95 % quantile of the chi-square distribution with 2 degrees of freedom."""


def config(no_imu: str, grid: dict[str, float] | None = None,
           radio_map: dict[str, Any] | None = None, *, smoother: bool = False) -> TrackerConfig:
    """The default configuration with ``no_imu``, some ``[prediction.grid]`` and
    ``[prediction.radio_map]`` keys, and ``[offline] grid_smoother``."""
    cfg = TrackerConfig()
    table = {**cfg.prediction.grid, **(grid or {})}
    rmap = {**cfg.prediction.radio_map, **(radio_map or {})}
    return TrackerConfig.model_validate({**cfg.model_dump(), "prediction": {
        **cfg.prediction.model_dump(), "no_imu": no_imu, "grid": table, "radio_map": rmap},
        "offline": {**cfg.offline.model_dump(), "grid_smoother": smoother}})


def scored(session: Session, cfg: TrackerConfig) -> tuple[np.ndarray, float]:
    """Horizontal error at every truth sample (m), and the share of truth samples inside the
    95 % ellipse of the latest row (its mean and covariance)."""
    res = Tracker(cfg).run(session)
    truth = session.truth
    assert truth is not None
    tr = res.trajectory
    k = hold_previous(tr.t, np.arange(len(tr.t)), truth.t)
    d = truth.xyz[:, :2] - tr.xyz[k, :2]
    m2 = np.einsum("ni,nij,nj->n", d, np.linalg.inv(tr.cov_xy[k]), d)
    return position_errors(tr, truth)[1], float(np.mean(m2 <= CHI2_2_95))


def errors(session: Session, cfg: TrackerConfig) -> np.ndarray:
    """Horizontal error at every truth sample, m."""
    return scored(session, cfg)[0]


def survey_channel(tracks: list[BleRssiTrajectory]) -> ChannelModel:
    """``A``, ``eta`` and the residual sigma fitted to the readings of ``tracks`` (truth)."""
    logd, rss = [], []
    for tr in tracks:
        pos = np.array([tr.receivers[a].xyz[:2] for a in tr.anchor.tolist()])
        d = np.maximum(np.linalg.norm(tr.beacon_xyz[:, :2] - pos, axis=1), 1.0)
        logd.append(-10.0 * np.log10(d))
        rss.append(tr.rss_dbm)
    x = np.column_stack([np.ones(sum(len(v) for v in logd)), np.concatenate(logd)])
    y = np.concatenate(rss)
    coef = np.linalg.lstsq(x, y, rcond=None)[0]
    return ChannelModel(a_dbm=float(coef[0]), eta=float(coef[1]),
                        sigma_db=float(np.std(y - x @ coef)))


def surveyed(s: Session, channel: ChannelModel, use: bool) -> Session:
    """``s`` with the surveyed ``channel`` when ``use``."""
    return s.with_parts(meta=s.meta.model_copy(update={"channel": channel})) if use else s


def write_survey(tracks: list[BleRssiTrajectory], path: Path) -> str:
    """The readings of ``tracks`` at their true positions as a survey CSV at ``path``."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(("x_m", "y_m", "anchor", "rss_dbm"))
        for tr in tracks:
            w.writerows(zip(tr.beacon_xyz[:, 0].tolist(), tr.beacon_xyz[:, 1].tolist(),
                            tr.anchor.tolist(), tr.rss_dbm.tolist(), strict=True))
    return str(path)


def map_study(loaded: dict[str, BleRssiTrajectory]) -> None:
    """Held-out p50 / p75 / p95 without and with the radio map (module docstring)."""
    tmp = Path(tempfile.mkdtemp(prefix="ble_map_"))
    surveys = {frozenset(out): write_survey([loaded[n] for n in TRACKS if n not in out],
                                            tmp / f"survey_{len(out)}_{'_'.join(sorted(out))}.csv")
               for k in (1, 2) for out in itertools.combinations(TRACKS, k)}
    p75: dict[tuple[int, str, str], float] = {}
    for k, cand in enumerate(MAP_CHOICES):
        for h, n in itertools.permutations(TRACKS, 2):
            cfg = config("grid", radio_map={**cand, "survey": surveys[frozenset((h, n))]})
            p75[(k, h, n)] = float(np.percentile(errors(loaded[n].session, cfg), 75))
    table = Table(title="BLE RSSI, RSS alone, radio map: horizontal error p50 / p75 / p95 (m), "
                        "held out")
    for col in ("track", "grid, default", "grid + map, held out", "map choice (dev)"):
        table.add_column(col)
    summary: dict[str, list[float]] = {"default": [], "map": []}
    for h in TRACKS:
        dev = [n for n in TRACKS if n != h]
        score = {k: float(np.mean([p75[(k, h, n)] for n in dev])) for k in range(len(MAP_CHOICES))}
        k = min(score, key=lambda c: score[c])
        s = loaded[h].session
        e = {"default": errors(s, config("grid")),
             "map": errors(s, config("grid", radio_map={**MAP_CHOICES[k],
                                                        "survey": surveys[frozenset((h,))]}))}
        for key, v in e.items():
            summary[key].append(float(np.percentile(v, 75)))
        cells = [" / ".join(f"{x:.2f}" for x in np.percentile(v, [50, 75, 95]))
                 for v in e.values()]
        choice = ", ".join(f"{a}={b}" for a, b in MAP_CHOICES[k].items())
        table.add_row(h, *cells, f"{choice} (dev p75 {score[k]:.2f})")
    table.add_row("p75 mean / worst", *(f"{np.mean(v):.2f} / {np.max(v):.2f}"
                                         for v in summary.values()), "")
    Console(width=160).print(table)
    # every candidate with each track scored once on the map of the other four: a look at
    # all five tracks (for the documented default, not held out)
    for cand in MAP_CHOICES:
        v = [float(np.percentile(errors(loaded[h].session, config("grid", radio_map={
            **cand, "survey": surveys[frozenset((h,))]})), 75)) for h in TRACKS]
        print(f"all five, {cand}: p75 " + " / ".join(f"{x:.2f}" for x in v) +
              f" m; mean {np.mean(v):.2f}, worst {np.max(v):.2f} m")


def sweep(loaded: dict[str, BleRssiTrajectory], grids: list[str]) -> None:
    """p75 per track (default channel) for each JSON object of ``[prediction.grid]`` keys."""
    for text in grids:
        p75 = [float(np.percentile(errors(loaded[n].session, config("grid", json.loads(text))),
                                   75)) for n in TRACKS]
        print(f"{text}: p75 " + " / ".join(f"{v:.2f}" for v in p75) +
              f" m; mean {np.mean(p75):.2f}, worst {np.max(p75):.2f} m")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grid", action="append", default=[],
                    help="JSON object of [prediction.grid] keys: p75 per track, all five")
    ap.add_argument("--default-channel", action="store_true",
                    help="only the default channel among the choices (a fifth of the runs)")
    ap.add_argument("--motion", action="store_true",
                    help="velocity modes and the burst state among the candidates")
    ap.add_argument("--window", action="store_true",
                    help="window_statistic (mean-db, mean-power, median) among the candidates")
    ap.add_argument("--estimate", action="store_true",
                    help="point_estimate (mean, median) among the candidates")
    ap.add_argument("--lag", action="store_true",
                    help="lag_compensation (0, 0.5, 1) among the candidates")
    ap.add_argument("--map", action="store_true",
                    help="the radio map from the other tracks' truth, held out")
    ap.add_argument("--smoother", action="store_true",
                    help="the held-out choice also with [offline] grid_smoother")
    ap.add_argument("--lag-s", type=float, action="append", default=[],
                    help="the held-out choice also with this [prediction.grid] smoother_lag_s "
                         "(repeatable)")
    args = ap.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = {n: load_trajectory(DATA, n) for n in TRACKS}
    if args.map:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            map_study(loaded)
        return
    if args.grid:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sweep(loaded, args.grid)
        return
    choices: dict[str, tuple[Any, ...]] = dict(GRID_CHOICES)
    shipped = GridParams()
    for flag, (key, values) in EXTRA_CHOICES.items():
        choices[key] = values if getattr(args, flag) else (getattr(shipped, key),)
    bases = [dict(zip(choices, v, strict=True)) for v in itertools.product(*choices.values())]
    motion = MOTION_CHOICES if args.motion else MOTION_CHOICES[:1]
    candidates = [{**b, **m} for b in bases for m in motion if fits(b, m)]
    # p75 of every candidate on every track, with the default channel and with each fold's
    # surveyed channel (the survey of the four tracks other than the held-out one)
    surveys = {h: survey_channel([loaded[n] for n in TRACKS if n != h]) for h in TRACKS}
    p75: dict[tuple[Any, ...], float] = {}
    for k, cand in enumerate(candidates):
        cfg = config("grid", cand)
        for n in TRACKS:
            s = loaded[n].session
            p75[(k, None, n)] = float(np.percentile(errors(s, cfg), 75))
            for h in TRACKS:
                if h != n and not args.default_channel:
                    sv = s.with_parts(meta=s.meta.model_copy(update={"channel": surveys[h]}))
                    p75[(k, h, n)] = float(np.percentile(errors(sv, cfg), 75))
    table = Table(title="BLE RSSI, RSS alone: horizontal error p50 / p75 / p95 (m), held out")
    # the held-out choice again, smoothed: (label, [offline] grid_smoother, smoother_lag_s)
    smoothed = ([("smoother", True, 0.0)] if args.smoother else []) + \
        [(f"lag {lag:g} s", False, lag) for lag in args.lag_s]
    cover_col = ["cover held" + "".join(f" / {label}" for label, _, _ in smoothed)] \
        if smoothed else []
    for col in ("track", "random walk", "grid, default", "grid, held out, before",
                "grid, held out", *(f"grid, held out, {label}" for label, _, _ in smoothed),
                "s / run", *cover_col, "choice (dev)"):
        table.add_column(col)
    summary: dict[str, list[float]] = {"walk": [], "default": [], "before": [], "held": []}
    summary.update({label: [] for label, _, _ in smoothed})
    first = {key: values[0] for flag, (key, values) in EXTRA_CHOICES.items()
             if getattr(args, flag)}
    before = [k for k, c in enumerate(candidates) if set(c) == set(choices)
              and all(c[key] == v for key, v in first.items())]
    for h in TRACKS:
        dev = [n for n in TRACKS if n != h]
        score = {(k, ch): np.mean([p75[(k, h if ch else None, n)] for n in dev])
                 for k in range(len(candidates))
                 for ch in ((False,) if args.default_channel else (False, True))}
        k, ch = min(score, key=lambda kc: score[kc])
        kb, cb = min((kc for kc in score if kc[0] in before), key=lambda kc: score[kc])
        s = loaded[h].session
        e = {"walk": errors(s, config("random-walk")), "default": errors(s, config("grid")),
             "before": errors(surveyed(s, surveys[h], cb), config("grid", candidates[kb]))}
        start = time.perf_counter()
        e["held"], cover = scored(surveyed(s, surveys[h], ch), config("grid", candidates[k]))
        seconds = time.perf_counter() - start
        covers = f"{cover:.2f}"
        for label, offline, lag in smoothed:
            e[label], cover = scored(surveyed(s, surveys[h], ch), config(
                "grid", {**candidates[k], "smoother_lag_s": lag}, smoother=offline))
            covers += f" / {cover:.2f}"
        for key, v in e.items():
            summary[key].append(float(np.percentile(v, 75)))
        cells = [" / ".join(f"{x:.2f}" for x in np.percentile(v, [50, 75, 95]))
                 for v in e.values()]
        choice = ", ".join(f"{a}={b}" for a, b in candidates[k].items()) + \
            (f", channel A={surveys[h].a_dbm:.1f} eta={surveys[h].eta:.2f} "
             f"sigma={surveys[h].sigma_db:.1f}" if ch else ", default channel")
        table.add_row(h, *cells, f"{seconds:.1f}", *((covers,) if cover_col else ()),
                      f"{choice} (dev p75 {score[(k, ch)]:.2f})")
    table.add_row("p75 mean / worst", *(f"{np.mean(v):.2f} / {np.max(v):.2f}"
                                         for v in summary.values()),
                  "", *([""] * len(cover_col)), "")
    Console(width=200 + 45 * len(smoothed)).print(table)


if __name__ == "__main__":
    main()
