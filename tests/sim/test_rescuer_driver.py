"""Planner-driven rescuers: legs walked from the truth and joined at standstill, the planner reads
estimates only, the loop is deterministic and causal (the offline tracker repeats it)."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Point, box
from shapely.ops import unary_union

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2
from hrtls.mission.tracker import AgentHeader, MissionTracker
from hrtls.mission.waypoints import planner_input
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.devices import get_device
from hrtls.sim.infrastructure import RangeModel, RfidTag
from hrtls.sim.magnetic import MagneticEnvironment
from hrtls.sim.mission import (
    ENTRANCE_XY,
    RESCUER_PREDICTION,
    ROOMS,
    MissionOptions,
    inderst_hybrid_mission,
)
from hrtls.sim.person import Infrastructure
from hrtls.sim.person_legs import WalkingPerson
from hrtls.sim.planner_loop import LoopParams
from hrtls.sim.rescuer_loop import TeamParams, drive_rescuers, polyline_distance, rescuer_estimate
from hrtls.sim.robot_driver import CorridorRouter
from hrtls.sim.scenario_options import scenario_rngs

L_CORRIDOR = unary_union([box(0, 0, 20, 3), box(17, 0, 20, 15)])
RING = unary_union([box(0, 0, 20, 3), box(0, 9, 20, 12), box(0, 0, 3, 12), box(17, 0, 20, 12)])
NODES = {"N1": (10.0, 1.5, 0.5), "N2": (18.5, 10.0, 0.5)}


def _person(free: object = L_CORRIDOR, *, seed: int = 0, device: str = "inemo",
            name: str = "R1", start: tuple[float, float] = (1.5, 1.5),
            nodes: dict | None = None, router: CorridorRouter | None = None) -> WalkingPerson:
    model = RangeModel(rate_hz=1.0, sigma_m=0.1, max_range_m=10.0, walls=ROOMS)
    tags = [RfidTag(id="T1", position=(1.5, 0.2, 2.2), lobe_orientation_rad=np.pi / 2,
                    floor=0)]
    return WalkingPerson(
        name=name, seed=seed, device=get_device(device),
        router=router or CorridorRouter(free, grid_m=0.5, margin_m=0.4),
        start_xy_m=np.array(start), start_heading_rad=0.0,
        infra=Infrastructure(tags=tags, nodes=NODES if nodes is None else nodes,
                             range_model=model),
        magnetic=MagneticEnvironment(), rngs=scenario_rngs(seed * 1000 + 17))


def test_person_walks_around_the_corner_to_its_way_point_and_stops() -> None:
    p = _person()
    p.stand_until(start_s=0.0, until_s=2.0)
    target = np.array([18.5, 13.0])
    p.walk_to(target, max_walk_s=100.0, until_s=200.0)
    s = p.session()
    assert s.truth is not None
    xy = s.truth.xyz[:, :2]
    assert np.hypot(*(xy[-1] - target)) < 0.05
    assert all(L_CORRIDOR.buffer(1e-6).contains(Point(q)) for q in xy[::20])
    assert not np.any((xy[:, 0] < 16.9) & (xy[:, 1] > 3.1))  # turns the corner
    # the walk starts 2 m straight ahead in the start heading (east), and ends at rest
    assert np.all(np.abs(xy[xy[:, 0] < 3.4, 1] - 1.5) < 1e-6)
    assert np.hypot(*(xy[-1] - xy[-2])) < 1e-3


def test_legs_join_continuously_at_standstill() -> None:
    p = _person(device="ideal", seed=2)
    a = p.stand_until(start_s=0.0, until_s=3.0)
    b = p.walk_to(np.array([12.0, 1.5]), max_walk_s=100.0, until_s=100.0)
    c = p.walk_to(np.array([18.5, 12.0]), max_walk_s=100.0, until_s=100.0)
    dt = 0.01
    for x, y in ((a, b), (b, c)):
        assert x.truth is not None and y.truth is not None
        assert y.truth.t[0] == pytest.approx(x.truth.t[-1] + dt, abs=1e-9)
        assert np.hypot(*(y.truth.xyz[0, :2] - x.truth.xyz[-1, :2])) < 1.6 * dt
        assert abs(y.truth.heading_rad[0] - x.truth.heading_rad[-1]) < 0.05
        assert x.imu is not None and y.imu is not None
        assert y.imu.accel.t[0] == pytest.approx(x.imu.accel.t[-1] + dt, abs=1e-9)
        # at the join the person is at rest (it arrived, or stands); the next sample starts
        # a turn on the spot or the walk's speed-up (MotionParams.accel_m_s2)
        assert np.hypot(*(x.truth.xyz[-1, :2] - x.truth.xyz[-2, :2])) < 1e-3
        assert x.imu.gyro is not None and y.imu.gyro is not None
        assert abs(np.linalg.norm(y.imu.accel.values[0]) - GRAVITY_M_S2) < 1.3
        assert np.linalg.norm(y.imu.gyro.values[0]) < 0.2
    # standing: the device feels gravity only and does not turn
    assert a.imu is not None and a.imu.gyro is not None
    assert np.linalg.norm(a.imu.accel.values[-1]) == pytest.approx(GRAVITY_M_S2, abs=1e-6)
    assert np.linalg.norm(a.imu.gyro.values[-1]) < 1e-6
    s = p.session()
    assert s.truth is not None and s.imu is not None
    assert np.allclose(np.diff(s.truth.t), dt) and np.allclose(np.diff(s.imu.accel.t), dt)
    assert np.max(np.hypot(*np.diff(s.truth.xyz[:, :2], axis=0).T)) < 1.6 * dt


def test_a_long_route_is_cut_after_the_planning_period() -> None:
    p = _person()
    p.stand_until(start_s=0.0, until_s=1.0)
    part = p.walk_to(np.array([18.5, 13.0]), max_walk_s=5.0, until_s=100.0)
    assert part.truth is not None
    walked = float(np.sum(np.hypot(*np.diff(part.truth.xyz[:, :2], axis=0).T)))
    assert 4.0 < walked <= 5.0 * 1.5 + 1e-6
    assert part.truth.t[-1] - part.truth.t[0] < 5.0 + 2.0 + 3.0 + 1.0  # walk + turn + pause
    with pytest.raises(InputError, match="until"):
        p.walk_to(np.array([1.5, 1.5]), max_walk_s=5.0, until_s=p.t_s)


def test_planner_input_does_not_follow_the_true_position() -> None:
    p = _person(seed=4)
    tracker = MissionTracker({"R1": AgentHeader(p.meta, dict(p.landmarks))})
    tracker.feed("R1", p.stand_until(start_s=0.0, until_s=3.0))
    tracker.feed("R1", p.walk_to(np.array([15.0, 1.5]), max_walk_s=20.0, until_s=60.0))
    tracker.advance(p.t_s)
    assert "R1" in tracker.started
    before = rescuer_estimate(tracker, p)
    inp = planner_input(tracker, agent_m=before)
    p.xy_m = np.array([100.0, -50.0])  # the truth moved: the planner's input must not
    after = rescuer_estimate(tracker, p)
    np.testing.assert_array_equal(before, after)
    again = planner_input(tracker, agent_m=after)
    np.testing.assert_array_equal(inp.tracks_m, again.tracks_m)
    assert inp.heard.keys() == again.heard.keys()
    assert np.hypot(*(before - [1.5, 1.5])) > 5.0  # the estimate walked with the person


@pytest.fixture(scope="module")
def loop() -> tuple[dict[str, WalkingPerson], object, LoopParams, TrackerConfig]:
    router = CorridorRouter(RING, grid_m=0.75, margin_m=0.4)
    nodes = {"N1": (10.0, 1.5, 0.5), "N2": (1.5, 10.0, 0.5), "N3": (18.5, 6.0, 0.5)}
    persons = {k: _person(RING, seed=7 + i, name=k, start=ENTRANCE_XY, nodes=nodes,
                          router=router) for i, k in enumerate(("R1", "R2"))}
    prm = LoopParams()
    config = TrackerConfig.model_validate({"prediction": RESCUER_PREDICTION})
    out = drive_rescuers(persons, {}, kinds={}, enter_s={"R1": 3.0, "R2": 8.0},
                         end_s={"R1": 63.0, "R2": 68.0}, params=prm, config=config)
    return persons, out, prm, config


def test_rescuers_reach_the_planners_way_points(loop: tuple) -> None:
    persons, out, prm, _ = loop
    for name, p in persons.items():
        s = p.session()
        truth = s.truth
        choices = out.choices[name]
        assert len(choices) >= 3
        reached = 0
        for j, (t, c) in enumerate(choices):
            t_next = choices[j + 1][0] if j + 1 < len(choices) else truth.t[-1]
            sel = (truth.t >= t) & (truth.t <= t_next)
            d = np.hypot(*(truth.xyz[sel, :2] - p.router.inside(c.position_m)).T)
            walked = float(np.sum(np.hypot(*np.diff(truth.xyz[sel, :2], axis=0).T)))
            if d.min() < p.params.arrive_m:  # there (or already there: it only stands)
                reached += 1
            elif j + 1 < len(choices):  # not reached: cut after the planning period
                assert walked > 0.9 * 0.9 * prm.plan_period_s
        assert reached >= 1
        assert np.allclose(np.diff(truth.t), 0.01)
        assert truth.t[-1] == pytest.approx({"R1": 63.0, "R2": 68.0}[name], abs=0.02)


def test_a_reached_way_point_is_not_offered_again(loop: tuple) -> None:
    persons, out, prm, _ = loop
    gap = prm.waypoints.explore_gap_m
    points = persons["R1"].router.points_m
    events = []  # (time given, way point, kind, reached)
    for name, p in persons.items():
        truth = p.session().truth
        ch = out.choices[name]
        for j, (t, c) in enumerate(ch):
            t_next = ch[j + 1][0] if j + 1 < len(ch) else truth.t[-1]
            sel = (truth.t >= t) & (truth.t <= t_next)
            end = truth.xyz[sel][-1, :2]
            events.append((t, t_next, c, np.hypot(*(end - c.position_m)) < p.params.arrive_m))
    checked = 0
    for t, _, c, _ in events:
        reached = [e[2].position_m for e in events if e[3] and e[1] <= t]
        if not reached or c.kind == "refine":  # a refine way point is a node estimate
            continue
        d = np.min(np.linalg.norm(points[:, None] - np.array(reached)[None], axis=2), axis=1)
        if np.any(d > gap):  # candidates left: the choice is one of them
            assert np.min(np.hypot(*(np.array(reached) - c.position_m).T)) > gap
            checked += 1
    assert checked >= 1


def test_offline_tracker_repeats_the_loops_estimates(loop: tuple) -> None:
    persons, out, prm, config = loop
    sessions = {k: p.session() for k, p in persons.items()}
    offline = MissionTracker(sessions, params=prm.mission, config=config).run()
    for name in persons:
        live = out.tracker.trackers[name].estimates_since()
        keep = live.t < live.t[-1]  # the last row may still be replaced
        tr = offline.agents[name].trajectory
        j = np.searchsorted(tr.t, live.t[keep])
        np.testing.assert_array_equal(tr.t[j], live.t[keep])
        np.testing.assert_allclose(tr.xyz[j], live.xyz[keep], atol=1e-9)


def test_planner_driven_mission_is_deterministic_for_a_seed() -> None:
    o = MissionOptions(n_rescuers=1, n_robots=1, n_nodes=10, walk_s=40.0, stagger_s=10.0,
                       rescuer_driver="planner")
    a, b = inderst_hybrid_mission(3, o), inderst_hybrid_mission(3, o)
    assert a.kinds == {"R1": "rescuer", "B1": "robot"}
    sa, sb = a.agents["R1"], b.agents["R1"]
    np.testing.assert_array_equal(sa.imu.accel.values, sb.imu.accel.values)
    np.testing.assert_array_equal(sa.truth.xyz, sb.truth.xyz)
    np.testing.assert_array_equal(sa.ranges.range_m, sb.ranges.range_m)
    assert sa.truth.t[-1] == pytest.approx(3.0 + 40.0, abs=0.02)
    assert "N1" not in sa.landmarks  # the session knows the tags, not the nodes
    assert "truth" not in str(sa.meta.model_dump())


def test_driver_options_are_checked() -> None:
    with pytest.raises(InputError, match="rescuer_driver"):
        MissionOptions(rescuer_driver="teleport")
    with pytest.raises(InputError, match="planner"):
        MissionOptions(n_robots=1, robot_driver="planner", rescuer_driver="planner")


def _first_choices(team: TeamParams) -> tuple:
    """Two rescuers with the same data entering a T of corridors at once: their first choices."""
    tee = unary_union([box(0, 0, 30, 3), box(14, 0, 17, 15)])
    router = CorridorRouter(tee, grid_m=0.75, margin_m=0.4)
    persons = {k: _person(tee, seed=11, name=k, start=ENTRANCE_XY, nodes={}, router=router)
               for k in ("R1", "R2")}
    out = drive_rescuers(persons, {}, kinds={}, enter_s={"R1": 10.0, "R2": 10.0},
                         end_s={"R1": 40.0, "R2": 40.0}, params=LoopParams(),
                         config=TrackerConfig.model_validate({"prediction": RESCUER_PREDICTION}),
                         team=team)
    return router, out.choices["R1"][0], out.choices["R2"][0]


def test_two_rescuers_asking_at_once_get_distinct_spread_way_points() -> None:
    team = TeamParams(team_gap_m=6.0, leg_walk_s=30.0)
    router, (t1, c1), (t2, c2) = _first_choices(team)
    assert t1 == pytest.approx(t2)  # both asked at their common entry time
    # R1 asked first (name order) and was sent to the far end of the long corridor; R2 is
    # sent neither there nor near R1's route: up the side branch
    assert c1.position_m[0] > 25.0
    assert np.hypot(*(c1.position_m - c2.position_m)) > team.team_gap_m
    route = router.route(np.array(ENTRANCE_XY), c1.position_m)
    assert polyline_distance(c2.position_m[None], route)[0] >= team.team_gap_m
    assert c2.position_m[1] > 7.0
    # without spreading the same data sends R2 down the same corridor as R1
    _, (_, d1), (_, d2) = _first_choices(TeamParams(team_gap_m=0.0, leg_walk_s=30.0))
    np.testing.assert_array_equal(d1.position_m, c1.position_m)
    assert polyline_distance(d2.position_m[None], route)[0] < team.team_gap_m


def test_polyline_distance_and_team_parameters() -> None:
    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    pts = np.array([[5.0, 2.0], [12.0, 5.0], [-3.0, -4.0], [10.0, 10.0]])
    np.testing.assert_allclose(polyline_distance(pts, line), [2.0, 2.0, 5.0, 0.0])
    np.testing.assert_allclose(polyline_distance(pts[:1], line[:1]), [np.hypot(5.0, 2.0)])
    with pytest.raises(InputError, match="team"):
        TeamParams(team_gap_m=-1.0)
    with pytest.raises(InputError, match="team"):
        TeamParams(leg_walk_s=0.0)


def test_the_rescue_mission_preset_widens_the_simulated_rescuers_step_length_noise() -> None:
    """The simulated rescuers follow their way points by the estimate of a tracker with
    ``RESCUER_PREDICTION``; the ``rescue-mission`` preset (the study's and the service's
    rescuers) takes a larger step-length noise (their along-track error was under-modelled),
    the gyro+compass heading with the magnetic offset's error shared (``consider``) and the
    default heading increment (the shared offset, not a larger increment, carries the
    persistent heading error)."""
    from hrtls.pipeline import preset

    cfg = preset("rescue-mission")
    default = preset("default")
    assert (cfg.prediction.sigma_heading_increment_rad
            == default.prediction.sigma_heading_increment_rad
            < RESCUER_PREDICTION["sigma_heading_increment_rad"])
    assert cfg.prediction.q_along > RESCUER_PREDICTION["q_along"]
    assert cfg.attitude.heading_source == "gyro+compass"
    assert cfg.attitude.mag_heading["offset_model"] == "consider"
    changed = {(section, k) for section, values in cfg.model_dump().items()
               if isinstance(values, dict)
               for k, v in values.items() if default.model_dump()[section][k] != v}
    assert changed == {("attitude", "heading_source"), ("attitude", "mag_heading"),
                       ("prediction", "q_along")}
