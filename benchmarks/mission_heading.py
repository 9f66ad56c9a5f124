"""Heading error of the hybrid mission's rescuers over the distance walked (issue 18 diagnosis).

Simulates ``inderst_hybrid_mission`` per seed and runs each rescuer's own tracker (no
cooperation, ``RESCUER_PREDICTION``) with an ``[attitude]`` variant; prints per rescuer the
tracker's heading error (state heading minus the true heading, median over the distance band)
at 0-5 m, 15-25 m and 55-65 m walked. The truth is read here for scoring only.

    python benchmarks/mission_heading.py --seeds 0-4 --variant default|no-magnetometer|\
        no-hard-iron|gyro+compass|gyro+compass-unfitted
"""

from __future__ import annotations

import argparse

import numpy as np

from _engine import parse_seeds
from hrtls.frames import wrap_angle
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import Tracker
from hrtls.sim.mission import RESCUER_PREDICTION, inderst_hybrid_mission

VARIANTS = {"default": {}, "no-magnetometer": {"use_magnetometer": False},
            "no-hard-iron": {"mag_hard_iron": "off"},
            "gyro+compass": {"heading_source": "gyro+compass"},
            "gyro+compass-unfitted": {"heading_source": "gyro+compass",
                                      "mag_heading": {"unfitted": "use"}},
            "gyro+compass-consider": {"heading_source": "gyro+compass",
                                      "mag_heading": {"offset_model": "consider"}}}
BANDS_M = ((0.3, 5.0), (15.0, 25.0), (55.0, 65.0))


def band_errors_deg(t: np.ndarray, heading_rad: np.ndarray, truth_t: np.ndarray,
                    truth_xy: np.ndarray, truth_heading_rad: np.ndarray) -> list[float]:
    """Median heading error (deg) of the estimate in each band of :data:`BANDS_M`."""
    walked = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(truth_xy, axis=0).T))])
    d = np.interp(t, truth_t, walked)
    err = np.degrees(wrap_angle(heading_rad - np.interp(t, truth_t, np.unwrap(truth_heading_rad))))
    return [float(np.median(err[(d > lo) & (d < hi)])) if np.any((d > lo) & (d < hi))
            else float("nan") for lo, hi in BANDS_M]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--variant", choices=sorted(VARIANTS), default="default")
    args = ap.parse_args()
    config = TrackerConfig.model_validate({"prediction": dict(RESCUER_PREDICTION),
                                           "attitude": VARIANTS[args.variant]})
    print(f"variant {args.variant}: heading error (deg) at " +
          ", ".join(f"{lo:g}-{hi:g} m" for lo, hi in BANDS_M))
    for seed in parse_seeds(args.seeds):
        mission = inderst_hybrid_mission(seed)
        for name, session in mission.agents.items():
            truth = session.truth
            assert truth is not None and truth.heading_rad is not None
            tr = Tracker(config).run(session).trajectory
            errs = band_errors_deg(tr.t, tr.heading_rad, truth.t, truth.xyz[:, :2],
                                   truth.heading_rad)
            print(f"seed {seed} {name}: " + " ".join(f"{e:+6.1f}" for e in errs), flush=True)


if __name__ == "__main__":
    main()
