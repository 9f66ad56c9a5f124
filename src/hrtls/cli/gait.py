"""Gait commands: ``hrtls activity train|calibrate-tree`` and ``hrtls calibrate steps``.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import gait as gait_cli
    app.add_typer(gait_cli.activity_app, name="activity")
    calibrate_app.command("steps")(gait_cli.calibrate_steps)   # under `hrtls calibrate`

Labelled sessions for training carry an ``activity.csv`` file next to ``imu.csv`` with the
header ``t_start,t_end,activity`` (times in s on the session clock, activity a label such as
``walking`` or its code). Windows that are not entirely inside one labelled interval are ignored.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from hrtls.cli.errors import reports_errors
from hrtls.data import Activity, activity_codes
from hrtls.errors import InputError
from hrtls.io.intervals import read_intervals

activity_app = typer.Typer(no_args_is_help=True, help="Activity recognition models.")


def read_activity_labels(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Intervals ``(t_start, t_end, codes)`` of an ``activity.csv`` file."""
    iv = read_intervals(path, columns={"activity": "str"})
    return iv.t_start, iv.t_end, activity_codes(iv.table.str("activity"),
                                                where=f"{path} activity")


def _read_session(path: Path) -> object:
    """Any recording hrtls reads (session folder, zip, other formats) as a Session."""
    try:
        from hrtls.recordings import read_any
    except ImportError:  # pragma: no cover - older trees: session folders only
        from hrtls.io.session import read_session

        return read_session(path)
    return read_any(path)


def labelled_windows(sessions: list[Path], *, window_s: float, cutoff_hz: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tree features (W, 3), LDA features (W, 7) and labels (W,) of labelled sessions.

    Each session folder has an ``activity.csv``; windows not entirely inside one labelled
    interval get the label UNKNOWN (-1).
    """
    from hrtls.data import Session
    from hrtls.gait.features import window_labels
    from hrtls.gait.session_analysis import activity_windows, session_inputs

    tree, feats, labels = [], [], []
    for path in sessions:
        session = _read_session(path)
        assert isinstance(session, Session)
        t, acc, q_nd, mount, rate = session_inputs(session)
        lab_file = Path(path) / "activity.csv"
        if not lab_file.exists():
            raise InputError("no activity.csv", where=str(path),
                             expected="t_start,t_end,activity intervals next to imu.csv")
        a, b, codes = read_activity_labels(lab_file)
        per_sample = np.full(t.shape[0], int(Activity.UNKNOWN), dtype=np.int64)
        for lo, hi, c in zip(a, b, codes, strict=True):
            per_sample[(t >= lo) & (t < hi)] = c
        wf = activity_windows(t, acc, rate_hz=rate, q_nd=q_nd, mounting_q_bd=mount,
                              window_s=window_s, cutoff_hz=cutoff_hz)
        tree.append(wf.tree)
        feats.append(wf.lda)
        labels.append(window_labels(per_sample, max(4, round(window_s * rate))))
    return np.concatenate(tree), np.concatenate(feats), np.concatenate(labels)


@activity_app.command("train")
@reports_errors
def train(
    sessions: Annotated[list[Path], typer.Argument(help="Labelled session folders (or zips).")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Model JSON to write.")],
    window_s: Annotated[float, typer.Option(help="Window length, s.")] = 2.0,
    cutoff_hz: Annotated[float, typer.Option(help="Low-pass corner before features, Hz.")] = 6.0,
    covariance: Annotated[str, typer.Option(
        help="'per_class' (eq. 4.8: one covariance per class) or 'pooled' (linear "
             "discriminant).")] = "per_class",
) -> None:
    """Train the LDA activity model (Inderst Sec. 4.1.2) on labelled sessions."""
    from hrtls.gait.activity_lda import train_lda

    if covariance not in ("per_class", "pooled"):
        raise InputError(f"--covariance {covariance!r}", where="--covariance",
                         expected="'per_class' or 'pooled'")
    _, f, y = labelled_windows(sessions, window_s=window_s, cutoff_hz=cutoff_hz)
    model = train_lda(f, y, window_s=window_s, cutoff_hz=cutoff_hz,
                      covariance="pooled" if covariance == "pooled" else "per_class",
                      info=f"trained by hrtls on {len(sessions)} session(s), "
                           f"{int(np.sum(y >= 0))} windows, {covariance} covariance")
    model.save(output)
    counts = {Activity(int(c)).label: int(np.sum(y == c)) for c in np.unique(y[y >= 0])}
    typer.echo(f"wrote {output}: windows per class {counts}")


TREE_FORMAT = "hrtls-activity-tree"


@activity_app.command("calibrate-tree")
@reports_errors
def calibrate_tree_cmd(
    sessions: Annotated[list[Path], typer.Argument(
        help="Labelled session folders (or zips) of one user.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Thresholds JSON to write.")],
) -> None:
    """Set the user's decision-tree thresholds d1-d3 from labelled walks (Inderst 4.1.1)."""
    from hrtls.gait.activity_tree import calibrate_tree, classify_tree

    # the gait stage computes the tree features with n_r = 1 (eq. 4.3)
    tree, _, y = labelled_windows(sessions, window_s=2.0, cutoff_hz=6.0)
    ok = y >= 0
    th = calibrate_tree(tree[ok], y[ok])
    acc = float(np.mean(classify_tree(tree[ok], th) == y[ok])) if ok.any() else float("nan")
    Path(output).write_text(json.dumps({"format": TREE_FORMAT, "version": 1,
                                        "thresholds": th.to_dict(),
                                        "windows": int(ok.sum()),
                                        "in_sample_accuracy": acc}, indent=1))
    typer.echo(f"wrote {output}: {th.to_dict()} (in-sample accuracy {acc * 100:.1f}% on "
               f"{int(ok.sum())} windows)")


@reports_errors
def calibrate_steps(
    sessions: Annotated[list[Path], typer.Argument(help="Session folders, one walk each.")],
    distance: Annotated[list[float], typer.Option(
        "--distance", help="True length of each walk, m (once per session, same order).")],
    output: Annotated[Path, typer.Option("-o", "--output",
                                         help="User profile JSON to write.")],
    model: Annotated[str, typer.Option(
        help="'weinberg', 'frequency' or 'pendulum' (inverted pendulum on the pelvis "
             "excursion, best for short daily-life steps).")] = "weinberg",
    detector: Annotated[str, typer.Option(help="'peak' or 'pll'.")] = "peak",
    leg_length: Annotated[float | None, typer.Option(
        "--leg-length", help="Pendulum length (sensor height above the ground), m; default "
                             "the profile's sensor_height_m or 0.53 x height_m, else 0.95.")]
    = None,
) -> None:
    """Fit the step-length model from walks of known length (Basso eq. 1-2) into a profile."""
    from hrtls.data import Session, UserProfile
    from hrtls.gait.analyzer import GaitAnalyzer
    from hrtls.gait.peak_steps import PeakStepDetector
    from hrtls.gait.pll import PllStepDetector, StepDetection
    from hrtls.gait.session_analysis import session_inputs
    from hrtls.gait.step_length_fit import (
        CalibrationWalk,
        fit_frequency_law,
        fit_pendulum,
        fit_weinberg,
    )
    from hrtls.gait.step_length_pendulum import PendulumModel

    if len(distance) != len(sessions):
        raise InputError(f"{len(distance)} distances for {len(sessions)} sessions",
                         where="--distance", expected="one --distance per session")
    if model not in ("weinberg", "frequency", "pendulum") or detector not in ("peak", "pll"):
        raise InputError(f"model {model!r}, detector {detector!r}", where="options",
                         expected="model weinberg|frequency|pendulum, detector peak|pll")
    walks = []
    legs: list[float] = []
    for path, dist in zip(sessions, distance, strict=True):
        session = _read_session(path)
        assert isinstance(session, Session)
        t, acc, q_nd, mount, rate = session_inputs(session)
        det = PllStepDetector() if detector == "pll" else PeakStepDetector()
        res = GaitAnalyzer(rate_hz=rate, step_detector=det, mounting_q_bd=mount).process(
            t, acc, q_nd)
        s = res.steps
        walks.append(CalibrationWalk(StepDetection(s.t_start, s.t_end, s.frequency_hz,
                                                   s.acc_max, s.acc_min), float(dist),
                                     res.step_excursion_m))
        user = session.meta.user
        extra = user.model_extra or {}
        if extra.get("sensor_height_m"):
            legs.append(float(extra["sensor_height_m"]))
        elif user.height_m:
            legs.append(0.53 * float(user.height_m))
    fitted: object
    if model == "weinberg":
        fitted = fit_weinberg(walks)
    elif model == "frequency":
        fitted = fit_frequency_law(walks)
    else:
        leg = leg_length if leg_length is not None else (float(np.mean(legs)) if legs
                                                         else 0.95)
        fitted = fit_pendulum(walks, base=PendulumModel(leg_length_m=leg))
    assert hasattr(fitted, "to_dict")
    profile = UserProfile(step_model=fitted.to_dict())
    Path(output).write_text(json.dumps(profile.model_dump(mode="json"), indent=1))
    typer.echo(f"wrote {output}: {fitted.to_dict()}")


app = typer.Typer(no_args_is_help=True, help="Gait analysis tools.")
app.add_typer(activity_app, name="activity")
app.command("calibrate-steps")(calibrate_steps)
