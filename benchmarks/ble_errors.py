"""What the grid filter's error on the BLE RSSI set is made of (analysis only: reads the truth).

Each of the five tracks is tracked with RSS alone (``hrtls track`` defaults; ``--grid JSON``
adds ``[prediction.grid]`` keys) and the horizontal error ``d = estimate - truth`` at every
truth sample is split into

* ``along`` / ``cross``: its components along the true walking direction (from the truth's
  velocity; negative along: behind the walker) and across it: p75 of the size, and the mean
  along-track component;
* ``bias``: the mean error vector over the track, and the p75 with it removed;
* ``lag``: the p75 against the truth 1 s and 2 s earlier (a lag of the causal filter shows as a
  lower figure there; non-causal, a bound);
* ``start``: the p75 over the first 8 s and over the rest;
* ``speed``: the truth's median speed.

Run: ``python benchmarks/ble_errors.py [--grid '{"point_estimate": "median"}']``.
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import numpy as np

from hrtls.datasets.ble_rssi import load_trajectory
from hrtls.evaluate.metrics import estimate_at
from hrtls.pipeline import Tracker, TrackerConfig

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "ble_rssi"
TRACKS = ("rectangular_with_rotation", "rectangular_without_rotation", "straight_01",
          "straight_02", "straight_03")


def p75(v: np.ndarray) -> float:
    """75th percentile."""
    return float(np.percentile(v, 75))


def parts(name: str, cfg: TrackerConfig) -> str:
    """One line of the error's parts for track ``name``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = load_trajectory(DATA, name).session
        est = Tracker(cfg).run(s).trajectory
    truth = s.truth
    assert truth is not None
    t, xy = truth.t, truth.xyz[:, :2]
    e = estimate_at(est, t)[:, :2]
    d = e - xy
    v = np.gradient(xy, t, axis=0)
    speed = np.hypot(v[:, 0], v[:, 1])
    u = v / np.maximum(speed, 1e-6)[:, None]
    along = np.sum(d * u, axis=1)
    cross = u[:, 0] * d[:, 1] - u[:, 1] * d[:, 0]
    bias = d.mean(axis=0)
    lag = [p75(np.hypot(*(e - np.column_stack([np.interp(t - lag_s, t, xy[:, k])
                                                for k in (0, 1)])).T)) for lag_s in (1.0, 2.0)]
    err = np.hypot(d[:, 0], d[:, 1])
    early = t < t[0] + 8.0
    return (f"{name:29s} {p75(err):4.2f}  {p75(np.abs(along)):4.2f} / {p75(np.abs(cross)):4.2f}"
            f"  {along.mean():+5.2f}  ({bias[0]:+.2f}, {bias[1]:+.2f}) "
            f"{p75(np.hypot(*(d - bias).T)):4.2f}  {lag[0]:4.2f} / {lag[1]:4.2f}"
            f"  {p75(err[early]):4.2f} / {p75(err[~early]):4.2f}  {np.median(speed):4.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grid", default="{}", help="JSON object of [prediction.grid] keys")
    args = ap.parse_args()
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, **json.loads(args.grid)}})})
    print("track                         p75   |along| / |cross| p75  mean along  bias (x, y) "
          "p75 without  p75 vs truth 1 / 2 s earlier  p75 first 8 s / rest  speed (m, m/s)")
    for name in TRACKS:
        print(parts(name, cfg))


if __name__ == "__main__":
    main()
