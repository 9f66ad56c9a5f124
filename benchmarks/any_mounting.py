"""Heading changes of a lower-back sensor in any orientation, mounting unknown (issue 19, item 2).

Each mobgap trial (sensor strapped with x up; the reader knows that mounting) is tracked with
``default`` as recorded, and again with its IMU rotated into other device frames and
``meta.mounting_q_bd`` dropped: "as recorded" (x up, mounting unknown) and three random frames
(``Rotation.random(random_state=seed)``, seeds 1-3). With the mounting unknown the step
headings are the yaw of a device axis plus the walking direction found from the motion
(:mod:`hrtls.gait.walking_direction`), which gives no heading for the first steps of a
recording; both runs are therefore compared over the steps that have a heading in both.

Tables: the heading change over the trial (mean step heading of its last fifth minus its first
fifth, unwrapped) with the known mounting, and the difference of each unknown-mounting run
from it; with ``--test Test11``, also the heading change over each turn of at least 120 deg of
the Stereophoto reference (mean heading of the two steps ending before the turn against the
two starting after it).

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

from hrtls.data import Session, StepEvents
from hrtls.datasets.mobgap import list_trials, load_trial
from hrtls.evaluate.metrics import heading_change_rad
from hrtls.frames import wrap_angle
from hrtls.pipeline import Tracker, preset

ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mobgap_lab"
U_TURN_DEG = 120.0


def rotated(session: Session, r: np.ndarray) -> Session:
    """The session in another device frame (``v_new = r @ v``), mounting unknown."""
    assert session.imu is not None
    meta = session.meta.model_copy(update={"mounting_q_bd": None})
    return session.with_parts(meta=meta, imu=session.imu.in_device_frame(r))


def step_headings(session: Session) -> StepEvents:
    """The tracked steps (``default``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Tracker(preset("default")).run(session).steps


def common(a: StepEvents, b: StepEvents) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step ends and headings of ``a`` and ``b`` at the steps (within 0.05 s) both have."""
    j = np.clip(np.searchsorted(b.t_end, a.t_end), 0, len(b.t_end) - 1)
    j = np.where((j > 0) & (np.abs(b.t_end[j - 1] - a.t_end) < np.abs(b.t_end[j] - a.t_end)),
                 j - 1, j)
    ok = (np.abs(b.t_end[j] - a.t_end) < 0.05) & np.isfinite(a.heading_rad) & np.isfinite(
        b.heading_rad[j])
    return a.t_end[ok], a.heading_rad[ok], b.heading_rad[j[ok]]


def change_deg(t: np.ndarray, h: np.ndarray, t0: float | None = None,
               t1: float | None = None) -> float:
    """Heading change, deg: over the walk, or over a turn from ``t0`` to ``t1`` (NaN: too few)."""
    if t0 is None or t1 is None:
        if len(h) < 4:
            return float("nan")
        ev = StepEvents(t, t, np.ones_like(t), h, np.zeros_like(t),
                        np.zeros(len(t), dtype=np.int64), np.full_like(t, np.nan),
                        np.full_like(t, np.nan), np.full_like(t, np.nan))
        return float(np.degrees(heading_change_rad(ev)))
    hu = np.unwrap(h)
    before, after = hu[t <= t0][-2:], hu[t > t1][:2]
    if len(before) < 2 or len(after) < 2:
        return float("nan")
    return float(np.degrees(after.mean() - before.mean()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--test", default="Test5", choices=["Test5", "Test11"])
    args = ap.parse_args()
    frames = {"as recorded": np.eye(3)} | {
        f"random {k}": Rotation.random(random_state=k).as_matrix() for k in (1, 2, 3)}
    walk = Table(title=f"mobgap {args.test}: heading change, known mounting, and the "
                       "unknown-mounting runs' difference from it (deg)")
    turns = Table(title=f"mobgap {args.test}: turns of at least {U_TURN_DEG:.0f} deg, heading "
                        "change with the known mounting and the unknown-mounting runs' "
                        "difference (deg)")
    for table in (walk, turns):
        for col in ("trial", "known mounting", *frames):
            table.add_column(col)
    worst = {"walk": 0.0, "turn": 0.0}
    for tid in list_trials(ROOT):
        if tid.test != args.test:
            continue
        trial = load_trial(ROOT, tid.participant, tid.test, tid.trial)
        ref_steps = step_headings(trial.session)
        runs = [common(step_headings(rotated(trial.session, r)), ref_steps)
                for r in frames.values()]
        t, _, h_ref = runs[0]
        ref = change_deg(t, h_ref)
        diffs = [change_deg(t, h) - change_deg(t, hr) for t, h, hr in runs]
        worst["walk"] = max([worst["walk"], *(abs(d) for d in diffs if np.isfinite(d))])
        walk.add_row(f"{tid.participant} {tid.trial}", f"{ref:.1f}", *(f"{d:+.1f}" for d in diffs))
        stereo = trial.reference.get("Stereophoto")
        for t0, t1, angle in ([] if stereo is None else stereo.turns):
            if abs(angle) < U_TURN_DEG:
                continue
            pairs = [(change_deg(t, h, t0, t1), change_deg(t, hr, t0, t1)) for t, h, hr in runs]
            d = [float(np.degrees(wrap_angle(np.radians(u - k)))) for u, k in pairs]
            worst["turn"] = max([worst["turn"], *(abs(x) for x in d if np.isfinite(x))])
            turns.add_row(f"{tid.participant} {t0:.0f}-{t1:.0f} s ({angle:+.0f})",
                          f"{pairs[0][1]:.1f}", *(f"{x:+.1f}" for x in d))
    console = Console()
    console.print(walk)
    console.print(f"worst difference over a walk: {worst['walk']:.1f} deg")
    if turns.row_count:
        console.print(turns)
        console.print(f"worst difference over a turn: {worst['turn']:.1f} deg")


if __name__ == "__main__":
    main()
