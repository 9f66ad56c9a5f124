"""Inter-agent ranges: hand-computed exchange, simulator round trip, mission regression,
offline == incremental, snapshot round trip of the peers' state."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Session
from hrtls.data.observations import PositionFixes, RangeMeasurements
from hrtls.data.session import SessionMeta, StartPose
from hrtls.errors import InputError
from hrtls.io.session import read_session, write_session
from hrtls.mission.peers import PEER_SPEED_M_S, PeerRangeParams, extrapolate_peer
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import (
    RESCUER_PREDICTION,
    MissionOptions,
    inderst_hybrid_mission,
    run_mission,
)


def _robot(x: float, ranges: RangeMeasurements | None) -> Session:
    """A robot standing at (x, 0) for 20 s, odometry at 5 Hz, start sigma 1 m."""
    t = np.arange(0.0, 20.0, 0.2)
    xyz = np.column_stack([np.full(len(t), x), np.zeros(len(t)), np.zeros(len(t))])
    meta = SessionMeta(start_pose=StartPose(x=x, y=0.0, z=0.0, heading=0.0, sigma_xy_m=1.0,
                                            sigma_heading_rad=0.01))
    return Session(meta=meta, fixes=PositionFixes(t, xyz, np.full(len(t), 0.05)), ranges=ranges)


@pytest.mark.parametrize("extrapolate", [False, True])
def test_one_exact_range_pulls_a_toward_b_and_shrinks_its_covariance_along_the_line(
        extrapolate: bool) -> None:
    """A at (0, 0), B at (10, 0); A measures 9 m to B at t = 7 s (sigma 1 mm). Window [5, 10):
    A goes first, B's latest row is t_B = 4.8 s. Eq. 4.35 with H = (-1, 0):
    x_A += P_xx / (P_xx + s^2) * (9 - 10), P_xx *= s^2 / (P_xx + s^2),
    s^2 = (1e-3)^2 + lambda_max(P_B) + s_move^2; P_yy unchanged. B stands: its rows do not move,
    so the extrapolated landmark stays at (10, 0) with s_move^2 = q g^3 / 3 (no velocity
    spread), g = 2.2 s; held: s_move^2 = (PEER_SPEED_M_S g)^2. The widening rule (two
    robots: by default they would intersect, ``tests/mission/test_robot_peers.py``)."""
    prm = MissionParams(peer_ranges=PeerRangeParams(extrapolate=extrapolate, rule="widen"))
    rg = RangeMeasurements(np.array([7.0]), np.array(["B"]), np.array([9.0]), np.array([1e-3]))
    alone = MissionTracker({"A": _robot(0.0, None), "B": _robot(10.0, None)},
                           kinds={"A": "robot", "B": "robot"}, params=prm).run()
    res = MissionTracker({"A": _robot(0.0, rg), "B": _robot(10.0, None)},
                         kinds={"A": "robot", "B": "robot"}, params=prm).run()
    before, after = alone.agents["A"].trajectory, res.agents["A"].trajectory
    k = int(np.searchsorted(before.t, 7.0))
    p = before.cov_xy[k]
    pb = alone.agents["B"].trajectory.cov_xy[int(np.searchsorted(before.t, 4.8))]
    move = (prm.peer_ranges.accel_sigma_m_s2 ** 2 * 2.2 ** 3 / 3 if extrapolate
            else (PEER_SPEED_M_S * 2.2) ** 2)
    s2 = 1e-6 + float(np.linalg.eigvalsh(pb)[-1]) + move
    gain = p[0, 0] / (p[0, 0] + s2)
    np.testing.assert_allclose(after.xyz[k, 0], before.xyz[k, 0] - gain * (9.0 - 10.0),
                               rtol=1e-6)
    assert after.xyz[k, 0] > before.xyz[k, 0]              # toward B
    np.testing.assert_allclose(after.cov_xy[k, 0, 0], p[0, 0] * s2 / (p[0, 0] + s2), rtol=1e-6)
    np.testing.assert_allclose(after.cov_xy[k, 1, 1], p[1, 1], rtol=1e-6)
    np.testing.assert_allclose(res.agents["B"].trajectory.xyz,
                               alone.agents["B"].trajectory.xyz)


def test_extrapolation_of_a_peer_by_hand() -> None:
    """Rows at 0, 1, 2, 3 s at x = 0, 1, 3, 4 m (y = 0), window 2 s, range at 4 s (g = 1 s).
    Window rows 1..3 s: v = (4 - 1) / 2 = 1.5 m/s; segment velocities 2, 1 (1 s each) deviate
    by +0.5, -0.5: S_v = diag(0.5 * 0.25 + 0.5 * 0.25, 0) = diag(0.25, 0); the row at 5 s is
    later than the range and ignored. x = 4 + 1.5 = 5.5; s_ext^2 = 1 * 0.25 + 0.3^2 / 3."""
    t = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    xy = np.column_stack([[0.0, 1.0, 3.0, 4.0, 100.0], np.zeros(5)])
    prm = PeerRangeParams(extrapolate=True, velocity_window_s=2.0, accel_sigma_m_s2=0.3)
    got = extrapolate_peer(t_s=t, xy_m=xy, at_s=4.0, params=prm)
    np.testing.assert_allclose(got.xy_m, [5.5, 0.0])
    np.testing.assert_allclose(got.velocity_m_s, [1.5, 0.0])
    np.testing.assert_allclose(got.var_m2, 0.25 + 0.09 / 3.0)
    held = extrapolate_peer(t_s=t, xy_m=xy, at_s=4.0,
                            params=PeerRangeParams(extrapolate=False))
    np.testing.assert_allclose(held.xy_m, [4.0, 0.0])
    np.testing.assert_allclose(held.var_m2, PEER_SPEED_M_S ** 2)
    one = extrapolate_peer(t_s=t[:1], xy_m=xy[:1], at_s=2.0, params=prm)
    np.testing.assert_allclose([*one.xy_m, one.var_m2], [0.0, 0.0, (2.0 * PEER_SPEED_M_S) ** 2])
    with pytest.raises(InputError, match="velocity_window_s"):
        PeerRangeParams(velocity_window_s=0.0)


OPTIONS = MissionOptions(walk_s=90.0, stagger_s=10.0, n_nodes=15, n_robots=1, peer_ranges=True)


@pytest.fixture(scope="module")
def mission():  # type: ignore[no-untyped-def]
    return inderst_hybrid_mission(3, OPTIONS)


def test_simulated_peer_ranges_name_the_other_agents_and_round_trip(mission, tmp_path) -> None:  # type: ignore[no-untyped-def]
    plain = inderst_hybrid_mission(3, MissionOptions(**{**OPTIONS.__dict__,
                                                        "peer_ranges": False}))
    for name, s in mission.agents.items():
        assert s.ranges is not None
        peers = np.isin(s.ranges.node, list(mission.agents))
        assert peers.any() and name not in set(s.ranges.node[peers].tolist())
        assert np.all(np.diff(s.ranges.t) >= 0)
        base = plain.agents[name].ranges
        assert base is not None
        np.testing.assert_array_equal(s.ranges.range_m[~peers], base.range_m)
        back = read_session(write_session(s, tmp_path / name))
        assert back.ranges is not None
        np.testing.assert_array_equal(back.ranges.node, s.ranges.node)
        np.testing.assert_allclose(back.ranges.range_m, s.ranges.range_m, atol=1e-6)
        np.testing.assert_allclose(back.ranges.t, s.ranges.t, atol=1e-6)


def test_run_mission_takes_a_boolean_peer_ranges_only() -> None:
    with pytest.raises(InputError, match="true or false"):
        run_mission("inderst_hybrid_mission", 0, peer_ranges=1)


@pytest.mark.parametrize("extrapolate", [False, True])
def test_offline_equals_incremental_with_peer_ranges_and_snapshot(mission, extrapolate) -> None:  # type: ignore[no-untyped-def]
    from hrtls.pipeline.chunks import split_session

    prm = MissionParams(peer_ranges=PeerRangeParams(extrapolate=extrapolate))
    sessions = {k: s.with_parts(truth=None, checkpoints=None) for k, s in mission.agents.items()}
    want = MissionTracker(sessions, kinds=mission.kinds, params=prm).run()
    from hrtls.mission.tracker import AgentHeader

    mt = MissionTracker({k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()},
                        kinds=mission.kinds, params=prm)
    parts = sorted(((k, p) for k, s in sessions.items() for p in split_session(s, 2.0)),
                   key=lambda kp: kp[1].time_span()[1])
    for j, (name, part) in enumerate(parts):
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
        if j == len(parts) // 2:
            assert mt.peers.uses
            mt = MissionTracker.restore(mt.snapshot())
            assert mt.params == prm
    for k in sessions:
        mt.end(k)
    got = mt.run()
    for k, r in want.agents.items():
        tail = got.agents[k].trajectory      # the restored tracker's rows: from the restore on
        i = int(np.searchsorted(r.trajectory.t, tail.t[0]))
        assert len(r.trajectory.t) - i == len(tail.t) > 0
        np.testing.assert_allclose(tail.xyz, r.trajectory.xyz[i:], atol=1e-9)
        np.testing.assert_allclose(tail.cov_xy, r.trajectory.cov_xy[i:], atol=1e-9)


@pytest.mark.parametrize("mode", ["off", "feedback"])
def test_peer_ranges_lower_the_rescuers_error_without_blowing_nees(mode: str) -> None:
    """Seeded regression (short mission), smoother ``off`` (seeds 3-5) and ``feedback`` (the
    default, with the peer factors; all dev seeds 0-9): the rescuers' mean error and NEES with
    and without inter-agent ranges.

    Measured mean error without / with, m: ``off`` 1.49 / 1.45, 2.67 / 2.48, 1.91 / 1.77;
    ``feedback`` seeds 0-9: 1.60 / 1.66, 1.84 / 1.55, 1.28 / 1.16, 1.49 / 1.43, 2.43 / 2.36,
    1.55 / 1.70, 2.73 / 2.66, 1.07 / 0.98, 1.08 / 1.07, 1.64 / 1.64 (mean 1.67 / 1.62; the
    peers as tracker corrections before the factors: 1.64, seed 3 1.64), docs/mission.md.
    """
    from hrtls.mission.smoother_modes import smoother_params

    out: dict[str, list[tuple[float, float]]] = {"off": [], "on": []}
    for seed in ((3, 4, 5) if mode == "off" else range(10)):
        for key, peers in (("off", False), ("on", True)):
            m = inderst_hybrid_mission(seed, MissionOptions(**{**OPTIONS.__dict__,
                                                               "peer_ranges": peers}))
            res = MissionTracker(m.agents, kinds=m.kinds, config=TrackerConfig.model_validate(
                {"prediction": RESCUER_PREDICTION}), params=MissionParams(
                    smoother=smoother_params(mode))).run()
            e, nees = [], []
            for name, r in res.agents.items():
                if m.kinds[name] != "rescuer":
                    continue
                truth = m.simulations[name].session.truth
                tr = r.trajectory
                d = np.column_stack([tr.xyz[:, 0] - np.interp(tr.t, truth.t, truth.xyz[:, 0]),
                                     tr.xyz[:, 1] - np.interp(tr.t, truth.t, truth.xyz[:, 1])])
                e.append(np.hypot(d[:, 0], d[:, 1]))
                nees.append(np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy), d))
            out[key].append((float(np.mean(np.concatenate(e))),
                             float(np.mean(np.concatenate(nees)))))
    print(out)
    for (e_off, n_off), (e_on, n_on) in zip(out["off"], out["on"], strict=True):
        assert n_on < 2.0 * n_off + 2.0
        if mode == "off":
            assert e_on < e_off + 0.05
    assert np.mean([e for e, _ in out["on"]]) < np.mean([e for e, _ in out["off"]])


def test_cli_simulate_writes_peer_ranges_and_mission_track_reads_them(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from typer.testing import CliRunner

    from hrtls.cli.app import app
    from hrtls.io.tables import read_trajectory

    root = tmp_path / "m"
    res = CliRunner().invoke(app, ["simulate", "inderst_hybrid_mission", "-o", str(root),
                                   "--seed", "3", "-O", "peer_ranges=true", "-O", "walk_s=40",
                                   "-O", "stagger_s=5", "-O", "n_nodes=5"])
    assert res.exit_code == 0, res.output
    text = (root / "agents" / "R1" / "ranges.csv").read_text()
    assert ",R2," in text
    res = CliRunner().invoke(app, ["mission", "track", str(root), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert len(read_trajectory(tmp_path / "out" / "agents" / "R1" / "trajectory.csv").t) > 10


def test_the_peer_range_parameters_survive_a_snapshot() -> None:
    prm = MissionParams(peer_ranges=PeerRangeParams(extrapolate=False, velocity_window_s=3.5,
                                                    accel_sigma_m_s2=0.7))
    mt = MissionTracker({"A": _robot(0.0, None), "B": _robot(10.0, None)},
                        kinds={"A": "robot", "B": "robot"}, params=prm)
    assert MissionTracker.restore(mt.snapshot()).params == prm


def test_rows_are_kept_for_the_velocity_window_only_when_extrapolating() -> None:
    from hrtls.mission.readings import trim_rows

    t = np.arange(0.0, 10.0, 0.5)
    rows = (t, np.column_stack([t, t]), np.repeat(np.eye(2)[None], len(t), axis=0))
    assert trim_rows(rows, 9.2)[0][0] == 8.5                    # the row before the last <= 9.2
    kept = PeerRangeParams(extrapolate=True).rows_kept_s()
    assert trim_rows(rows, 9.2, keep_s=kept)[0][0] == 9.0 - kept - 0.5
    assert PeerRangeParams().rows_kept_s() == 0.0              # the default holds the peer
