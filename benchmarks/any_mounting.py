"""Heading changes of a lower-back sensor in any orientation, mounting unknown (issue 19, item 2).

Each mobgap trial (sensor strapped with x up; the reader knows that mounting) is tracked with
``default`` as recorded, and again with its IMU rotated into other device frames and
``meta.mounting_q_bd`` dropped: "as recorded" (x up, mounting unknown) and three random frames
(``Rotation.random(random_state=seed)``, seeds 1-3). The table shows the heading change over
the trial (mean step heading of its last fifth minus its first fifth, unwrapped) with the
known mounting, and the difference of each unknown-mounting run from it.

Needs ``../shared/data``. Run: ``python benchmarks/any_mounting.py [--test Test5|Test11]``.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

from hrtls.data import Session
from hrtls.datasets.mobgap import list_trials, load_trial
from hrtls.evaluate.metrics import heading_change_rad
from hrtls.pipeline import Tracker, preset

ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mobgap_lab"


def rotated(session: Session, r: np.ndarray) -> Session:
    """The session in another device frame (``v_new = r @ v``), mounting unknown."""
    assert session.imu is not None
    meta = session.meta.model_copy(update={"mounting_q_bd": None})
    return session.with_parts(meta=meta, imu=session.imu.in_device_frame(r))


def turn_deg(session: Session) -> float:
    """Heading change over the trial from the tracked steps, deg."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = Tracker(preset("default")).run(session)
    return float(np.degrees(heading_change_rad(res.steps)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--test", default="Test5", choices=["Test5", "Test11"])
    args = ap.parse_args()
    frames = {"as recorded": np.eye(3)} | {
        f"random {k}": Rotation.random(random_state=k).as_matrix() for k in (1, 2, 3)}
    table = Table(title=f"mobgap {args.test}: heading change, known mounting, and the "
                        "unknown-mounting runs' difference from it (deg)")
    for col in ("trial", "known mounting", *frames):
        table.add_column(col)
    worst = 0.0
    for tid in list_trials(ROOT):
        if tid.test != args.test:
            continue
        s = load_trial(ROOT, tid.participant, tid.test, tid.trial).session
        ref = turn_deg(s)
        diffs = [turn_deg(rotated(s, r)) - ref for r in frames.values()]
        worst = max(worst, max(abs(d) for d in diffs))
        table.add_row(f"{tid.participant} {tid.trial}", f"{ref:.1f}",
                      *(f"{d:+.1f}" for d in diffs))
    Console().print(table)
    Console().print(f"worst difference: {worst:.1f} deg")


if __name__ == "__main__":
    main()
