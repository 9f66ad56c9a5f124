"""A simulated session carries only what a real user would have (issue 16 item 1)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.frames import quat_angle_between
from hrtls.io.session import read_session
from hrtls.pipeline import Tracker, preset
from hrtls.sim.scenarios import CALIBRATION_LEG_M, SCENARIOS, run_scenario, write_result

TRUTH_FILES = ("truth.csv", "checkpoints.csv", "truth_steps.csv", "activity.csv",
               "scenario.json")


@pytest.mark.parametrize("name", ["tarrio_circle", "basso_test1", "inderst_ring",
                                  "office_random_walk"])
def test_session_json_holds_no_simulator_truth(name: str) -> None:
    sim = run_scenario(name, 100)
    meta = sim.session.meta
    assert meta.user.step_model == {}
    assert meta.channel is None
    extra = meta.user.model_dump()
    assert set(extra) == {"height_m", "step_model"}
    # the truth is kept, but outside the session
    assert sim.hidden_truth["gait"]["step_a_m"] > 0
    if sim.session.rss is not None:
        assert sim.hidden_truth["channel"]["eta"] > 0
    if meta.mounting_q_bd is not None:  # a declared (nominal) mounting is not the true one
        q_true = np.asarray(sim.hidden_truth["mounting_q_bd"])
        assert quat_angle_between(np.asarray(meta.mounting_q_bd), q_true) > 1e-4


def test_every_person_scenario_has_a_calibration_course() -> None:
    for name in ("colombo_circle", "basso_test5", "tarrio_office", "inderst_two_users"):
        assert name in SCENARIOS
        sim = run_scenario(name, 3)
        cal = run_scenario(name, 3, calibration=True)
        # same person with the same device
        assert cal.hidden_truth["gait"] == sim.hidden_truth["gait"]
        assert cal.hidden_truth["device"] == sim.hidden_truth["device"]
        cps = cal.session.checkpoints
        assert cps is not None and len(cps) >= 4
        assert cal.session.fixes is None and cal.session.tags is None
        legs = np.diff(np.concatenate([[0.0], np.interp(cps.t, cal.session.truth.t,
                                                        _distance(cal.session.truth.xyz))]))
        assert np.all(legs >= CALIBRATION_LEG_M - 0.5)


def _distance(xyz: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xyz[:, :2], axis=0).T))])


def _track(session_dir: Path) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = Tracker(preset("default")).run(read_session(session_dir))
    return np.column_stack([res.trajectory.t, res.trajectory.xyz])


def test_tracker_output_does_not_depend_on_any_truth_file(tmp_path: Path) -> None:
    sim = run_scenario("tarrio_circle", 101, laps=1.0)
    folder = write_result(sim, tmp_path / "s")
    assert (folder / "truth.csv").exists() and (folder / "scenario.json").exists()
    before = _track(folder)
    # the truth files removed or falsified: the estimate must not change
    for f in TRUTH_FILES[:-1]:
        (folder / f).unlink(missing_ok=True)
    info = json.loads((folder / "scenario.json").read_text())
    info["truth"]["gait"] = {k: 2.0 * v if isinstance(v, float) else v
                             for k, v in info["truth"]["gait"].items()}
    info["truth"]["channel"] = {"a_dbm": -40.0, "eta": 4.0}
    (folder / "scenario.json").write_text(json.dumps(info))
    np.testing.assert_array_equal(_track(folder), before)
