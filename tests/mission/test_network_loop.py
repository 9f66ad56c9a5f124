"""Ranges between the dropped nodes in the mission loop: snapshot, seeded gain, offline CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.io.mission import NETWORK_RANGES_FILE, read_mission
from hrtls.io.tables import decode_table
from hrtls.mission.tracker import MissionParams, MissionResult, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission

from ._live import restored_half_way

runner = CliRunner()
SHORT = {"walk_s": 60.0, "stagger_s": 15.0, "n_nodes": 15}


def _scores(m: Mission, res: MissionResult) -> tuple[float, float, float]:
    """Share localized, RMSE (m) and mean NEES of the localized nodes."""
    d = [e.position_m - m.node_truth_m[n] for n, e in res.nodes.items() if e.localized]
    nees = [float(x @ np.linalg.solve(res.nodes[n].covariance_m2, x)) for x, n in
            zip(d, [n for n, e in res.nodes.items() if e.localized], strict=True)]
    return (len(d) / len(m.node_truth_m), float(np.sqrt(np.mean([x @ x for x in d]))),
            float(np.mean(nees)))


def _run(m: Mission, *, links: bool, config: TrackerConfig | None = None) -> MissionTracker:
    mt = MissionTracker({k: s.with_parts(truth=None, checkpoints=None)
                         for k, s in m.agents.items()}, kinds=m.kinds, config=config)
    if links:
        mt.feed_network(m.network_ranges)
    mt.run()
    return mt


def test_restored_half_way_with_node_ranges_the_mission_continues_identically() -> None:
    m = inderst_hybrid_mission(1, MissionOptions(**SHORT, node_ranges=True))
    assert len(m.network_ranges) > 0
    want_mt = _run(m, links=True)
    want = want_mt.result()
    sessions = {k: s.with_parts(truth=None, checkpoints=None) for k, s in m.agents.items()}
    mt = restored_half_way(sessions, dict(m.kinds), MissionParams(), network=m.network_ranges)
    got = mt.run()
    assert {n: e.localized for n, e in got.nodes.items()} == \
        {n: e.localized for n, e in want.nodes.items()}
    for n, e in want.nodes.items():
        if e.localized:
            np.testing.assert_array_equal(got.nodes[n].position_m, e.position_m)
            np.testing.assert_array_equal(got.nodes[n].covariance_m2, e.covariance_m2)
    np.testing.assert_array_equal(mt.network.used.t_s, want_mt.network.used.t_s)
    assert len(mt.network.used) > 0 and mt.network.late == 0


def test_node_ranges_localize_more_nodes_better_on_a_seeded_mission() -> None:
    """Dev seed 1, a 90 s mission with 20 nodes: the same recordings with and without the
    ranges between the nodes (scored against the truth here only). The links localize no
    fewer nodes (in 90 s the one more they used to add joined from an unconfirmed start,
    :func:`hrtls.mission.graph_links.confirmed`: 0.75 -> 0.70, the share without links);
    with the pairs' NLOS bias persistent (:mod:`hrtls.sim.node_links`) the error of the
    localized nodes is not lower here, only bounded."""
    m = inderst_hybrid_mission(1, MissionOptions(walk_s=90.0, stagger_s=20.0, n_nodes=20,
                                                 range_sigma_fraction=0.02, node_ranges=True))
    frac0, rmse0, nees0 = _scores(m, _run(m, links=False).result())
    frac1, rmse1, nees1 = _scores(m, _run(m, links=True).result())
    assert frac1 >= frac0
    assert rmse1 < 1.1 * rmse0
    assert nees1 <= max(nees0, 3.0)


def test_nodes_join_through_links_from_confirmed_starts_on_a_seeded_mission(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Dev seed 1, a 150 s mission with 30 nodes ranging each other (the truth read here only):
    of the starting points the nodes joining through their links get, few are more than 3 m
    off (3 of 28; without the confirmation, 22 of 71: mirrors, ill-conditioned
    trilaterations and misplaced neighbours, which the solve then keeps)."""
    from hrtls.mission import graph

    m = inderst_hybrid_mission(1, MissionOptions(walk_s=150.0, stagger_s=20.0, n_nodes=30,
                                                 range_sigma_fraction=0.02, node_ranges=True))
    errors: list[float] = []
    select = graph.select_linked

    def recorded(*args: object) -> tuple[dict[str, float], dict[str, np.ndarray]]:
        out, joined = select(*args)  # type: ignore[arg-type]
        errors.extend(float(np.linalg.norm(p - m.node_truth_m[n][:2])) for n, p in joined.items())
        return out, joined

    monkeypatch.setattr(graph, "select_linked", recorded)
    _run(m, links=True)
    assert len(errors) >= 10
    assert sum(e > 3.0 for e in errors) <= 5


def test_offline_mission_track_reads_network_ranges(tmp_path: Path) -> None:
    out = tmp_path / "m"
    args = ["simulate", "inderst_hybrid_mission", "--seed", "1", "-o", str(out),
            "-O", "node_ranges=true"]
    for k, v in SHORT.items():
        args += ["-O", f"{k}={v}"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert (out / NETWORK_RANGES_FILE).is_file()
    folder = read_mission(out)
    m = inderst_hybrid_mission(1, MissionOptions(**SHORT, node_ranges=True))
    np.testing.assert_array_equal(folder.network_ranges.range_m, m.network_ranges.range_m)

    def nodes_csv(where: Path, run: str) -> dict[str, tuple[float, float]]:
        res = runner.invoke(app, ["mission", "track", str(where), "-o", str(tmp_path / run)])
        assert res.exit_code == 0, res.output
        tab = decode_table((tmp_path / run / "nodes.csv").read_bytes(), table="nodes",
                           name="nodes.csv")
        ok = tab.str("localized") == "true"
        return {str(n): (x, y) for n, x, y in zip(tab.str("id")[ok], tab.float("x")[ok],
                                                  tab.float("y")[ok], strict=True)}

    got = nodes_csv(out, "with")
    want = _run(m, links=True, config=preset("default")).result().nodes
    assert got == {n: (e.position_m[0], e.position_m[1]) for n, e in want.items() if e.localized}
    (out / NETWORK_RANGES_FILE).unlink()
    assert nodes_csv(out, "without") != got                  # the file was used


@pytest.mark.parametrize("floors", [2])
def test_two_floors_link_only_nodes_of_one_floor(floors: int) -> None:
    m = inderst_hybrid_mission(2, MissionOptions(**SHORT, n_floors=floors, node_ranges=True))
    nr = m.network_ranges
    assert len(nr) > 0
    assert all(m.node_floor[a] == m.node_floor[b] for a, b in
               zip(nr.node_a.tolist(), nr.node_b.tolist(), strict=True))
    _run(m, links=True)
