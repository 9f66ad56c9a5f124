"""Mission folders: simulate -> save -> `hrtls mission track`, equal to the in-memory tracker."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.data.observations import RangeMeasurements
from hrtls.errors import DegradedInputWarning
from hrtls.io.mission import read_mission, write_mission
from hrtls.io.tables import decode_table, read_trajectory
from hrtls.mission.smoother_modes import smoother_mode, smoother_params
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline.finish import finish_track
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission, mission_tags

runner = CliRunner()
SEED = 1
OPTIONS = {"walk_s": 60.0, "stagger_s": 10.0, "n_nodes": 10}
"""A short mission (the default tags at the doors and one robot) in which one rescuer uses
nodes the others localized."""


@pytest.fixture(scope="module")
def mission():  # type: ignore[no-untyped-def]
    return inderst_hybrid_mission(SEED, MissionOptions(**OPTIONS))


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("mission") / "m"
    args = ["simulate", "inderst_hybrid_mission", "--seed", str(SEED), "-o", str(out)]
    for k, v in OPTIONS.items():
        args += ["-O", f"{k}={v}"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    return out


def _track(saved: Path, out: Path, *extra: str) -> str:
    res = runner.invoke(app, ["mission", "track", str(saved), "-o", str(out), *extra])
    assert res.exit_code == 0, res.output
    return " ".join(res.output.split())


def test_saved_folder_reads_back_the_mission(mission, saved: Path) -> None:  # type: ignore[no-untyped-def]
    folder = read_mission(saved)
    assert list(folder.agents) == list(mission.agents)
    assert set(folder.nodes) == set(mission.node_truth_m)
    assert folder.node_truth_m is not None
    for k, v in mission.node_truth_m.items():
        np.testing.assert_array_equal(folder.node_truth_m[k], v)
    o = MissionOptions()
    tags = mission_tags(layout=o.tag_layout, door_spacing_m=o.door_spacing_m)
    assert sorted(folder.landmarks) == sorted(t.id for t in tags)
    assert {n: a.kind for n, a in folder.agents.items()} == {
        "R1": "rescuer", "R2": "rescuer", "R3": "rescuer", "B1": "robot"}
    for name, agent in folder.agents.items():
        src = mission.agents[name]
        if agent.kind == "rescuer":
            np.testing.assert_array_equal(agent.session.imu.accel.values, src.imu.accel.values)
        else:
            np.testing.assert_array_equal(agent.session.fixes.xyz, src.fixes.xyz)
        np.testing.assert_array_equal(agent.session.ranges.range_m, src.ranges.range_m)
        np.testing.assert_array_equal(agent.session.truth.xyz, src.truth.xyz)
        assert all(lm.kind != "node" for lm in agent.session.landmarks.values())
    # what the estimator gets holds no ground truth
    assert all(s.truth is None and s.checkpoints is None for s in folder.sessions().values())
    assert "position" not in (saved / "network.json").read_text()


@pytest.mark.parametrize(("cooperate", "chunk_s", "smoother"),
                         [(True, 5.0, None), (False, 4.0, None), (True, 5.0, "feedback")])
def test_offline_track_equals_the_in_memory_tracker(mission, saved: Path, tmp_path: Path,
                                                    cooperate: bool, chunk_s: float,
                                                    smoother: str | None
                                                    ) -> None:  # type: ignore[no-untyped-def]
    flags = ["--chunk-s", str(chunk_s)] + ([] if cooperate else ["--no-cooperate"])
    prm = MissionParams(cooperate=cooperate, chunk_s=chunk_s)
    if smoother is not None:
        flags += ["--smoother", smoother]
        prm = dataclasses.replace(prm, smoother=smoother_params(smoother))
    text = _track(saved, tmp_path / "out", *flags)
    assert f"smoother {smoother_mode(prm.smoother)}" in text
    cfg = preset("default")
    res = MissionTracker(mission.agents, config=cfg, kinds=mission.kinds, params=prm).run()
    for name, raw in res.agents.items():
        want = finish_track(raw, mission.agents[name], cfg).trajectory
        got = read_trajectory(tmp_path / "out" / "agents" / name / "trajectory.csv")
        np.testing.assert_array_equal(got.t, want.t)
        np.testing.assert_array_equal(got.xyz, want.xyz)
        np.testing.assert_array_equal(got.cov_xy, want.cov_xy)
        report = json.loads((tmp_path / "out" / "agents" / name / "report.json").read_text())
        assert report["evaluation"]["position"]["mean"] > 0
        assert report["mission"]["cooperate"] is cooperate
        assert name in text
    summary = json.loads((tmp_path / "out" / "report.json").read_text())
    assert summary["params"] == {
        "cooperate": cooperate, "chunk_s": chunk_s, "loop_closure_ratio": 4.0,
        "pass_cap": True, "use_variance_ratio": None, "agent_cov_scale": 2.0,
        "agent_correlation": 0.5, "smoother": smoother_mode(prm.smoother), "config": "default"}
    assert summary["loop_closures"] == [
        {"t": c.t, "agent": c.agent, "node": c.node, "trace_now_m2": c.trace_now_m2,
         "trace_readings_m2": c.trace_readings_m2} for c in res.closures]
    assert bool(res.closures) <= cooperate
    fixes = sum(r.report["corrections"].get("range", {}).get("accepted", 0)
                for r in res.agents.values())
    assert (fixes > 0) is cooperate
    for name, r in res.agents.items():     # the rescuers' trackers take the door tags as fixes
        tags = r.report["corrections"].get("tag", {}).get("accepted", 0)
        assert (tags > 0) is (mission.kinds[name] == "rescuer"), (name, tags)
    nodes = decode_table((tmp_path / "out" / "nodes.csv").read_bytes(), table="nodes",
                         name="nodes.csv")
    ids = list(nodes.str("id"))
    assert set(ids) == set(mission.node_truth_m)
    localized = nodes.str("localized") == "true"
    assert set(np.asarray(ids)[localized]) == {n for n, e in res.nodes.items() if e.localized}
    assert localized.any() or not cooperate
    for i in np.flatnonzero(localized):
        est = res.nodes[ids[i]]
        assert nodes.float("x")[i] == est.position_m[0]
        assert nodes.float("var_y")[i] == est.covariance_m2[1, 1]
    np.testing.assert_array_equal(nodes.float("readings"),
                                  [res.readings.get(n, 0) for n in ids])
    summary = json.loads((tmp_path / "out" / "report.json").read_text())
    score = summary["nodes"]["score"]
    errors = [float(np.hypot(*(res.nodes[n].position_m - mission.node_truth_m[n])))
              for n in score["errors_m"]]
    assert score["localized"] == len(errors) == np.count_nonzero(localized)
    if errors:
        assert score["rmse_m"] == pytest.approx(float(np.sqrt(np.mean(np.square(errors)))))
        assert f"RMSE {score['rmse_m']:.2f} m" in text
    else:
        assert score["rmse_m"] is None and "RMSE - m" in text


def test_falsified_truth_changes_no_estimate(mission, saved: Path, tmp_path: Path
                                             ) -> None:  # type: ignore[no-untyped-def]
    fake = tmp_path / "fake"
    shutil.copytree(saved, fake)
    for name in mission.agents:
        truth = fake / "agents" / name / "truth.csv"
        lines = truth.read_text().splitlines()
        rows = [line.split(",") for line in lines[1:]]
        truth.write_text("\n".join([lines[0]] + [",".join([r[0], str(float(r[1]) + 50.0),
                                                            *r[2:]]) for r in rows]) + "\n")
    _edit(fake / "network_truth.json",
          lambda d: [n.update(position=[0.0, 0.0]) for n in d["nodes"]])
    a, b = tmp_path / "a", tmp_path / "b"
    _track(saved, a)
    _track(fake, b)
    for name in mission.agents:
        for table in ("trajectory.csv", "steps.csv"):
            assert (a / "agents" / name / table).read_bytes() == \
                (b / "agents" / name / table).read_bytes()
        ev_a = json.loads((a / "agents" / name / "report.json").read_text())["evaluation"]
        ev_b = json.loads((b / "agents" / name / "report.json").read_text())["evaluation"]
        assert ev_b["position"]["mean"] > ev_a["position"]["mean"] + 40.0
    assert (a / "nodes.csv").read_bytes() == (b / "nodes.csv").read_bytes()


def test_existing_results_are_refused(saved: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "nodes.csv").write_text("x\n")
    res = runner.invoke(app, ["mission", "track", str(saved), "-o", str(out)])
    assert res.exit_code == 2
    assert "already holds results (nodes.csv)" in " ".join(res.output.split())


# --------------------------------------------------------------------------------------------
# bad mission folders (tiny sessions: they fail before any tracking)
# --------------------------------------------------------------------------------------------
def _tiny_session() -> Session:
    t = np.arange(300) * 0.01
    imu = ImuStream(SensorSeries(t, np.tile([0.0, 0.0, 9.81], (300, 1)), "acc"))
    ranges = RangeMeasurements(np.array([1.0, 2.0]), np.array(["N1", "N9"]),
                               np.array([3.0, 3.1]), np.array([0.1, 0.1]))
    return Session(imu=imu, ranges=ranges)


def _tiny(tmp_path: Path, nodes: tuple[str, ...] = ("N1",)) -> Path:
    s = _tiny_session()
    return write_mission(tmp_path / "m", agents=[("A", "rescuer", s), ("B", "rescuer", s)],
                         nodes=nodes, name="tiny")


def _edit(path: Path, change) -> None:  # type: ignore[no-untyped-def]
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def _fails(mission: Path, tmp_path: Path) -> str:
    res = runner.invoke(app, ["mission", "track", str(mission), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2, res.output
    assert not (tmp_path / "o").exists()
    return " ".join(res.output.split())


def test_missing_agent_folder_names_the_entry(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    shutil.rmtree(m / "agents" / "B")
    text = _fails(m, tmp_path)
    assert "mission.json agents[1].session" in text and "agent 'B'" in text


def test_agent_folder_without_a_session_names_the_entry(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    shutil.rmtree(m / "agents" / "A")
    (m / "agents" / "A").mkdir()
    (m / "agents" / "A" / "notes.txt").write_text("not a recording\n")
    text = _fails(m, tmp_path)
    assert "mission.json agents[0].session" in text and "is not a session" in text


def test_writer_refuses_bad_agents(tmp_path: Path) -> None:
    from hrtls.errors import InputError

    with pytest.raises(InputError, match=r"mission\.json agents"):
        write_mission(tmp_path / "w", agents=[("a/b", "rescuer", _tiny_session())])
    with pytest.raises(InputError, match=r"mission\.json agents"):
        write_mission(tmp_path / "w", agents=[])
    with pytest.raises(InputError, match="duplicate agent name 'a'"):
        write_mission(tmp_path / "w", agents=[("a", "rescuer", _tiny_session())] * 2)
    assert not (tmp_path / "w").exists()


def test_a_bad_session_file_names_the_agent_folder(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    imu = m / "agents" / "B" / "imu.csv"
    lines = imu.read_text().splitlines()
    lines[5] = "0.0,0,0,9.81"
    imu.write_text("\n".join(lines) + "\n")
    text = _fails(m, tmp_path)
    assert "agents/B/imu.csv" in text and "time goes backwards" in text and "--repair" in text
    res = runner.invoke(app, ["mission", "track", str(m), "-o", str(tmp_path / "o"), "--repair"])
    assert res.exit_code == 0, res.output
    assert "repaired" in res.output


def test_unknown_agent_kind_names_the_field(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    _edit(m / "mission.json", lambda d: d["agents"][0].update(kind="drone"))
    text = _fails(m, tmp_path)
    assert "mission.json" in text and "'agents.0.kind'" in text and "rescuer" in text


def test_a_robot_without_odometry_is_refused(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    _edit(m / "mission.json", lambda d: d["agents"][1].update(kind="robot"))
    text = _fails(m, tmp_path)
    assert "agents[1]" in text and "robot" in text and "fixes.csv" in text


@pytest.mark.parametrize(("file", "change", "needle"), [
    ("mission.json", lambda d: d.pop("version"), "'version'"),
    ("mission.json", lambda d: d.update(version=2), "field 'version': 2"),
    ("mission.json", lambda d: d.update(agents=[]), "'agents'"),
    ("mission.json", lambda d: d["agents"][0].update(session="../elsewhere"), "'agents.0.session'"),
    ("mission.json", lambda d: d["agents"][1].update(name="A"), "duplicate agent name 'A'"),
    ("mission.json", lambda d: d["agents"][1].update(name="../up"), "'agents.1.name'"),
    ("mission.json", lambda d: d["agents"][0].update(sesion="x"), "'agents.0.sesion'"),
    ("network.json", lambda d: d["nodes"][0].update(position=[1, 2, 0]), "'nodes.0.position'"),
])
def test_malformed_mission_files_name_file_and_field(tmp_path: Path, file: str, change,
                                                     needle: str) -> None:  # type: ignore[no-untyped-def]
    m = _tiny(tmp_path)
    _edit(m / file, change)
    text = _fails(m, tmp_path)
    assert file in text and needle in text


def test_invalid_json_names_line_and_column(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    (m / "mission.json").write_text('{"format": "hrtls-mission",\n "version": 1,,}')
    text = _fails(m, tmp_path)
    assert "mission.json line 2 column" in text


def test_bad_chunk_is_refused(saved: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["mission", "track", str(saved), "-o", str(tmp_path / "o"),
                              "--chunk-s", "0"])
    assert res.exit_code == 2 and "--chunk-s" in res.output


def test_no_mission_file(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    assert "no mission.json" in _fails(tmp_path / "empty", tmp_path)


def test_ranges_to_unlisted_nodes_warn_with_the_agent_folder(tmp_path: Path) -> None:
    m = _tiny(tmp_path)
    with pytest.warns(DegradedInputWarning) as caught:
        folder = read_mission(m)
    texts = sorted(str(w.message) for w in caught)
    assert len(texts) == 2, texts
    for name, text in zip("AB", texts, strict=True):
        assert f"agents/{name} ranges: 1 id(s)" in text and "(N9)" in text
    assert folder.nodes == ("N1",)


def test_bad_smoother_is_refused(saved: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["mission", "track", str(saved), "-o", str(tmp_path / "o"),
                              "--smoother", "fast"])
    assert res.exit_code == 2
    assert "--smoother" in res.output and "off or nodes or feedback" in res.output
    assert not (tmp_path / "o").exists()


def test_unknown_simulate_option_is_refused(tmp_path: Path) -> None:
    res = runner.invoke(app, ["simulate", "inderst_hybrid_mission", "-o", str(tmp_path / "m"),
                              "-O", "n_drones=1"])
    assert res.exit_code == 2
    assert "unknown option 'n_drones'" in " ".join(res.output.split())


# --------------------------------------------------------------------------------------------
# landmark updates during the mission (landmark_updates.json)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("content", "needle"), [
    ({"id": "T1"}, "list of location messages"),
    ([{"id": "T1", "position": [0, 0, 0]}], "item 0: no field 'updated'"),
    ([{"id": "T1", "position": [0, 0, 0], "updated": 5, "status": "gone"}], "'status'"),
    ([{"id": "N1", "position": [0, 0, 0], "updated": 5}], "id 'N1' is a dropped node"),
])
def test_bad_landmark_updates_name_the_item(tmp_path: Path, content: object,
                                            needle: str) -> None:
    m = _tiny(tmp_path)
    (m / "landmark_updates.json").write_text(json.dumps(content))
    text = _fails(m, tmp_path)
    assert "landmark_updates.json" in text and needle in text


def test_a_tag_destroyed_mid_mission_stops_correcting(tmp_path: Path) -> None:
    from hrtls.sim.scenarios import run_scenario

    ring = run_scenario("inderst_ring", 3, distance_m=150.0).session
    assert ring.tags is not None
    late = (ring.tags.tag == "T5") & (ring.tags.t > 100.0)
    assert late.any() and ((ring.tags.tag == "T5") & (ring.tags.t < 100.0)).any()
    m = write_mission(tmp_path / "m", agents=[("A", "rescuer", ring)], name="ring")
    gone = ring.landmarks["T5"].model_copy(update={"updated": 100.0, "status": "destroyed"})
    (m / "landmark_updates.json").write_text(json.dumps([gone.model_dump(mode="json")]))
    assert read_mission(m).landmark_updates == (gone,)
    _track(m, tmp_path / "out")
    report = json.loads((tmp_path / "out" / "agents" / "A" / "report.json").read_text())
    assert any("landmark 'T5' destroyed at 100.00 s: its readings no longer correct" in str(n)
               for n in report["notes"]), report["notes"]
