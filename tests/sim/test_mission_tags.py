"""The hybrid mission's RFID tags: the entrance pair and the office doors (``tag_layout``)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point

from hrtls.errors import InputError
from hrtls.sim.infrastructure import RfidTag
from hrtls.sim.mission import (
    FREE_SPACE,
    ROOMS,
    MissionOptions,
    inderst_hybrid_mission,
    mission_tags,
    run_mission,
)


def _default_tags() -> list[RfidTag]:
    o = MissionOptions()
    return mission_tags(layout=o.tag_layout, door_spacing_m=o.door_spacing_m)


def test_entrance_layout_is_the_two_corner_tags() -> None:
    tags = mission_tags(layout="entrance", door_spacing_m=12.0)
    assert [(t.id, t.position) for t in tags] == [("T1", (1.5, 0.2, 2.2)), ("T2", (0.2, 1.5, 2.2))]


def test_doors_every_12_m_hand_computed() -> None:
    """Walls 25.5 m (along x) and 24 m (along y): two doors each, centred: 6.75 / 18.75 m and
    6 / 18 m from the wall's start; 8 walls -> 16 door tags after T1, T2."""
    tags = {t.id: t for t in mission_tags(layout="doors", door_spacing_m=12.0)}
    assert len(tags) == 18 and {"T1", "T2"} <= set(tags)
    d1 = tags["D1"]                       # block 1, wall y = 3 (faces the south corridor)
    assert d1.position == (9.75, 3.0, 2.2) and d1.floor == 0
    assert d1.lobe_orientation_rad == pytest.approx(-np.pi / 2)
    np.testing.assert_allclose(d1.bearings_rad, (np.pi / 2, -np.pi / 2))
    assert tags["D2"].position[:2] == (21.75, 3.0)
    assert tags["D3"].position[:2] == (9.75, 27.0)
    assert tags["D5"].position[:2] == (3.0, 9.0)           # west wall, lobe to the west
    assert tags["D5"].lobe_orientation_rad == pytest.approx(np.pi)
    assert tags["D8"].position[:2] == (28.5, 21.0)         # middle corridor, lobe to the east
    assert tags["D8"].lobe_orientation_rad == pytest.approx(0.0)
    assert tags["D9"].position[:2] == (38.25, 3.0)         # second block
    assert tags["D16"].position[:2] == (57.0, 21.0)


@settings(max_examples=40, deadline=None)
@given(spacing=st.floats(min_value=1.0, max_value=60.0))
def test_every_door_tag_is_on_a_wall_facing_the_corridor(spacing: float) -> None:
    tags = mission_tags(layout="doors", door_spacing_m=spacing)[2:]
    per_wall = 2 * max(1, int(np.floor(25.5 / spacing))) + 2 * max(1, int(np.floor(24.0 / spacing)))
    assert len(tags) == 2 * per_wall
    assert len({t.id for t in tags}) == len(tags)
    for t in tags:
        x, y, z = t.position
        assert z == 2.2 and t.floor == 0
        assert ROOMS.distance(Point(x, y)) < 1e-9
        ahead = Point(x + np.cos(t.lobe_orientation_rad), y + np.sin(t.lobe_orientation_rad))
        assert FREE_SPACE.contains(ahead)
        assert len(t.bearings_rad) == 2
        assert abs(np.cos(t.bearings_rad[0] - t.lobe_orientation_rad) + 1.0) < 1e-9


def test_layout_and_spacing_are_validated() -> None:
    with pytest.raises(InputError, match="tag_layout"):
        MissionOptions(tag_layout="roof")
    with pytest.raises(InputError, match="door_spacing_m"):
        MissionOptions(door_spacing_m=0.0)
    with pytest.raises(InputError, match="layout"):
        mission_tags(layout="roof", door_spacing_m=12.0)


def test_defaults_are_the_issue_scenario() -> None:
    o = MissionOptions()
    assert (o.tag_layout, o.door_spacing_m, o.n_robots, o.n_rescuers) == ("doors", 12.0, 1, 3)


def test_corridor_walkers_read_the_door_tags_and_not_only_the_entrance() -> None:
    """Seed 1 (60 s walks): every rescuer reads door tags (5 or more reads of 3 or more doors);
    with the entrance layout the same walks read no tag; the landmarks hold the tags' messages."""
    short = {"walk_s": 60.0, "stagger_s": 10.0, "n_nodes": 10}
    doors = run_mission("inderst_hybrid_mission", 1, **short)
    entrance = run_mission("inderst_hybrid_mission", 1, tag_layout="entrance", **short)
    for name in ("R1", "R2", "R3"):
        reads = doors.agents[name].tags
        assert reads is not None
        counts = Counter(reads.tag.tolist())
        assert sum(counts.values()) >= 5 and len(counts) >= 3
        assert all(k.startswith("D") for k in counts)
        assert {k for k, lm in doors.agents[name].landmarks.items() if lm.kind == "rfid"} == {
            t.id for t in _default_tags()}
        assert entrance.agents[name].tags is None
        np.testing.assert_array_equal(entrance.agents[name].truth.xyz,
                                      doors.agents[name].truth.xyz)
    assert doors.kinds["B1"] == "robot" and doors.agents["B1"].tags is None  # no reader


def test_planner_driven_rescuers_get_the_same_tags() -> None:
    m = inderst_hybrid_mission(2, MissionOptions(rescuer_driver="planner", n_rescuers=1,
                                                 n_robots=0, n_nodes=8, walk_s=30.0))
    rfid = {k for k, lm in m.agents["R1"].landmarks.items() if lm.kind == "rfid"}
    assert rfid == {t.id for t in _default_tags()}
