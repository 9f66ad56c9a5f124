"""Planner-driven robot: the driver reaches way points, the planner reads estimates only, and the
closed loop is deterministic for a seed."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from shapely.geometry import Point, box
from shapely.ops import unary_union

from hrtls.data.session import SessionMeta, StartPose
from hrtls.mission.waypoints import PlannerInput, WaypointParams, next_waypoint, planner_input
from hrtls.sim.infrastructure import RangeModel
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission
from hrtls.sim.robot_driver import CorridorRouter, DrivenRobot

L_CORRIDOR = unary_union([box(0, 0, 20, 3), box(17, 0, 20, 15)])


def _robot(start: tuple[float, float], seed: int = 0) -> DrivenRobot:
    meta = SessionMeta(start_pose=StartPose(x=start[0], y=start[1], z=0.0, heading=0.0,
                                            sigma_xy_m=0.1, sigma_heading_rad=0.02))
    return DrivenRobot(meta=meta, start_xy_m=np.array(start), start_t_s=0.0,
                       nodes={"N1": (10.0, 1.5, 0.5)},
                       model=RangeModel(rate_hz=1.0, sigma_m=0.1, max_range_m=10.0),
                       router=CorridorRouter(L_CORRIDOR, grid_m=0.5, margin_m=0.4),
                       rng=np.random.default_rng(seed))


def test_driven_robot_reaches_its_way_point_around_the_corner() -> None:
    robot = _robot((1.5, 1.5))
    target = np.array([18.5, 13.0])
    xy = []
    while robot.t_s < 120.0:
        part = robot.drive(estimate_m=robot.xy_m, target_m=target, until_s=robot.t_s + 5.0)
        assert part.truth is not None
        xy.append(part.truth.xyz[:, :2])
    path = np.vstack(xy)
    assert np.hypot(*(path[-1] - target)) < 0.35
    inside = L_CORRIDOR.buffer(1e-6)
    assert all(inside.contains(Point(p)) for p in path[::5])
    # the route turns the corner: it never cuts through the missing part of the rectangle
    assert not np.any((path[:, 0] < 16.9) & (path[:, 1] > 3.1))


def test_driver_steers_on_the_estimate_so_the_truth_carries_its_error() -> None:
    robot = _robot((5.0, 1.5))
    err = np.array([0.0, 0.4])  # the estimate is 0.4 m off the truth, to the side
    target = np.array([12.0, 1.5])
    while robot.t_s < 40.0:
        robot.drive(estimate_m=robot.xy_m - err, target_m=target, until_s=robot.t_s + 5.0)
    # the planned route from the estimate, shifted by the error: the robot stops at target + err
    np.testing.assert_allclose(robot.xy_m, target + err, atol=0.35)


def test_odometry_parts_continue_one_another() -> None:
    robot = _robot((1.5, 1.5), seed=3)
    a = robot.drive(estimate_m=robot.xy_m, target_m=np.array([15.0, 1.5]), until_s=5.0)
    b = robot.drive(estimate_m=robot.xy_m, target_m=np.array([15.0, 1.5]), until_s=10.0)
    assert a.fixes is not None and b.fixes is not None
    assert a.fixes.t[0] == 0.0 and b.fixes.t[0] > a.fixes.t[-1]
    step = np.hypot(*(b.fixes.xyz[0, :2] - a.fixes.xyz[-1, :2]))
    assert step < 0.5 / 5 * 1.1  # one odometry period at 0.5 m/s, not a jump
    assert np.hypot(*(b.fixes.xyz[-1, :2] - b.truth.xyz[-1, :2])) < 0.2  # type: ignore[union-attr]


def test_planner_input_is_built_from_the_tracker_and_the_estimate_only() -> None:
    params = list(inspect.signature(planner_input).parameters)
    assert params == ["tracker", "agent_m"]
    assert set(PlannerInput.__dataclass_fields__) == {
        "agent_m", "localized", "heard", "tracks_m", "heard_by"}


def test_heard_node_way_point_is_a_new_view_inside_its_range_disc() -> None:
    grid = np.stack(np.meshgrid(np.arange(0.0, 20.0, 0.5), np.arange(0.0, 3.0, 0.5)),
                    axis=-1).reshape(-1, 2)
    reading = np.array([[2.0, 1.5]])
    inp = PlannerInput(agent_m=np.array([0.5, 1.5]), localized={},
                       heard={"N1": (reading, np.array([6.0]), np.array([0.1]))},
                       tracks_m=np.zeros((0, 2)))
    c = next_waypoint(inp, candidates_m=grid, visits={})
    d = float(np.hypot(*(c.position_m - reading[0])))
    assert c.kind == "heard" and c.node == "N1"
    assert 3.0 <= d <= 6.3
    # by hand: the grid has no point 3 m behind the reading (x >= 0, |dy| <= 1.5), so the
    # nearest feasible point to the agent is straight ahead, 3 m past the reading
    np.testing.assert_allclose(c.position_m, [5.0, 1.5])
    # once visited enough the node is not targeted again: explore instead
    c2 = next_waypoint(inp, candidates_m=grid, visits={"N1": 3})
    assert c2.kind == "explore"


def test_refine_goes_to_a_wide_localized_node_and_explore_to_the_gap() -> None:
    grid = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    inp = PlannerInput(agent_m=np.array([0.0, 0.0]),
                       localized={"A": (np.array([5.0, 0.0]), np.eye(2) * 0.01),
                                  "B": (np.array([15.0, 0.0]), np.eye(2) * 1.0)},
                       heard={}, tracks_m=np.array([[0.0, 0.0], [10.0, 0.0]]))
    refine_first = WaypointParams(explore_gap_m=float("inf"))
    c = next_waypoint(inp, candidates_m=grid, visits={}, params=refine_first)
    assert (c.kind, c.node) == ("refine", "B")
    np.testing.assert_allclose(c.position_m, [15.0, 0.0])
    c = next_waypoint(inp, candidates_m=grid, visits={"B": 3}, params=refine_first)
    assert c.kind == "explore"
    np.testing.assert_allclose(c.position_m, [20.0, 0.0])
    # (20, 0) is 10 m from every track, wider than the default 6 m gap: explored first
    c = next_waypoint(inp, candidates_m=grid, visits={})
    assert c.kind == "explore"
    # a 5 m gap (tracks to 15 m) is narrower: the wide node again
    near = PlannerInput(inp.agent_m, inp.localized, {}, np.array([[0.0, 0.0], [15.0, 0.0]]))
    assert next_waypoint(near, candidates_m=grid, visits={}).node == "B"


@pytest.fixture(scope="module")
def short_missions() -> tuple[object, object]:
    o = MissionOptions(n_rescuers=1, n_robots=1, n_nodes=12, walk_s=60.0, stagger_s=10.0,
                       robot_driver="planner")
    return inderst_hybrid_mission(5, o), inderst_hybrid_mission(5, o)


def test_closed_loop_is_deterministic_for_a_seed(short_missions: tuple) -> None:
    a, b = short_missions
    sa, sb = a.agents["B1"], b.agents["B1"]
    np.testing.assert_array_equal(sa.fixes.xyz, sb.fixes.xyz)
    np.testing.assert_array_equal(sa.truth.xyz, sb.truth.xyz)
    np.testing.assert_array_equal(sa.ranges.range_m, sb.ranges.range_m)
    np.testing.assert_array_equal(a.agents["R1"].imu.accel.values, b.agents["R1"].imu.accel.values)


def test_closed_loop_robot_drives_the_corridors_for_the_mission(short_missions: tuple) -> None:
    m = short_missions[0]
    s = m.agents["B1"]
    assert m.kinds["B1"] == "robot"
    t = s.fixes.t
    assert np.all(np.diff(t) > 0) and t[-1] - t[0] == pytest.approx(60.0, abs=0.3)
    travelled = float(np.sum(np.hypot(*np.diff(s.truth.xyz[:, :2], axis=0).T)))
    assert 10.0 < travelled <= 0.5 * 60.0 + 1.0
    free = m.simulations["B1"].session.truth
    from hrtls.sim.mission import FREE_SPACE
    assert all(FREE_SPACE.buffer(1e-6).contains(Point(p)) for p in free.xyz[::10, :2])


def test_unknown_robot_driver_is_refused() -> None:
    from hrtls.errors import InputError
    with pytest.raises(InputError, match="robot_driver"):
        MissionOptions(robot_driver="teleport")


def test_loop_estimate_reads_the_odometry_not_the_true_pose() -> None:
    from hrtls.mission.tracker import AgentHeader, MissionTracker
    from hrtls.sim.planner_loop import _estimate

    robot = _robot((1.5, 1.5), seed=4)
    part = robot.drive(estimate_m=robot.xy_m, target_m=np.array([15.0, 1.5]), until_s=4.0)
    assert part.fixes is not None
    tracker = MissionTracker({"B1": AgentHeader(robot.meta)}, kinds={"B1": "robot"})
    before = _estimate(tracker, "B1", robot, [part.fixes])
    robot.xy_m = np.array([100.0, -50.0])  # the truth moved: the estimate must not follow
    after = _estimate(tracker, "B1", robot, [part.fixes])
    np.testing.assert_array_equal(before, after)
    # before the tracker's first row: start pose plus the odometry's displacement
    np.testing.assert_allclose(before, [1.5, 1.5] + part.fixes.xyz[-1, :2] - [1.5, 1.5])


def test_robot_goes_beside_a_node_heard_from_one_straight_pass() -> None:
    from hrtls.mission.waypoints import heard_point
    from hrtls.sim.mission import FREE_SPACE
    from hrtls.sim.planner_loop import LoopParams

    router = CorridorRouter(FREE_SPACE, grid_m=0.75, margin_m=0.4)
    # one pass along the bottom corridor's centre line y = 1.5, x 8..22, a node at (15, 2.5):
    # 12 m from the side corridors (beyond the radio's 10 m), so no crossing view exists
    a = np.column_stack([np.linspace(8.0, 22.0, 15), np.full(15, 1.5)])
    r = np.hypot(*(a - [15.0, 2.5]).T)
    inp = PlannerInput(np.array([40.0, 1.5]), {}, {"N": (a, r, np.full(15, 0.3))},
                       np.zeros((0, 2)))
    p = heard_point(inp, "N", router.points_m, LoopParams().waypoints)
    assert p is not None
    # by hand: the foot of the shortest range is (15, 1.5); 1 m off the line on the side of
    # the nearer grid point (y 1.15 and 1.9 are equally near: the first of +-normal)
    assert abs(p[1] - 1.5) == pytest.approx(1.0)
    assert p[0] == pytest.approx(15.0)
    # the driver pulls the point into the free space: the robot's leg leaves the pass's line
    assert abs(router.inside(p)[1] - 1.5) >= 1.0 - 1e-6
    # without side_m the nearest new view is on the pass's line, 3 m past its end
    q = heard_point(inp, "N", router.points_m, WaypointParams(cross_m=3.0))
    assert q is None or abs(q[1] - 1.5) < 1.0
