"""One radio noise model for node and inter-agent ranges (``sim.infrastructure.draw_ranges``).

The golden values below were produced by the code *before* the noise model was factored out of
``range_measurements`` and ``peer_ranges`` (commit 290ef9f: the cases of this file run with
``PYTHONPATH`` on that commit's ``src``, ranges printed with ``repr``): the same seed must give
the same readings, draw for draw. The property test compares ``draw_ranges`` with that inline
model, kept here verbatim as the oracle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Session
from hrtls.data.observations import GroundTruth, PositionFixes, RangeMeasurements
from hrtls.sim.infrastructure import RangeModel, TrackSample, draw_ranges, range_measurements
from hrtls.sim.peers import peer_ranges

WALLS = shapely.MultiLineString([[(10.0, -6.0), (10.0, 6.0)], [(0.0, 3.0), (20.0, 3.0)]])
MODEL = RangeModel(rate_hz=1.0, sigma_m=0.2, sigma_fraction=0.03, max_range_m=8.0,
                   nlos_bias_mean_m=1.5, walls=WALLS, dropout_probability=0.2,
                   agent_height_m=1.2)
NODES = {"n1": (5.0, 1.0, 0.5), "n2": (15.0, -2.0, 2.5), "n3": (9.0, 5.0, 1.0)}
WALKS = {"A": (0.0, 4.0, 0.0, 1.0, 0.0, 10.0), "B": (2.0, 13.0, 1.0, -0.8, 0.1, 8.0),
         "C": (1.0, 8.0, 5.0, 0.0, -0.6, 9.0)}
"""Straight walks: start s, start x, y m, velocity x, y m/s, duration s."""


def _walk(t0_s: float, x0_m: float, y0_m: float, vx_m_s: float, vy_m_s: float,
          dur_s: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(t0_s, t0_s + dur_s + 1e-9, 0.1)
    xyz = np.column_stack([x0_m + vx_m_s * (t - t0_s), y0_m + vy_m_s * (t - t0_s),
                           np.zeros(len(t))])
    return t, xyz


def _track() -> TrackSample:
    t, xyz = _walk(0.0, 2.0, 0.0, 1.0, 0.05, 14.0)
    return TrackSample(t=t, xyz=xyz, heading=np.full(len(t), 0.05), speed=np.full(len(t), 1.0))


def _agents() -> dict[str, Session]:
    out = {}
    for name, walk in WALKS.items():
        t, xyz = _walk(*walk)
        out[name] = Session(fixes=PositionFixes(t, xyz, np.full(len(t), 0.1)),
                            truth=GroundTruth(t, xyz))
    return out


@dataclass(frozen=True)
class Golden:
    """Readings of a case: first time, s; whole periods after it; node id tails; ranges, m."""

    t0_s: float
    steps: list[int]
    nodes: str
    range_m: list[float]


GOLDEN = {
    'nodes': Golden(t0_s=0.35691561906286307,
                 steps=[0, 1, 2, 3, 4, 4, 5, 6, 6, 7, 7, 7, 8, 8, 9, 9, 9, 10, 10, 11, 11, 12, 13,
                        13],
                 nodes='131113112123231231323223', range_m=[
                     2.8329141455709976, 8.543968539045007, 0.7312141021341861,
                     1.171969552087287, 1.5828182575867968, 6.365072988969183,
                     2.692981301338361, 3.8596887707152256, 8.132420930637466,
                     4.269604262089764, 8.144613149060097, 7.403727577782304,
                     5.326427838446594, 5.969241834790628, 9.194010682209809,
                     4.5395480788449944, 7.097589047895873, 9.420882443865699,
                     10.466501948789372, 3.3011277796096845, 7.550748405514624,
                     3.1246699300368896, 3.396231690591003, 8.80916762894732,
                 ]),
    'A': Golden(t0_s=1.3993057692175728, steps=[0, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 8, 8],
                 nodes='CBCBCBCBCBCCBC', range_m=[
                     5.752890293887097, 7.227580282854082, 4.309636879025886,
                     4.474649423165539, 2.988569384207587, 4.118063621198358,
                     2.6491728871491964, 2.158186693588793, 6.93896484196928,
                     4.330038364174867, 4.012762334404035, 4.984263476609886,
                     7.939378612999919, 5.4536257376665835,
                 ]),
    'B': Golden(t0_s=2.0225022784143403, steps=[0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 7, 7],
                 nodes='CACACACACACAAC', range_m=[
                     6.086065961210127, 6.307632097856251, 7.181812564882207,
                     4.70868030386416, 4.673566046555822, 4.917810512071787,
                     9.786067635549818, 2.734700203294536, 1.8556373115074951,
                     6.571398608661218, 0.6526161439441834, 5.08940769369957,
                     6.12961399779024, 1.9476886260556894,
                 ]),
    'C': Golden(t0_s=1.2395418593907186, steps=[0, 1, 2, 3, 4, 4, 5, 6, 7, 7, 8, 8],
                 nodes='AAAAABBBABAB', range_m=[
                     6.537173475157039, 5.01232634869231, 6.318564067366172,
                     3.35342455859913, 2.661069590876938, 2.793600055378102,
                     1.5700542969423505, 0.6029770701953152, 7.918032536043924,
                     0.8721727329606558, 8.308309022916132, 2.0983386743464743,
                 ]),
}


def _check(got: RangeMeasurements | None, want: Golden, prefix: str) -> None:
    assert got is not None
    np.testing.assert_allclose(got.t, want.t0_s + np.asarray(want.steps, dtype=float),
                               rtol=0, atol=1e-9)
    assert got.node.tolist() == [prefix + c for c in want.nodes]
    np.testing.assert_array_equal(got.range_m, np.asarray(want.range_m))
    np.testing.assert_array_equal(
        got.sigma_m, np.hypot(MODEL.sigma_m, MODEL.sigma_fraction * got.range_m))


def test_node_ranges_equal_the_readings_before_the_refactor() -> None:
    got = range_measurements(NODES, MODEL, _track(), np.random.default_rng(20261204))
    _check(got, GOLDEN["nodes"], "n")


def test_peer_ranges_equal_the_readings_before_the_refactor() -> None:
    out = peer_ranges(_agents(), MODEL, np.random.default_rng(18))
    for name in WALKS:
        _check(out[name].ranges, GOLDEN[name], "")


def test_the_node_case_exercises_dropouts_nlos_and_the_range_limit() -> None:
    want = GOLDEN["nodes"]
    tr = _track()
    xyz, _, _ = tr.at(want.t0_s + np.arange(14.0))
    xyz[:, 2] += MODEL.agent_height_m
    pos = np.asarray(list(NODES.values()))
    d = np.linalg.norm(xyz[:, None, :] - pos[None], axis=2)
    segs = shapely.linestrings(np.stack(np.broadcast_arrays(xyz[:, None, :2], pos[None, :, :2]),
                                        axis=2))
    in_range = d <= MODEL.max_range_m
    assert (~in_range).any() and (shapely.intersects(segs, WALLS) & in_range).any()
    assert len(want.range_m) < int(in_range.sum())      # some attempts in range dropped


def _inline_model(d: np.ndarray, a: np.ndarray, b: np.ndarray, inside: np.ndarray,
                  model: RangeModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The pre-refactor inline model of ``sim/peers.py`` (oracle)."""
    keep = inside & (d <= model.max_range_m) & (rng.random(len(d)) >= model.dropout_probability)
    n = int(keep.sum())
    if n == 0:
        return keep, np.zeros(0)
    sd = np.hypot(model.sigma_m, model.sigma_fraction * d[keep])
    r = d[keep] + sd * rng.standard_normal(n)
    if model.walls is not None and model.nlos_bias_mean_m > 0:
        segs = shapely.linestrings(np.stack([a[keep], b[keep]], axis=1))
        r = r + shapely.intersects(segs, model.walls) * rng.exponential(
            model.nlos_bias_mean_m, n)
    return keep, np.maximum(r, 0.0)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 40), st.floats(0.0, 1.0),
       st.floats(0.0, 0.1), st.floats(0.0, 2.0), st.floats(0.0, 1.0), st.booleans())
def test_draw_ranges_equals_the_inline_model_draw_for_draw(
        seed: int, n: int, sigma_m: float, fraction: float, bias_m: float, dropout: float,
        walls: bool) -> None:
    model = RangeModel(sigma_m=sigma_m, sigma_fraction=fraction, max_range_m=8.0,
                       nlos_bias_mean_m=bias_m, walls=WALLS if walls else None,
                       dropout_probability=dropout)
    pts = np.random.default_rng(seed).uniform(0.0, 14.0, (n, 4))
    a, b = pts[:, :2], pts[:, 2:]
    d = np.hypot(*(a - b).T)
    inside = np.random.default_rng(seed + 1).random(n) < 0.8
    r1, r2 = np.random.default_rng(seed + 2), np.random.default_rng(seed + 2)
    keep, want = _inline_model(d, a, b, inside, model, r1)
    got = draw_ranges(distance_m=d, from_xy_m=a, to_xy_m=b, model=model, rng=r2,
                      eligible=inside)
    np.testing.assert_array_equal(got.keep, keep)
    np.testing.assert_array_equal(got.range_m, want)
    np.testing.assert_array_equal(got.sigma_m, np.hypot(sigma_m, fraction * want))
    assert r1.random() == r2.random()                   # the generators are in the same state
