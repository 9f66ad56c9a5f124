"""A simulated session with everything true about it, and its on-disk form.

:func:`write_result` writes the session folder and, next to its files, ``truth_steps.csv``
(steps.csv columns), ``activity.csv`` (``t_start,t_end,activity`` intervals, the
labelled-session form the activity trainer reads), ``scenario.json`` (name, seed, options,
paper reference numbers, hidden truth) and for sensor-network scenarios ``wsn.json``
(positions of anchors only) and ``wsn_truth.json`` (all positions).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session, StepEvents, activity_labels
from hrtls.sim.imu_model import BodyKinematics, SimulatedImu
from hrtls.sim.infrastructure import WsnDeployment
from hrtls.sim.motion_truth import MotionTruth

__all__ = ["SimulationResult", "activity_intervals_table", "write_extras", "write_result"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class SimulationResult:
    """A simulated session with everything that is true about it.

    Attributes
    ----------
    scenario, seed, options: how it was made.
    session: the recording (with ``truth`` and, where the paper had them, ``checkpoints``).
    true_steps: true step events (heel strike to heel strike).
    activity_t, activity: per-sample true activity codes on the simulation grid.
    motion, kinematics, imu: internals (nominal motion, waist pose, device signals) or None.
    wsn: sensor-network deployment, or None.
    reference: the paper's numbers for this experiment (for comparison in reports).
    description: one line on what is simulated.
    hidden_truth: what the session does not tell an algorithm (true mounting, drawn sensor
        biases / scales / misalignments), written to ``scenario.json`` under ``"truth"``.
    """

    scenario: str
    seed: int
    options: dict[str, Any]
    session: Session
    true_steps: StepEvents
    activity_t: FloatArray
    activity: IntArray
    motion: MotionTruth | None = None
    kinematics: BodyKinematics | None = None
    imu: SimulatedImu | None = None
    wsn: WsnDeployment | None = None
    reference: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    hidden_truth: dict[str, Any] = field(default_factory=dict)



def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def write_result(result: SimulationResult, path: Path | str, *, overwrite: bool = False
                 ) -> Path:
    """Write the session folder plus the truth extras (see the module docstring)."""
    from hrtls.io.session import write_session

    out = write_session(result.session, Path(path), overwrite=overwrite)
    write_extras(result, out)
    return out


def write_extras(result: SimulationResult, out: Path) -> None:
    """Write the truth extras of :func:`write_result` into the session folder ``out``."""
    from hrtls.io.tables import steps_table

    (out / "truth_steps.csv").write_text(steps_table(result.true_steps))
    (out / "activity.csv").write_text(activity_intervals_table(result.activity_t,
                                                               result.activity))
    info = {"scenario": result.scenario, "seed": result.seed, "options": result.options,
            "description": result.description, "reference": result.reference,
            "truth": result.hidden_truth}
    (out / "scenario.json").write_text(json.dumps(_jsonable(info), indent=2) + "\n")
    if result.wsn is not None:
        (out / "wsn.json").write_text(json.dumps(result.wsn.to_json(), indent=2) + "\n")
        (out / "wsn_truth.json").write_text(json.dumps(result.wsn.to_json(truth=True),
                                                       indent=2) + "\n")


def activity_intervals_table(t: FloatArray, codes: IntArray) -> str:
    """``activity.csv`` text: one ``t_start,t_end,activity`` row per constant stretch."""
    if len(t) == 0:
        return "t_start,t_end,activity\n"
    change = np.flatnonzero(np.concatenate([[True], codes[1:] != codes[:-1]]))
    ends = np.concatenate([t[change[1:]], [t[-1]]])
    labels = activity_labels(codes[change])
    rows = [f"{t[i]:.6f},{e:.6f},{lab}" for i, e, lab in zip(change, ends, labels, strict=True)
            if e > t[i]]
    return "t_start,t_end,activity\n" + "\n".join(rows) + "\n"
