"""A phone held in front is recognised from its tilt when the recording does not say so.

`[attitude] mounting = "auto"` with no declared placement holds the first samples and decides
from the mean specific force (hrtls.pipeline.mounting.looks_handheld). Checked on the real
recordings of every placement we have, their placement removed.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.data import Session
from hrtls.datasets import mobgap
from hrtls.datasets.ipin2023 import list_logfiles, load_logfile
from hrtls.datasets.oxford import load_recording
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.mounting import looks_handheld
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import run_scenario

TILT = (14.0, 66.0)


def _undeclared(s: Session) -> Session:
    return s.with_parts(meta=s.meta.model_copy(update={"placement": None}))


def _track(s: Session) -> TrackResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Tracker(preset("default")).run(s)


def _verdict(res: TrackResult) -> str:
    notes = [str(n) for n in res.report["notes"] if "placement not declared" in str(n)]
    assert len(notes) == 1, res.report["notes"]
    return notes[0]


@pytest.mark.parametrize(("deg", "portrait", "expected"), [
    (45.0, True, True), (20.0, True, True), (60.0, True, True),
    (2.0, True, False),     # flat, screen up (a table, a bag)
    (88.0, True, False),    # upright (a pocket, a belt clip)
    (45.0, False, False),   # landscape
    (120.0, True, False),   # screen facing down
])
def test_tilt_rule_hand_computed(deg: float, portrait: bool, expected: bool) -> None:
    a = math.radians(deg)
    up = (0.0, math.sin(a), math.cos(a)) if portrait else (math.sin(a), 0.0, math.cos(a))
    acc = 9.81 * np.tile(up, (50, 1))
    ok, how = looks_handheld(acc, screen_tilt_deg=TILT)
    assert ok is expected
    assert f"{deg:.0f} deg" in how
    assert looks_handheld(np.zeros((5, 3)), screen_tilt_deg=TILT)[0] is False


def test_ipin_log_without_placement_tracks_as_declared(shared_data: Path) -> None:
    folder = shared_data / "ipin2023"
    name = "IPIN2023_T3_TrainingTrial04_repetition01.txt"
    if not folder.is_dir() or name not in list_logfiles(folder):
        pytest.skip("ipin2023 recordings not available")
    s = load_logfile(folder, name)
    declared, detected = _track(s), _track(_undeclared(s))
    assert _verdict(detected).endswith("a phone held in front")
    np.testing.assert_allclose(detected.trajectory.xyz, declared.trajectory.xyz, atol=1e-9)


@pytest.mark.parametrize(("placement", "hand"), [
    ("hand", True), ("armband", False), ("backpocket", False), ("bag", False),
    ("frontpocket", False), ("neckpouch", False)])
def test_oxford_placements_without_placement(shared_data: Path, placement: str,
                                             hand: bool) -> None:
    files = sorted((shared_data / "oxford_step").glob(f"user1_{placement}_*.csv"))
    if not files:
        pytest.skip("oxford recordings not available")
    rec = load_recording(files[0], repair=True)
    verdict = _verdict(_track(_undeclared(rec.session)))
    assert verdict.endswith("not a phone held in front") is not hand


def test_lower_back_sensor_is_not_hand_held(shared_data: Path) -> None:
    root = shared_data / "mobgap_lab"
    if not root.is_dir():
        pytest.skip("mobgap recordings not available")
    trial = mobgap.load_trial(root, "HA/001", "Test5", "Trial1")
    assert _verdict(_track(_undeclared(trial.session))).endswith("not a phone held in front")


def test_an_undeclared_belt_device_tracks_as_a_declared_one() -> None:
    s = run_scenario("basso_test1", 100).session.with_parts(truth=None, checkpoints=None)
    declared, undeclared = _track(s), _track(_undeclared(s))
    assert _verdict(undeclared).endswith("not a phone held in front")
    np.testing.assert_allclose(undeclared.trajectory.xyz, declared.trajectory.xyz, atol=1e-9)
