"""Floor plans of simulated missions (corridors around the routes, per floor)."""

import math

import numpy as np
import pytest
from shapely.geometry import Point, shape

from hrtls.errors import InputError
from hrtls.sim.floorplan import floor_of, route_floorplan


def _by(plan, floor, kind):
    return [shape(f["geometry"]) for f in plan["features"]
            if f["properties"]["floor"] == floor and f["properties"]["kind"] == kind]


def test_straight_corridor_area_hand_computed():
    route = np.column_stack([np.linspace(0, 10, 101), np.zeros(101), np.zeros(101)])
    plan = route_floorplan([route], floor_height_m=3.0, corridor_width_m=2.0, simplify_m=0.0)
    (corridor,) = _by(plan, 0, "corridor")
    # 10 m x 2 m plus two half-disc caps of radius 1 m (shapely's 16-segment circle: -1.3 %)
    assert corridor.area == pytest.approx(20 + math.pi, rel=0.015)
    assert len(_by(plan, 0, "wall")) == 1
    assert _by(plan, 0, "exit")[0].contains(Point(0, 0))
    assert not _by(plan, 0, "stairs")


def test_two_floors_joined_by_stairs_drawn_on_both():
    flat0 = np.column_stack([np.linspace(0, 10, 50), np.zeros(50), np.zeros(50)])
    stairs = np.column_stack([np.full(20, 10.0), np.linspace(0, 4, 20), np.linspace(0, 3.3, 20)])
    flat1 = np.column_stack([np.linspace(10, 0, 50), np.full(50, 4.0), np.full(50, 3.3)])
    plan = route_floorplan([np.vstack([flat0, stairs[1:-1], flat1])], floor_height_m=3.3)
    assert {f["properties"]["floor"] for f in plan["features"]} == {0, 1}
    for floor in (0, 1):
        assert len(_by(plan, floor, "corridor")) == 1
        (steps,) = _by(plan, floor, "stairs")
        assert steps.distance(Point(10, 2)) < 1e-9
    assert _by(plan, 1, "corridor")[0].contains(Point(5, 4))
    assert not _by(plan, 0, "corridor")[0].contains(Point(5, 4))


def test_floor_of_rounds_to_nearest_level():
    np.testing.assert_array_equal(floor_of(np.array([0.0, 1.6, 1.7, 3.3, -3.2]),
                                           floor_height_m=3.3), [0, 0, 1, 1, -1])


@pytest.mark.parametrize("route", [np.zeros((1, 3)), np.zeros((5, 2)),
                                   np.array([[0, 0, 0], [1, np.nan, 0]])])
def test_bad_routes_are_refused(route):
    with pytest.raises(InputError, match="route 0"):
        route_floorplan([route], floor_height_m=3.0)


def test_multifloor_mission_plan_covers_its_route():
    from hrtls.sim.scenarios import run_scenario

    sim = run_scenario("inderst_multifloor", 0)
    fh = sim.session.meta.floor_height_m
    xyz = sim.session.truth.xyz
    plan = route_floorplan([xyz], floor_height_m=fh)
    floors = floor_of(xyz[:, 2], floor_height_m=fh)
    for floor in (0, 1):
        area = _by(plan, floor, "corridor") + _by(plan, floor, "stairs")
        pts = xyz[floors == floor][::50]
        assert all(any(a.distance(Point(p[0], p[1])) < 1e-6 for a in area) for p in pts)
