"""Ranges between the dropped nodes: the data, the mission folder's CSV, the loop's buffer."""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import DegradedInputWarning, FormatError, InputError
from hrtls.io.mission import NETWORK_RANGES_FILE, read_network_ranges, write_network_ranges
from hrtls.mission.graph_links import confirmed, pair_links, select_linked
from hrtls.mission.graph_params import SmootherParams
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.tracker import AgentHeader, MissionTracker

from ._live import short_mission


def _nr(t: list[float], a: list[str], b: list[str], r: list[float]) -> NetworkRanges:
    return NetworkRanges(np.asarray(t, float), np.asarray(a), np.asarray(b), np.asarray(r, float))


@pytest.mark.parametrize(("kw", "field"), [
    ({"t": [0.0, 1.0]}, "node_a"),
    ({"r": [1.0, 0.0, 2.0]}, "range_m index 1"),
    ({"r": [1.0, -2.0, 2.0]}, "range_m index 1"),
    ({"r": [1.0, np.inf, 2.0]}, "range_m"),
    ({"t": [0.0, np.nan, 2.0]}, "t_s"),
    ({"b": ["N2", "N3", "N1"]}, "node_b index 2"),
    ({"a": ["N1", "", "N1"]}, "node_a index 1"),
])
def test_bad_network_ranges_name_the_field(kw: dict[str, list], field: str) -> None:
    base = {"t": [0.0, 1.0, 2.0], "a": ["N1", "N2", "N1"], "b": ["N2", "N3", "N3"],
            "r": [1.0, 2.0, 3.0]}
    base.update(kw)
    with pytest.raises(InputError, match=field):
        _nr(base["t"], base["a"], base["b"], base["r"])


def test_between_takes_the_windows_convention_and_concat_sorts_stably() -> None:
    x = NetworkRanges.concat([_nr([2.0, 0.0], ["N1", "N1"], ["N2", "N3"], [1.0, 2.0]),
                              _nr([2.0, 1.0], ["N4", "N4"], ["N5", "N6"], [3.0, 4.0])])
    np.testing.assert_array_equal(x.t_s, [0.0, 1.0, 2.0, 2.0])
    np.testing.assert_array_equal(x.node_b, ["N3", "N6", "N2", "N5"])   # ties: parts' order
    np.testing.assert_array_equal(x.between(1.0, 2.0).range_m, [4.0])   # 1 <= t < 2
    assert len(x.between(2.0, 2.0)) == 0 and len(NetworkRanges.concat([])) == 0
    assert x.nodes() == ["N1", "N2", "N3", "N4", "N5", "N6"]


_times = st.lists(st.floats(-50.0, 50.0, allow_nan=False), max_size=12)


@settings(max_examples=60, deadline=None)
@given(parts=st.lists(_times, max_size=4), cuts=st.lists(st.floats(-60.0, 60.0), max_size=5))
def test_windows_partition_the_ranges_and_concat_keeps_them(parts: list[list[float]],
                                                            cuts: list[float]) -> None:
    ps = [_nr(t, [f"A{i}"] * len(t), [f"B{j}" for j in range(len(t))],
              list(1.0 + np.arange(len(t), dtype=float))) for i, t in enumerate(parts)]
    x = NetworkRanges.concat(ps)
    assert len(x) == sum(len(p) for p in ps)
    assert np.all(np.diff(x.t_s) >= 0)
    keys = sorted(zip(x.t_s.tolist(), x.node_a.tolist(), x.node_b.tolist(), strict=True))
    assert keys == sorted((t, a, b) for p in ps for t, a, b in
                          zip(p.t_s.tolist(), p.node_a.tolist(), p.node_b.tolist(), strict=True))
    edges = [-np.inf, *sorted(cuts), np.inf]
    windows = [x.between(a, b) for a, b in itertools.pairwise(edges)]
    assert sum(len(w) for w in windows) == len(x)
    for (a, b), w in zip(itertools.pairwise(edges), windows, strict=True):
        assert np.all((w.t_s >= a) & (w.t_s < b))


def test_a_pair_is_one_factor_at_its_median_range() -> None:
    links = pair_links(np.array(["N2", "N1", "N1", "N3"]), np.array(["N1", "N2", "N2", "N1"]),
                       np.array([1.0, 2.0, 4.0, 5.0]), sigma_m=0.3, sigma_fraction=0.1)
    np.testing.assert_array_equal(links.a, ["N1", "N1"])
    np.testing.assert_array_equal(links.b, ["N2", "N3"])
    np.testing.assert_allclose(links.range_m, [2.0, 5.0])           # median of 1, 2, 4
    # N1-N2: deviations 1, 0, 2 from the median, MAD 1 above the model's sigma
    np.testing.assert_allclose(links.sigma_m, [1.4826, np.hypot(0.3, 0.5)])
    np.testing.assert_array_equal(links.count, [3, 1])
    # a persistent excess path adds in variance to whichever of the two is larger
    biased = pair_links(np.array(["N2", "N1", "N1", "N3"]), np.array(["N1", "N2", "N2", "N1"]),
                        np.array([1.0, 2.0, 4.0, 5.0]), sigma_m=0.3, sigma_fraction=0.1,
                        bias_sigma_m=0.4)
    np.testing.assert_allclose(biased.sigma_m,
                               [np.hypot(1.4826, 0.4), np.sqrt(0.3**2 + 0.5**2 + 0.4**2)])


def test_a_node_seen_from_one_line_joins_through_a_neighbour_off_it() -> None:
    """Readings along y = 0 only (the mirror ambiguity) plus a link to a node at y = 4."""
    from hrtls.mission.graph import AgentPath, RangeSet

    t = np.arange(0.0, 11.0)
    xy = np.column_stack([t, np.zeros_like(t)])
    path = AgentPath("R1", t, xy, np.eye(2) * 0.01)
    node = np.array([5.0, 2.0])
    r = np.hypot(np.linalg.norm(xy - node, axis=1), 1.0)
    ranges = RangeSet(np.zeros(len(t), np.int64), t, np.full(len(t), "N1"), r,
                      np.full(len(t), 0.1))
    prm = SmootherParams()
    links = pair_links(np.array(["N1"]), np.array(["N2"]), np.array([2.0]), sigma_m=0.1,
                       sigma_fraction=0.0)
    alone, _ = select_linked([path], ranges, links.select(np.array([False])), {}, {}, prm, 1.0)
    assert alone == {}
    got, start = select_linked([path], ranges, links, {"N2": 3.0},
                               {"N2": np.array([5.0, 4.0])}, prm, 1.0)
    assert got["N1"] >= 4.0 - 1e-9 and set(got) == {"N1", "N2"}
    np.testing.assert_allclose(start["N1"], node, atol=1e-6)         # the mirror side resolved


def test_a_joining_start_is_confirmed_by_each_anchor_kind_by_hand() -> None:
    """Start (0, 0); neighbours at (3, 0) and (0, 4): link residuals |3 - 3| = 0 and
    |6 - 4| = 2, median 1; readings at (0, 5), (0, -5), (5, 0) at ranges 5, 5, 8: residuals
    0, 0, 3, median 0."""
    start = np.zeros(2)
    nb = np.array([[3.0, 0.0], [0.0, 4.0]])
    pts = np.array([[0.0, 5.0], [0.0, -5.0], [5.0, 0.0]])
    kw = {"start_m": start, "neighbour_xy_m": nb, "link_range_m": np.array([3.0, 6.0])}
    none = {"reading_xy_m": np.zeros((0, 2)), "reading_range_m": np.zeros(0)}
    assert confirmed(**kw, **none, tol_m=1.0)                       # links only: median 1
    assert not confirmed(**kw, **none, tol_m=0.99)
    readings = {"reading_xy_m": pts, "reading_range_m": np.array([5.0, 5.0, 8.0])}
    assert confirmed(**kw, **readings, tol_m=1.0)
    bad = {"reading_xy_m": pts, "reading_range_m": np.array([7.0, 7.0, 8.0])}   # median 2
    assert not confirmed(**kw, **bad, tol_m=1.0)
    assert confirmed(**kw, **bad, tol_m=2.0)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20)), min_size=1, max_size=6),
       st.floats(0.05, 3.0), st.floats(1.01, 5.0))
def test_an_exact_start_is_confirmed_and_a_common_excess_beyond_the_tolerance_is_not(
        xy: list[tuple[float, float]], tol_m: float, excess: float) -> None:
    """Ranges from the true distances: confirmed at any tolerance; every range longer by more
    than the tolerance (a misplaced start, one NLOS excess on all): not confirmed."""
    a = np.array(xy, np.float64)
    start = np.array([0.5, -0.25])
    r = np.linalg.norm(a - start, axis=1)
    none = {"reading_xy_m": np.zeros((0, 2)), "reading_range_m": np.zeros(0)}
    assert confirmed(start_m=start, neighbour_xy_m=a, link_range_m=r, tol_m=tol_m, **none)
    assert not confirmed(start_m=start, neighbour_xy_m=a, link_range_m=r + excess * tol_m,
                         tol_m=tol_m, **none)
    assert not confirmed(start_m=start, neighbour_xy_m=a[:1], link_range_m=r[:1],
                         reading_xy_m=a, reading_range_m=r + excess * tol_m, tol_m=tol_m)


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan")])
def test_the_join_tolerance_is_validated(value: float) -> None:
    with pytest.raises(InputError, match="link_join_tol_m"):
        SmootherParams(link_join_tol_m=value)


def test_a_node_whose_start_its_links_contradict_does_not_join() -> None:
    """Readings along y = 0 of a node at (5, 2) plus a neighbour placed at (5, 12) with a link
    of 2 m (the neighbour misplaced by 8 m): the trilateration compromises, the link's residual
    stays metres large, and the node waits; with no check (inf) it joins."""
    from hrtls.mission.graph import AgentPath, RangeSet

    t = np.arange(0.0, 11.0)
    xy = np.column_stack([t, np.zeros_like(t)])
    path = AgentPath("R1", t, xy, np.eye(2) * 0.01)
    r = np.hypot(np.linalg.norm(xy - np.array([5.0, 2.0]), axis=1), 1.0)
    ranges = RangeSet(np.zeros(len(t), np.int64), t, np.full(len(t), "N1"), r,
                      np.full(len(t), 0.1))
    links = pair_links(np.array(["N1"]), np.array(["N2"]), np.array([2.0]), sigma_m=0.1,
                       sigma_fraction=0.0)
    args = ([path], ranges, links, {"N2": 3.0}, {"N2": np.array([5.0, 12.0])})
    got, start = select_linked(*args, SmootherParams(), 1.0)
    assert set(got) == {"N2"} and start == {}
    got, start = select_linked(*args, SmootherParams(link_join_tol_m=np.inf), 1.0)
    assert set(got) == {"N1", "N2"} and set(start) == {"N1"}


def test_csv_round_trip_and_bad_rows_name_line_and_field(tmp_path: Path) -> None:
    x = _nr([0.5, 1.25, 1.25], ["N1", "N2", "N1"], ["N2", "N3", "N3"], [3.5, 0.125, 7.0])
    write_network_ranges(tmp_path, x)
    assert (tmp_path / NETWORK_RANGES_FILE).read_text().splitlines()[0] == \
        "t_s,node_a,node_b,range_m"
    back = read_network_ranges(tmp_path / NETWORK_RANGES_FILE, ["N1", "N2", "N3"])
    for f in ("t_s", "node_a", "node_b", "range_m"):
        np.testing.assert_array_equal(getattr(back, f), getattr(x, f))
    assert len(read_network_ranges(tmp_path / "none.csv", [])) == 0
    bad = {"t_s,node_a,node_b,range_m\n0,N1,N2,1\n1,N1,N2,0\n": r"line 3 column range_m",
           "t_s,node_a,node_b,range_m\n0,N1,N2,1\n1,N1,N2,1\n2,N2,N2,1\n": r"line 4 column node_b",
           "t_s,node_a,node_b,range_m\n0,N1,N2,x\n": r"line 2",
           "t_s,node_a,range_m\n0,N1,1\n": r"node_b"}
    for text, where in bad.items():
        (tmp_path / NETWORK_RANGES_FILE).write_text(text)
        with pytest.raises(FormatError, match=where):
            read_network_ranges(tmp_path / NETWORK_RANGES_FILE, ["N1", "N2"])
    (tmp_path / NETWORK_RANGES_FILE).write_text("t_s,node_a,node_b,range_m\n0,N1,N9,1\n")
    with pytest.warns(DegradedInputWarning, match="N9"):
        read_network_ranges(tmp_path / NETWORK_RANGES_FILE, ["N1", "N2"])


def test_feed_network_keeps_late_ranges_out_and_warns_of_agents() -> None:
    sessions, kinds = short_mission(1)
    mt = MissionTracker({k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()},
                        kinds=kinds)
    assert mt.feed_network(_nr([5.0, 1.0], ["N1", "N2"], ["N2", "N3"], [2.0, 3.0])) is None
    for k, s in sessions.items():
        mt.feed(k, s)
    mt.advance(20.0)
    assert mt.horizon_s > 5.0
    assert len(mt.network.used) == 2 and len(mt.network.pending) == 0
    late = mt.feed_network(_nr([mt.horizon_s - 1.0, mt.horizon_s + 1.0, 0.0],
                               ["N1", "N1", "N4"], ["N3", "N4", "N5"], [1.0, 2.0, 3.0]))
    assert late is not None and late.agent == "network" and late.samples == 2
    assert (late.t_first_s, late.t_last_s) == (0.0, mt.horizon_s - 1.0)
    assert len(mt.network.pending) == 1 and mt.network.late == 2
    with pytest.warns(DegradedInputWarning, match="R1"):
        mt.feed_network(_nr([1e6], ["R1"], ["N2"], [2.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mt.feed_network(_nr([1e6], ["N7"], ["N2"], [2.0]))


def test_the_per_node_estimator_takes_a_localized_neighbour_as_an_anchor() -> None:
    """Readings from one straight pass leave the mirror ambiguity; a linked localized
    neighbour off the line (its covariance as an agent's) resolves it."""
    from types import SimpleNamespace

    from hrtls.mission import network_feed
    from hrtls.mission.nodes import NodeEstimate, NodeEstimator, NodeRanges

    t = np.arange(0.0, 21.0)
    xy = np.column_stack([0.5 * t, np.zeros_like(t)])
    node, nb = np.array([5.0, 2.0]), np.array([5.0, 6.0])
    rng = np.random.default_rng(3)
    obs = NodeRanges.build(agent_xy_m=xy, agent_cov_m2=np.tile(np.eye(2) * 0.01, (len(t), 1, 1)),
                           range_m=np.linalg.norm(xy - node, axis=1) + rng.normal(0, 0.05, len(t)),
                           range_sigma_m=np.full(len(t), 0.05), group=np.zeros(len(t)),
                           chain=np.zeros(len(t)), t_s=t)
    est = NodeEstimator()
    assert not est.estimate(obs).localized                         # the mirror
    nb_est = NodeEstimate(nb, np.eye(2) * 0.04, True, "", np.ones(3, bool), 1.0, 3)
    mt = SimpleNamespace(
        readings={"N1": SimpleNamespace(ranges=lambda gap, floor: obs)},
        params=SimpleNamespace(pass_gap_s=15.0, smoother=None),
        network=network_feed.NetworkState(used=_nr([1.0, 2.0, 3.0], ["N1", "N2", "N1"],
                                                   ["N2", "N1", "N3"], [4.0, 4.1, 9.0])),
        estimates={"N2": nb_est}, node_floor={"N2": 0})
    got = network_feed.node_ranges(mt, "N1", 0)                   # type: ignore[arg-type]
    assert len(got) == len(obs) + 1                                # N3 is not localized
    np.testing.assert_array_equal(got.agent_xy_m[-1], nb)
    assert got.range_m[-1] == pytest.approx(4.05) and got.group[-1] == got.chain[-1] == 1
    e = est.estimate(got)
    assert e.localized and np.linalg.norm(e.position_m - node) < 0.3
    mt.node_floor["N2"] = 1                                        # another floor: no anchor
    assert len(network_feed.node_ranges(mt, "N1", 0)) == len(obs)  # type: ignore[arg-type]
