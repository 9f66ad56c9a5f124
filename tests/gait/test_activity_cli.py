"""``hrtls activity train`` options and ``hrtls activity calibrate-tree``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli import gait as gait_cli
from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds, classify_tree
from hrtls.gait.synthetic import SimPerson, simulate

SEGMENTS = [(0, 10), (1, 20), (3, 16), (4, 16), (2, 10), (0, 6)]
LABELS = ("t_start,t_end,activity\n0,10,standing\n10,30,walking\n30,46,upstairs\n"
          "46,62,downstairs\n62,72,running\n72,78,standing\n")


@pytest.fixture()
def sessions(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    out = {}
    for i in range(2):
        w = simulate(SEGMENTS, person=SimPerson(), seed=i)
        imu = ImuStream(SensorSeries(w.t, w.acc_d, name="accelerometer"))
        meta = SessionMeta(mounting_q_bd=tuple(float(v) for v in w.q_bd))
        d = tmp_path / f"s{i}"
        d.mkdir()
        (d / "activity.csv").write_text(LABELS)
        out[str(d)] = Session(meta=meta, imu=imu)
    monkeypatch.setattr(gait_cli, "_read_session", lambda p: out[str(p)])
    return list(out)


def test_train_per_class_and_pooled(sessions: list[str], tmp_path: Path) -> None:
    runner = CliRunner()
    for cov, ndim in (("per_class", 3), ("pooled", 2)):
        out = tmp_path / f"{cov}.json"
        r = runner.invoke(gait_cli.app, ["activity", "train", *sessions, "-o", str(out),
                                         "--covariance", cov])
        assert r.exit_code == 0, r.output
        model = LdaModel.load(out)
        assert model.covariance.ndim == ndim
        assert set(model.classes.tolist()) == {0, 1, 2, 3, 4}
    r = runner.invoke(gait_cli.app, ["activity", "train", *sessions, "-o",
                                     str(tmp_path / "x.json"), "--covariance", "diagonal"])
    assert r.exit_code != 0


def test_calibrate_tree_writes_thresholds(sessions: list[str], tmp_path: Path) -> None:
    out = tmp_path / "tree.json"
    r = CliRunner().invoke(gait_cli.app, ["activity", "calibrate-tree", *sessions, "-o",
                                          str(out)])
    assert r.exit_code == 0, r.output
    data = json.loads(out.read_text())
    assert data["format"] == "hrtls-activity-tree"
    th = TreeThresholds.from_dict(data["thresholds"])
    # the calibrated tree separates the person's own labelled windows well (in-sample)
    tree, _, y = gait_cli.labelled_windows([Path(s) for s in sessions], window_s=2.0,
                                           cutoff_hz=6.0)
    ok = y >= 0
    acc = np.mean(classify_tree(tree[ok], th) == y[ok])
    assert acc == pytest.approx(data["in_sample_accuracy"])
    assert acc > 0.7
