"""CLI (activity train, calibrate steps) and the real recordings in ../shared/data."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli import gait as gait_cli
from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta
from hrtls.errors import FormatError
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.session_analysis import analyze_session, session_inputs
from hrtls.gait.synthetic import SimPerson, simulate


def sim_session(seed: int, segments: list[tuple[int, float]]) -> tuple[Session, object]:
    w = simulate(segments, person=SimPerson(), seed=seed)
    imu = ImuStream(SensorSeries(w.t, w.acc_d, name="accelerometer"))
    meta = SessionMeta(mounting_q_bd=tuple(float(v) for v in w.q_bd))
    return Session(meta=meta, imu=imu), w


def test_read_activity_labels(tmp_path: Path) -> None:
    p = tmp_path / "activity.csv"
    p.write_text("t_start,t_end,activity\n0,5,standing\n5,9.5,walking\n")
    a, _b, c = gait_cli.read_activity_labels(p)
    np.testing.assert_allclose(a, [0, 5])
    np.testing.assert_array_equal(c, [0, 1])
    p.write_text("t_start,t_end,activity\n5,4,walking\n")
    with pytest.raises(FormatError, match="line 2"):
        gait_cli.read_activity_labels(p)
    p.write_text("start,end\n")
    with pytest.raises(FormatError, match="line 1"):
        gait_cli.read_activity_labels(p)


def test_cli_train_and_calibrate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sessions = {}
    for i in range(2):
        s, w = sim_session(i, [(0, 10), (1, 20), (2, 10), (0, 6)])
        d = tmp_path / f"s{i}"
        d.mkdir()
        (d / "activity.csv").write_text(
            "t_start,t_end,activity\n0,10,standing\n10,30,walking\n30,40,running\n"
            "40,46,standing\n")
        sessions[str(d)] = s
    monkeypatch.setattr(gait_cli, "_read_session", lambda p: sessions[str(p)])
    runner = CliRunner()
    out = tmp_path / "model.json"
    r = runner.invoke(gait_cli.app, ["activity", "train", *sessions, "-o", str(out)])
    assert r.exit_code == 0, r.output
    model = LdaModel.load(out)
    assert set(model.classes.tolist()) == {0, 1, 2}
    # calibration walks of known length
    walks = {}
    dists = []
    for i in range(2):
        s, w = sim_session(10 + i, [(0, 3), (1, 25), (0, 3)])
        walks[f"w{i}"] = s
        dists.append(float(np.sum(w.step_length_m)))
    monkeypatch.setattr(gait_cli, "_read_session", lambda p: walks[str(p)])
    prof = tmp_path / "profile.json"
    args = ["calibrate-steps", "w0", "w1", "--distance", str(dists[0]), "--distance",
            str(dists[1]), "-o", str(prof)]
    r = runner.invoke(gait_cli.app, args)
    assert r.exit_code == 0, r.output
    step_model = json.loads(prof.read_text())["step_model"]
    assert step_model["kind"] == "weinberg" and 0.2 < step_model["k"] < 0.8
    r = runner.invoke(gait_cli.app, [*args, "--model", "frequency"])
    assert r.exit_code == 0, r.output
    assert json.loads(prof.read_text())["step_model"]["kind"] == "frequency"
    r = runner.invoke(gait_cli.app, [*args, "--model", "pendulum", "--leg-length", "0.9"])
    assert r.exit_code == 0, r.output
    pend = json.loads(prof.read_text())["step_model"]
    assert pend["kind"] == "pendulum" and pend["leg_length_m"] == 0.9 and 0.3 < pend["k"] < 3
    r = runner.invoke(gait_cli.app, ["calibrate-steps", "w0", "--distance", "1", "--distance",
                                     "2", "-o", str(prof)])
    assert r.exit_code != 0


def test_analyze_session_uses_profile() -> None:
    s, _w = sim_session(3, [(0, 3), (1, 20), (0, 3)])
    meta = s.meta.model_copy(update={"user": s.meta.user.model_copy(
        update={"step_model": {"kind": "weinberg", "k": 0.3}})})
    s2 = Session(meta=meta, imu=s.imu)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = analyze_session(s)
        b = analyze_session(s2)
    assert len(a.steps) == len(b.steps) > 20
    assert b.steps.distance_m < a.steps.distance_m
    _t, _acc, q, mount, rate = session_inputs(s)
    assert rate == pytest.approx(100.0) and q is None and mount is not None


@pytest.mark.realdata
def test_mobgap_straight_walks_step_events(shared_data: Path) -> None:
    from hrtls.datasets import mobgap

    root = shared_data / "mobgap_lab"
    for participant in ("HA/001", "MS/001"):
        trial = mobgap.load_trial(root, participant, "Test5", "Trial1")
        t, acc, _, mount, rate = session_inputs(trial.session)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = GaitAnalyzer(rate_hz=rate, mounting_q_bd=mount).process(t, acc)
        ref = trial.reference.indip
        ic = ref.initial_contacts_s[np.isfinite(ref.initial_contacts_s)]
        te = res.steps.t_end
        inside = te[(te > ref.bout_start_s[0] - 0.3) & (te < ref.bout_end_s[-1] + 0.3)]
        assert abs(len(inside) - len(ic)) <= 1
        matched = sum(np.any(np.abs(inside - r) <= 0.2) for r in ic)
        assert matched >= len(ic) - 1


@pytest.mark.realdata
def test_oxford_pocket_counts(shared_data: Path) -> None:
    from hrtls.datasets import oxford

    for path in oxford.list_recordings(shared_data / "oxford_step"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec = oxford.load_recording(path, repair=True)
        if rec.placement not in ("frontpocket", "backpocket"):
            continue
        t, acc, _, _, _ = session_inputs(rec.session)
        tu = np.arange(t[0], t[-1], 0.01)
        au = np.column_stack([np.interp(tu, t, acc[:, k]) for k in range(3)])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = GaitAnalyzer(rate_hz=100.0).process(tu, au)
        assert abs(len(res.steps) - rec.total_steps) <= 0.015 * rec.total_steps
