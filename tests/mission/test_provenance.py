"""Provenance of the mission's errors; the capped information of a pass (mission.provenance)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.mission.provenance import (
    NodeUse,
    Provenance,
    UsePool,
    informative,
    pool_factor,
    widening,
)


def test_pool_factor_hand_case() -> None:
    pool, a = pool_factor(UsePool(), t_first_s=0.0, t_last_s=2.0, ranges=3, gap_s=15.0)
    assert a == 4.0 and pool == UsePool(2.0, 3)
    pool, a = pool_factor(pool, t_first_s=5.0, t_last_s=6.0, ranges=2, gap_s=15.0)
    assert a == 24.0 and pool == UsePool(6.0, 5)
    # 3 / 4 + 2 / 24 = 1 - 1 / 6: the pass's ranges carry less than one node's information
    assert math.isclose(3 / 4 + 2 / 24, 1 - 1 / 6)
    _, a = pool_factor(pool, t_first_s=30.0, t_last_s=30.0, ranges=1, gap_s=15.0)
    assert a == 2.0                                          # after the gap: a new pass
    _, a = pool_factor(pool, t_first_s=8.0, t_last_s=8.0, ranges=1, gap_s=15.0)
    assert a == 42.0


def test_second_order_loop_is_classified() -> None:
    """A (0) localizes n, B (1) corrected by n localizes m: A's use of m is second-order."""
    p = Provenance()
    p.read(0, "n")
    assert p.kind(1, "n", contributor=False) == "independent"
    p.use(NodeUse(1.0, 1, "n", "independent", 1, np.zeros(2), np.eye(2), 1.0))
    p.read(1, "m")
    assert p.node("m") == {0, 1}
    assert p.kind(0, "m", contributor=False) == "second-order"
    assert p.kind(2, "m", contributor=False) == "independent"
    assert p.kind(1, "m", contributor=True) == "direct"
    back = Provenance.from_state(p.state())
    assert back.inside_agent == p.inside_agent and back.inside_node == p.inside_node
    assert [u.node for u in back.uses] == ["n"]


@settings(max_examples=200, deadline=None)
@given(windows=st.lists(st.integers(1, 6), min_size=1, max_size=6),
       node_var=st.lists(st.floats(0.05, 20.0), min_size=1, max_size=4),
       prior_var=st.floats(0.01, 100.0), sigma=st.floats(0.01, 1.0),
       seed=st.integers(0, 2 ** 31 - 1))
def test_claimed_variance_never_below_true_in_correlated_scalar_model(
        windows: list[int], node_var: list[float], prior_var: float, sigma: float,
        seed: int) -> None:
    """Scalar agent ``x`` (prior error independent of the nodes), ranges ``x + e_k + v_k`` to
    nodes whose errors ``e_k`` have any correlation (variances ``node_var``), each taken by a
    sequential scalar Kalman update as independent with variance ``sigma^2 + a P_node``: the
    filter's claimed variance is at least the true one (``a`` from :func:`pool_factor`)."""
    rng = np.random.default_rng(seed)
    k = len(node_var)
    f = rng.normal(size=(k, rng.integers(1, k + 1)))
    corr = f @ f.T + 1e-12 * np.eye(k)
    d = 1.0 / np.sqrt(np.diag(corr))
    sd = np.sqrt(node_var)
    cov = (d[:, None] * corr * d[None, :]) * sd[:, None] * sd[None, :]
    pool, t = UsePool(), 0.0
    p = prior_var
    gain_x = 1.0                      # posterior error = gain_x * e_x + g_e @ e + g_v @ v
    g_e = np.zeros(k)
    g_v: list[float] = []
    for m in windows:
        pool, a = pool_factor(pool, t_first_s=t, t_last_s=t + 1.0, ranges=m, gap_s=15.0)
        t += 2.0
        for _ in range(m):
            node = int(rng.integers(k))
            r = sigma ** 2 + a * node_var[node]
            gain = p / (p + r)        # x+ = x + K (z - x): error (1 - K) err + K (e + v)
            gain_x *= 1.0 - gain
            g_e *= 1.0 - gain
            g_e[node] += gain
            g_v = [(1.0 - gain) * g for g in g_v] + [gain]
            p *= 1.0 - gain
    true = gain_x ** 2 * prior_var + float(g_e @ cov @ g_e) + sigma ** 2 * float(np.sum(
        np.square(g_v)))
    assert p >= true * (1.0 - 1e-9)


def test_widening_with_and_without_the_cap() -> None:
    """Hand case: the third and fourth ranges of a pass, one window: ``a = 3 * 5`` capped, else
    ``N_after = 4``; ``c = 2`` for a second-order use only with the cap."""
    pool = UsePool(1.0, 2)
    kw = {"t_first_s": 2.0, "t_last_s": 3.0, "ranges": 2, "gap_s": 15.0}
    assert widening(pool, kind="independent", cap=True, **kw) == (UsePool(3.0, 4), 15.0)
    assert widening(pool, kind="second-order", cap=True, **kw)[1] == 30.0
    assert widening(pool, kind="direct", cap=True, **kw)[1] == 30.0
    assert widening(pool, kind="second-order", cap=False, **kw)[1] == 4.0
    assert widening(pool, kind="direct", cap=False, **kw)[1] == 8.0


def test_information_gate_hand_case() -> None:
    """Node at (10, 0) with variances 1 (x) and 100 (y) m^2; agent at the origin, 2 and 0.1.

    Along the line of sight (x): node 1 against agent 2: taken at ratio 1 (1 <= 2), not at 0.4
    (1 > 0.8). Seen from (10, -10) the line of sight is y: 100 against 0.1, never taken. At a
    common position the largest variances compare: 100 against 2.
    """
    node, pn = np.array([10.0, 0.0]), np.diag([1.0, 100.0])
    pa = np.diag([2.0, 0.1])
    assert informative(node, pn, np.zeros(2), pa, ratio=1.0)
    assert not informative(node, pn, np.zeros(2), pa, ratio=0.4)
    assert informative(node, pn, np.zeros(2), pa, ratio=0.5)             # 1 <= 0.5 * 2
    assert not informative(node, pn, np.array([10.0, -10.0]), pa, ratio=100.0)   # 100 > 10
    assert informative(node, pn, np.array([10.0, -10.0]), pa, ratio=1000.0)
    assert not informative(node, pn, node, pa, ratio=49.0)                 # 100 > 98
    assert informative(node, pn, node, pa, ratio=50.0)
    assert informative(node, pn, np.zeros(2), pa, ratio=math.inf)


def _cov(draw_l1: float, draw_l2: float, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c, -s], [s, c]])
    return r @ np.diag([draw_l1, draw_l2]) @ r.T


@settings(max_examples=200, deadline=None)
@given(st.floats(0.01, 10.0), st.floats(0.01, 10.0), st.floats(0.0, 3.2),
       st.floats(0.01, 10.0), st.floats(0.01, 10.0), st.floats(0.0, 3.2),
       st.floats(-50.0, 50.0), st.floats(-50.0, 50.0), st.floats(0.05, 20.0))
def test_information_gate_bounded_by_eigenvalues(a1: float, a2: float, aa: float, n1: float,
                                                  n2: float, na: float, x: float, y: float,
                                                  ratio: float) -> None:
    """An agent whose every variance times the ratio is below every node variance never takes
    the node's ranges, wherever it is; one whose smallest variance times the ratio is above the
    node's largest always does."""
    pa, pn = _cov(a1, a2, aa), _cov(n1, n2, na)
    node = np.array([3.0, -2.0])
    agent = np.array([x, y])
    if ratio * max(a1, a2) < 0.999 * min(n1, n2):
        assert not informative(node, pn, agent, pa, ratio=ratio)
    if ratio * min(a1, a2) > 1.001 * max(n1, n2):
        assert informative(node, pn, agent, pa, ratio=ratio)
    # monotone in the ratio
    if informative(node, pn, agent, pa, ratio=ratio):
        assert informative(node, pn, agent, pa, ratio=2.0 * ratio)
