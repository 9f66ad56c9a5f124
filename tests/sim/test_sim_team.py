"""The simulated team mission: two rescuers (one stops long enough for a PASS alarm), a robot."""

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.sim.floorplan import floor_of
from hrtls.sim.team import team_mission


@pytest.fixture(scope="module")
def mission():
    return team_mission(0, stop_s=45.0)


def test_members_and_floors(mission):
    assert [(m.name, m.kind) for m in mission.members] == [
        ("Rescuer A", "rescuer"), ("Rescuer B", "rescuer"), ("Robot 1", "robot")]
    assert {f["properties"]["floor"] for f in mission.plan["features"]} == {0, 1}
    for m in mission.members[:2]:
        floors = floor_of(m.session.truth.xyz[:, 2], floor_height_m=mission.floor_height_m)
        assert set(floors.tolist()) == {0, 1}
        assert m.session.imu is not None and m.session.tags is not None
        assert {"T1", "T2"} <= set(m.session.tags.tag.tolist())
    assert {lm.id for lm in mission.landmarks} == {"T1", "T2", "T3", "T4", "T5"}


def test_rescuer_b_stands_still_for_the_stop_on_the_first_floor(mission):
    truth = mission.members[1].session.truth
    speed = np.linalg.norm(np.diff(truth.xyz[:, :2], axis=0), axis=1) / np.diff(truth.t)
    still = speed < 1e-3
    # longest run of standing still
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    runs = (edges[1::2] - edges[::2]) * float(np.median(np.diff(truth.t)))
    longest = int(np.argmax(runs))
    assert runs[longest] >= 45.0 - 0.1
    at = truth.xyz[edges[::2][longest]]
    assert at[:2] == pytest.approx([20.0, 36.2], abs=0.2)
    assert floor_of(at[2:3], floor_height_m=mission.floor_height_m)[0] == 1


def test_robot_odometry_drifts_within_its_sigma(mission):
    robot = mission.members[2].session
    assert robot.imu is None and robot.fixes is not None
    err = np.linalg.norm(robot.fixes.xyz[:, :2] - robot.truth.xyz[:, :2], axis=1)
    assert np.all(np.diff(robot.fixes.sigma_m) >= 0)
    assert np.mean(err <= 3 * robot.fixes.sigma_m) > 0.99
    assert err[-1] > 0  # it does drift


def test_bad_options_refused():
    with pytest.raises(InputError, match="team_mission"):
        team_mission(0, stop_s=-1.0)
