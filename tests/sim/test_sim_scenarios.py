"""Every paper scenario runs, writes a valid session with ground truth, and the CLI works."""

from __future__ import annotations

import json

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from hrtls.cli import sim as sim_cli
from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.io.session import read_session
from hrtls.sim.scenarios import SCENARIOS, run_scenario, write_result


@pytest.fixture(scope="module")
def results():
    return {name: run_scenario(name, 0) for name in SCENARIOS}


def test_registry_covers_the_papers():
    expected = {"colombo_circle", "colombo_square", "colombo_natural", "tarrio_circle",
                "tarrio_office", "inderst_ring", "inderst_multifloor", "inderst_two_users",
                "inderst_wsn_random", "inderst_wsn_building"}
    assert expected <= set(SCENARIOS)
    assert {f"basso_test{i}" for i in range(1, 7)} <= set(SCENARIOS)


def test_every_scenario_has_truth(results):
    for name, r in results.items():
        s = r.session
        assert s.truth is not None, name
        assert len(s.truth) > 100, name
        assert r.activity.shape == r.activity_t.shape, name
        if s.imu is not None:
            assert r.true_steps.distance_m == pytest.approx(r.motion.distance_m, rel=1e-6), name
            assert s.meta.start_pose is not None
            assert s.meta.user.step_model == {}  # calibrated by the user, not given


def test_colombo_fixes_only_while_moving(results):
    r = results["colombo_natural"]
    speed = np.interp(r.session.fixes.t, r.motion.t, r.motion.speed)
    assert np.all(speed > 0.2)
    assert r.session.imu.accel.rate_hz == pytest.approx(250.0, rel=0.01)
    assert results["colombo_circle"].motion.distance_m == pytest.approx(31.0, rel=0.01)


def test_basso_lengths_pace_and_orientation(results):
    for i, length in enumerate([433, 399, 551, 578, 1124, 3262], start=1):
        r = results[f"basso_test{i}"]
        assert r.motion.distance_m == pytest.approx(length, rel=0.02)
        assert r.session.orientation is not None
        assert r.session.meta.mounting_q_bd is None  # any orientation: not declared
        assert len(r.hidden_truth["mounting_q_bd"]) == 4
        assert r.session.imu.accel.rate_hz == pytest.approx(50.0, rel=0.05)
    assert Activity.RUNNING in set(results["basso_test6"].activity.tolist())
    assert Activity.RUNNING not in set(results["basso_test1"].activity.tolist())


def test_tarrio_channel_and_anchors(results):
    r = results["tarrio_circle"]
    s = r.session
    assert len([k for k, v in s.landmarks.items() if v.kind == "anchor"]) == 9
    assert s.meta.channel is None  # surveyed or estimated online, not given
    assert r.hidden_truth["channel"]["eta"] == 2.5
    assert np.all(s.rss.rss_dbm >= -95.0)
    c = np.array([10.0, 10.0])
    np.testing.assert_allclose(np.hypot(*(s.truth.xyz[:, :2] - c).T)[s.truth.t > 6], 8.0,
                               atol=0.05)


def test_inderst_tag_sets():
    all_tags = run_scenario("inderst_ring", 0, distance_m=120.0)
    corners = run_scenario("inderst_ring", 0, distance_m=120.0, tags="corners")
    no5 = run_scenario("inderst_ring", 0, distance_m=120.0, tags="no_tag5")
    assert len(all_tags.session.landmarks) == 9
    assert len(corners.session.landmarks) == 5
    assert "T5" not in no5.session.landmarks
    assert set(corners.session.tags.tag.tolist()) <= set(corners.session.landmarks)
    with pytest.raises(InputError):
        run_scenario("inderst_ring", 0, tags="bogus")


def test_multifloor_goes_up_and_down(results):
    r = results["inderst_multifloor"]
    acts = set(r.activity.tolist())
    assert {Activity.UPSTAIRS, Activity.DOWNSTAIRS} <= acts
    assert r.session.truth.xyz[:, 2].max() == pytest.approx(3.3)
    up = r.true_steps.activity == Activity.UPSTAIRS
    np.testing.assert_allclose(r.true_steps.length_m[up], 0.30, rtol=0.15)
    assert r.session.checkpoints is not None and len(r.session.checkpoints) >= 9


def test_two_users_turn_differently(results):
    a = results["inderst_two_users"]
    b = run_scenario("inderst_two_users", 0, user="B")
    standing_a = np.sum(a.activity == Activity.STANDING)
    standing_b = np.sum(b.activity == Activity.STANDING)
    assert standing_a > standing_b
    assert a.motion.distance_m == pytest.approx(305.0, rel=0.05)


def test_wsn_scenarios(results):
    r = results["inderst_wsn_random"]
    assert r.wsn is not None and len(r.wsn.ids) == 50
    assert np.all(r.session.ranges.range_m <= 0.2 + 0.05)
    b = results["inderst_wsn_building"]
    assert b.wsn is not None and len(b.wsn.ids) == 12
    assert b.session.ranges is not None and b.session.imu is not None


def test_unknown_scenario_or_option():
    with pytest.raises(InputError):
        run_scenario("nope", 0)
    with pytest.raises(InputError):
        run_scenario("colombo_circle", 0, bogus=1)


@pytest.mark.filterwarnings("ignore::hrtls.errors.DegradedInputWarning")
def test_write_and_read_back(tmp_path, results):
    for name in ("tarrio_office", "inderst_wsn_random"):
        out = write_result(results[name], tmp_path / name)
        s = read_session(out)
        assert s.truth is not None
        np.testing.assert_allclose(s.truth.xyz, results[name].session.truth.xyz, atol=1e-6)
        assert (out / "truth_steps.csv").exists()
        assert (out / "activity.csv").read_text().startswith("t_start,t_end,activity")
        info = json.loads((out / "scenario.json").read_text())
        assert info["scenario"] == name
        assert "truth" in info
    wsn = json.loads((tmp_path / "inderst_wsn_random" / "wsn.json").read_text())
    assert set(wsn) == {"radius", "nodes", "links"}


def _app() -> typer.Typer:
    app = typer.Typer()
    app.command("simulate")(sim_cli.simulate)
    app.command("evaluate")(sim_cli.evaluate)
    return app


def test_cli_simulate_and_evaluate(tmp_path):
    runner = CliRunner()
    res = runner.invoke(_app(), ["simulate", "--list"])
    assert res.exit_code == 0 and "inderst_ring" in res.output
    out = tmp_path / "sess"
    res = runner.invoke(_app(), ["simulate", "colombo_square", "-o", str(out), "--seed", "3",
                                 "-O", "laps=2", "-O", "tp_s=4"])
    assert res.exit_code == 0, res.output
    assert (out / "imu.csv").exists() and (out / "fixes.csv").exists()
    # a perfect "estimate": the truth itself
    from hrtls.data import Trajectory
    from hrtls.io.tables import read_steps, write_steps, write_trajectory

    s = read_session(out)
    result = tmp_path / "res"
    result.mkdir()
    write_trajectory(Trajectory.build(t=s.truth.t, xyz=s.truth.xyz, heading_rad=s.truth.heading_rad,
                                      activity=np.ones(len(s.truth), int)),
                     result / "trajectory.csv")
    write_steps(read_steps(out / "truth_steps.csv"), result / "steps.csv")
    res = runner.invoke(_app(), ["evaluate", str(result), "--truth", str(out)])
    assert res.exit_code == 0, res.output
    report = json.loads((result / "evaluation.json").read_text())
    assert report["position"]["max"] < 1e-6
    assert report["steps"]["count_error"] == 0
    for png in ("evaluation_trajectory.png", "evaluation_error.png", "evaluation_cdf.png"):
        assert (result / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    res = runner.invoke(_app(), ["simulate", "nope", "-o", str(tmp_path / "x")])
    assert res.exit_code == 2


def test_parse_options():
    assert sim_cli.parse_options(["a=1", "b=2.5", "c=true", "d=corners"]) == {
        "a": 1, "b": 2.5, "c": True, "d": "corners"}
    with pytest.raises(InputError):
        sim_cli.parse_options(["novalue"])
