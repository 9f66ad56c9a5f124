"""The sensor-network layer of the dashboard, in chromium, on a real networked mission.

A small simulated ``inderst_hybrid_mission`` (seed 2: two rescuers, ten dropped nodes; the
agents' sessions without ground truth) becomes a service mission with its nodes declared
(``PUT /missions/{m}/network``) and is streamed by the real agent client to a real
``hrtls serve``, whose mission estimator localizes the nodes from the agents' ranges. First the
data up to ``CUT_S``, then the rest and the mission's close: the page must show, without a
reload, what the API lists after each part. The ellipse's geometry (``js/geometry.js``) is
checked against numpy on hand cases.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest
from tests.service.streams import stream_agents

from hrtls.service.client import AgentClient
from hrtls.service.network_sim import common_offset, create_network_mission, network_team

from .conftest import Service, login

pytestmark = pytest.mark.slow

OPTIONS = {"walk_s": 30.0, "stagger_s": 5.0, "n_nodes": 10, "n_rescuers": 2}
SEED = 2
CUT_S = 50.0
PARAMS = {"silent_after_s": 120.0}   # the windows past the cut wait for the rest or the close


def _network(service: Service, mid: int) -> list[dict[str, Any]]:
    status, net = service.api("GET", f"/missions/{mid}/network")
    assert status == 200, net
    assert isinstance(net, dict)
    return list(net["nodes"])


def _wait_network(service: Service, mid: int, done: Any, timeout_s: float = 60.0
                  ) -> list[dict[str, Any]]:
    deadline = time.monotonic() + timeout_s
    while True:
        nodes = _network(service, mid)
        if done(nodes):
            return nodes
        assert time.monotonic() < deadline, f"network not as expected: {nodes}"
        time.sleep(0.3)


def _settled(service: Service, mid: int, quiet_s: float = 1.5) -> list[dict[str, Any]]:
    """The network once it stayed the same for ``quiet_s`` (the estimator's polls are done)."""
    nodes, since = _network(service, mid), time.monotonic()
    deadline = since + 30.0
    while time.monotonic() - since < quiet_s:
        assert time.monotonic() < deadline, "the network keeps changing"
        time.sleep(0.3)
        now = _network(service, mid)
        if now != nodes:
            nodes, since = now, time.monotonic()
    return nodes


def _count_text(nodes: list[dict[str, Any]]) -> str:
    """The panel's line, from the API's nodes."""
    loc = sum(1 for n in nodes if n["localized"])
    declared = sum(1 for n in nodes if n["declared"])
    heard = sum(1 for n in nodes if n["readings"] > 0)
    extra = len(nodes) - declared
    return (f"nodes: {loc} localized of {declared} declared, {heard} heard"
            + (f" ({extra} not declared)" if extra else ""))


def _shown(page) -> dict[str, Any]:
    return page.evaluate("""() => ({
        markers: [...document.querySelectorAll('path.node-marker')].map(e =>
            [...e.classList].find(c => c.startsWith('node-id-')).slice(8)).sort(),
        ellipses: document.querySelectorAll('path.node-ellipse').length,
        count: document.getElementById('node-count').textContent,
        listed: [...document.querySelectorAll('#node-list li')].map(li =>
            [li.dataset.node, li.dataset.state]),
    })""")


def _check_page(page, nodes: list[dict[str, Any]]) -> list[str]:
    """The page shows the API's nodes: markers and ellipses of the localized, the rest listed."""
    localized = sorted(n["id"] for n in nodes if n["localized"])
    want_text = _count_text(nodes)
    page.wait_for_function("([ids, text]) => document.getElementById('node-count').textContent "
                           "=== text && document.querySelectorAll('path.node-marker').length "
                           "=== ids.length", arg=[localized, want_text], timeout=20_000)
    shown = _shown(page)
    assert shown["markers"] == localized and shown["ellipses"] == len(localized)
    assert shown["count"] == want_text
    heard = sorted(n["id"] for n in nodes if not n["localized"] and n["readings"] > 0)
    never = sorted(n["id"] for n in nodes if n["readings"] == 0)
    assert shown["listed"] == [[i, "heard"] for i in heard] + [[i, "declared"] for i in never]
    return localized


def test_node_layer_follows_the_live_mission_estimator(page, page_log, service, screenshot):
    mission, members = network_team("inderst_hybrid_mission", seed=SEED, options=OPTIONS)
    with AgentClient(service.url, service.token) as commander:
        mid, agents = create_network_mission(commander, "nodes", mission, members,
                                             params=PARAMS)
        offset = common_offset(commander, mid, members)
    seqs = stream_agents(service.url, agents, offset, t_from=-math.inf, t_to=offset + CUT_S,
                   first_seq=None)
    _wait_network(service, mid, lambda ns: any(n["localized"] for n in ns)
                  and any(not n["localized"] and n["readings"] for n in ns))
    first = _settled(service, mid)

    login(page, service)
    page.goto(f"{service.url}/?mission={mid}")
    page.wait_for_selector("#app:not([hidden])")
    page.evaluate("() => { window.notReloaded = true; }")
    loc1 = _check_page(page, first)
    assert any(n["readings"] == 0 for n in first), "every node heard: no never-heard state"

    node = next(n for n in first if n["localized"])
    x, y = node["position"]
    page.evaluate("([x, y]) => window.hrtlsDashboard.map.map.setView([y, x], 4)", [x, y])
    page.hover(f"path.node-marker.node-id-{node['id']}")
    tip = page.wait_for_selector(".node-tooltip").text_content() or ""
    assert f"node {node['id']}" in tip and f"σ {node['sigma_m']:.2f} m" in tip
    r, p = node["readings"], node["passes"]
    assert f"{r} reading{'' if r == 1 else 's'} in {p} pass{'' if p == 1 else 'es'}" in tip
    t = int(node["t"])
    assert f"estimated at t {t // 60}:{t % 60:02d}" in tip
    screenshot(page, "nodes_first_part")

    page.uncheck("#layer-nodes")
    assert page.locator("path.node-marker").count() == 0
    assert page.locator("path.node-ellipse").count() == 0
    assert page.locator("#node-list li").count() == len(first) - len(loc1)   # still listed
    page.check("#layer-nodes")
    page.wait_for_function("n => document.querySelectorAll('path.node-marker').length === n",
                           arg=len(loc1))

    stream_agents(service.url, agents, offset, t_from=offset + CUT_S, t_to=math.inf, first_seq=seqs)
    status, _ = service.api("PATCH", f"/missions/{mid}", {"status": "closed"})
    assert status == 200
    _wait_network(service, mid, lambda ns: len([n for n in ns if n["localized"]]) > len(loc1))
    final = _settled(service, mid)
    loc2 = _check_page(page, final)
    assert set(loc2) - set(loc1), "no newly localized node"
    assert page.evaluate("() => window.notReloaded === true")
    screenshot(page, "nodes_final")
    page_log.assert_clean()


def test_node_ellipse_against_numpy_hand_cases(geometry):
    """The 95 % ellipse's semi-axes and angle from the eigen-decomposition of the covariance."""
    rot = math.radians(30.0)
    r = np.array([[math.cos(rot), -math.sin(rot)], [math.sin(rot), math.cos(rot)]])
    cases = [np.diag([4.0, 1.0]), np.diag([1.0, 9.0]), r @ np.diag([2.25, 0.25]) @ r.T,
             np.array([[1.0, 1.0], [1.0, 1.0]]), np.eye(2) * 0.04]
    out = geometry.evaluate("""async (covs) => {
        const g = await import('./js/geometry.js');
        return [g.chi2Scale2d(0.95), covs.map((c) => g.covarianceEllipse(c, 0.95))];
    }""", [c.tolist() for c in cases])
    k, axes = out
    assert k == pytest.approx(math.sqrt(5.991464547107979), rel=1e-12)   # chi2.ppf(0.95, 2)
    for cov, got in zip(cases, axes, strict=True):
        w, v = np.linalg.eigh(cov)
        assert got["a"] == pytest.approx(k * math.sqrt(w[1]), rel=1e-12)
        assert got["b"] == pytest.approx(k * math.sqrt(max(w[0], 0.0)), abs=1e-7)
        if w[1] - w[0] > 1e-9:
            major = np.array([math.cos(got["angle"]), math.sin(got["angle"])])
            assert abs(major @ v[:, 1]) == pytest.approx(1.0, abs=1e-12)
    # by hand: diag(4, 1): a = 2k, b = k along x; rotated by 30 deg: a = 1.5k at 30 deg;
    # [[1, 1], [1, 1]] (rank 1): a = sqrt(2) k at 45 deg, b = 0
    assert (axes[0]["a"], axes[0]["b"], axes[0]["angle"]) == pytest.approx((2 * k, k, 0.0))
    assert abs(axes[1]["angle"]) == pytest.approx(math.pi / 2) and axes[1]["a"] == \
        pytest.approx(3 * k)
    assert (axes[2]["a"], axes[2]["b"], axes[2]["angle"]) == pytest.approx((1.5 * k, 0.5 * k,
                                                                           rot))
    assert (axes[3]["a"], axes[3]["b"], axes[3]["angle"]) == pytest.approx(
        (math.sqrt(2) * k, 0.0, math.pi / 4), abs=1e-7)
    assert axes[4]["a"] == pytest.approx(0.2 * k) and axes[4]["b"] == pytest.approx(0.2 * k)
