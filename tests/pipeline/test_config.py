"""Tracker configuration: presets, TOML files and errors that name the key."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from hrtls.errors import FormatError, InputError
from hrtls.pipeline import PRESETS, TrackerConfig, load_config, preset

if TYPE_CHECKING:
    from hrtls.sim.scenarios import SimulationResult


@pytest.mark.parametrize("name", PRESETS)
def test_presets_load(name: str) -> None:
    cfg = preset(name)
    assert isinstance(cfg, TrackerConfig)
    assert cfg.name == name


def test_unknown_preset() -> None:
    with pytest.raises(InputError, match="unknown preset"):
        preset("nope")


def test_toml_roundtrip(tmp_path: Path) -> None:
    p = tmp_path / "c.toml"
    p.write_text('name = "mine"\n[fixes]\nperiod_s = 16.0\n[rss]\nmode = "kalman"\n')
    cfg = load_config(p)
    assert cfg.name == "mine" and cfg.fixes.period_s == 16.0 and cfg.rss.mode == "kalman"
    assert cfg.tags == TrackerConfig().tags


@pytest.mark.parametrize(("text", "key"), [
    ("[fixes]\nperiod_z = 1.0\n", "fixes.period_z"),
    ("[rss]\nmode = \"loud\"\n", "rss.mode"),
    ("[fixes]\nperiod_s = -1.0\n", "fixes.period_s"),
    ("gate_probability = 2.0\n", "gate_probability"),
    ("[bogus]\nx = 1\n", "bogus"),
])
def test_bad_key_is_named(tmp_path: Path, text: str, key: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(FormatError) as err:
        load_config(p)
    assert key in str(err.value)
    assert str(p) in str(err.value)


def test_bad_toml_syntax(tmp_path: Path) -> None:
    p = tmp_path / "broken.toml"
    p.write_text("[fixes\nperiod_s = 1\n")
    with pytest.raises(FormatError, match=r"broken\.toml"):
        load_config(p)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        load_config(tmp_path / "absent.toml")


@pytest.mark.parametrize("kind", ["weinberg", "frequency", "pendulum"])
def test_step_length_kinds(tmp_path: Path, kind: str) -> None:
    p = tmp_path / "c.toml"
    p.write_text(f'[gait]\nstep_length = "{kind}"\n')
    assert load_config(p).gait.step_length == kind


def test_pendulum_step_model_from_profile(office: SimulationResult) -> None:
    from hrtls.gait.step_length_pendulum import PendulumModel
    from hrtls.pipeline import Tracker
    from hrtls.pipeline.build import step_model

    s = office.session
    cfg = preset("default").model_copy(update={
        "gait": preset("default").gait.model_copy(update={"step_length": "pendulum"})})
    meta = s.meta.model_copy(update={"user": s.meta.user.model_copy(update={
        "step_model": {"kind": "pendulum", "k": 1.1, "leg_length_m": 0.9}})})
    model, _ = step_model(cfg.gait, meta)
    assert isinstance(model, PendulumModel) and model.k == 1.1 and model.leg_length_m == 0.9
    plain = s.meta.model_copy(update={"user": s.meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.5}})})
    assert step_model(cfg.gait, plain)[0] == PendulumModel()
    res = Tracker(cfg).run(s.with_parts(meta=meta, fixes=None, rss=None, tags=None,
                                        ranges=None))
    assert len(res.steps) > 50 and np.all(np.isfinite(res.steps.length_m))
    assert 0.3 < float(np.median(res.steps.length_m[res.steps.length_m > 0])) < 1.2


def test_fix_keys_of_the_colombo_targets(tmp_path: Path) -> None:
    d = preset("default").fixes
    assert d.partial_step and d.yaw_feedback == "kalman" and d.drift_fraction > 0 and d.gate
    c = preset("colombo2014").fixes
    assert not c.gate and c.yaw_feedback == "gain" and not c.partial_step
    f = tmp_path / "p.toml"
    f.write_text('[fixes]\ngate = false\ndrift_fraction = 0.2\nyaw_feedback = "kalman"\n')
    cfg = load_config(f)
    assert (cfg.fixes.gate, cfg.fixes.drift_fraction, cfg.fixes.yaw_feedback) == \
        (False, 0.2, "kalman")
    f.write_text('[fixes]\nyaw_feedback = "always"\n')
    with pytest.raises(InputError):
        load_config(f)


def test_walking_bout_keys_reach_the_gait_stage(office: SimulationResult) -> None:
    from hrtls.pipeline import Tracker

    s = office.session.with_parts(fixes=None, rss=None, tags=None, ranges=None)
    base = preset("default")
    cfg = base.model_copy(update={"gait": base.gait.model_copy(
        update={"walking_bouts": True, "fill_missed_steps": True})})
    plain = Tracker(base).run(s)
    tr = Tracker(cfg)
    bouts = tr.run(s)
    assert tr.gait is not None and tr.gait.bouts is not None and tr.gait.filler is not None
    true_steps = len(office.true_steps)
    # both keep the steps of a continuous office walk (bouts drop only isolated steps)
    assert abs(len(bouts.steps) - true_steps) <= 0.03 * true_steps
    assert abs(len(bouts.steps) - len(plain.steps)) <= 0.03 * len(plain.steps)


# ---------------------------------------------------------------- hrtls config show
@pytest.mark.parametrize("name", PRESETS)
def test_config_show_round_trips(tmp_path: Path, name: str) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app
    from hrtls.pipeline.config import load_config

    out = CliRunner().invoke(app, ["config", "show", "--preset", name])
    assert out.exit_code == 0, out.output
    path = tmp_path / "cfg.toml"
    path.write_text(out.output, encoding="utf-8")
    assert load_config(path) == preset(name)
    again = CliRunner().invoke(app, ["config", "show", "--config", str(path)])
    assert again.output == out.output


def test_config_show_unknown_key_names_it(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    path = tmp_path / "bad.toml"
    path.write_text("[attitude]\nmounting_windw_s = 3.0\n", encoding="utf-8")
    out = CliRunner().invoke(app, ["config", "show", "--config", str(path)])
    assert out.exit_code != 0
    assert "mounting_windw_s" in out.output


def test_default_tracker_is_the_default_preset() -> None:
    from hrtls.pipeline import Tracker

    assert Tracker().config == preset("default")


def test_tracker_config_defaults_are_the_default_preset() -> None:
    from hrtls.pipeline import Tracker, TrackerConfig

    assert TrackerConfig() == preset("default")
    assert Tracker().config == Tracker(TrackerConfig()).config == preset("default")


def test_every_component_knob_reaches_its_component(tmp_path: Path,
                                                    office: SimulationResult) -> None:
    """Sub-tables map 1:1 onto the components' parameter dataclasses (and the constants)."""
    from hrtls.pipeline import Tracker

    p = tmp_path / "knobs.toml"
    p.write_text(
        "floor_sigma_m = 0.3\n"
        "[attitude]\nmethod = \"quat-ekf\"\n"
        "[attitude.quat_ekf]\nacc_gate_m_s2 = 0.7\ngyro_bias_rad_s = [0.001, 0.0, 0.0]\n"
        "[prediction.step_scale]\ngain = 0.5\nmin_scale = 0.9\nmax_scale = 1.1\n"
        "min_baseline_m = 5.0\n"
        "[prediction.random_walk]\nsigma_speed_m_per_sqrt_s = 2.0\n"
        "[rss]\nmin_distance_m = 1.5\n"
        "[rss.channel]\nforgetting = 0.99\neta_bounds = [1.5, 5.0]\n", encoding="utf-8")
    cfg = load_config(p)
    s = office.session
    tr = Tracker(cfg)
    tr.start_session(s)
    assert tr.attitude is not None
    att = tr.attitude.filter.params
    assert att.acc_gate_m_s2 == 0.7 and tuple(att.gyro_bias_rad_s) == (0.001, 0.0, 0.0)
    sc = tr.engine.scale.params
    assert (sc.gain, sc.min_scale, sc.max_scale, sc.min_baseline_m) == (0.5, 0.9, 1.1, 5.0)
    parts = tr.engine.parts
    assert parts.random_walk.sigma_speed_m_per_sqrt_s == 2.0
    assert parts.channel_estimator is not None
    assert parts.channel_estimator.params.forgetting == 0.99
    assert tuple(parts.channel_estimator.params.eta_bounds) == (1.5, 5.0)
    rec = tr.engine.params[0]
    assert rec["floor_sigma_m"] == 0.3 and rec["rss_min_distance_m"] == 1.5
    # the defaults are the dataclasses' own
    from hrtls.attitude.quat_ekf import QuatEkfParams
    from hrtls.pipeline.step_scale import StepScaleParams

    d = preset("default")
    assert d.attitude.filter_params("quat-ekf") == QuatEkfParams()
    assert d.prediction.step_scale == {"min_baseline_m": 8.0, "gain": 0.25, "min_scale": 0.8,
                                       "max_scale": 1.25}
    assert StepScaleParams() == StepScaleParams(**d.prediction.step_scale)


@pytest.mark.parametrize(("text", "key"), [
    ("[rss.channel]\nforgeting = 0.9\n", "forgeting"),
    ("[attitude.quat_ekf]\nacc_gate = 1.0\n", "acc_gate"),
    ("[prediction.step_scale]\ngain = \"high\"\n", "gain"),
    ("[rss.channel]\nforgetting = 1.5\n", "forgetting"),
])
def test_bad_sub_table_key_is_named(tmp_path: Path, text: str, key: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(FormatError, match=key):
        load_config(p)


@pytest.mark.parametrize("table", ["random_walk", "grid"])
def test_renamed_diffusion_key_old_name_warns_new_name_reads(tmp_path: Path, table: str) -> None:
    new = tmp_path / "new.toml"
    new.write_text(f"[prediction.{table}]\nsigma_speed_m_per_sqrt_s = 2.5\n", encoding="utf-8")
    old = tmp_path / "old.toml"
    old.write_text(f"[prediction.{table}]\nsigma_speed_m_s = 2.5\n", encoding="utf-8")
    cfg_new = load_config(new)
    with pytest.warns(FutureWarning, match="sigma_speed_m_per_sqrt_s"):
        cfg_old = load_config(old)
    for cfg in (cfg_new, cfg_old):
        assert getattr(cfg.prediction, table)["sigma_speed_m_per_sqrt_s"] == 2.5
        assert "sigma_speed_m_s" not in getattr(cfg.prediction, table)
    both = tmp_path / "both.toml"
    both.write_text(f"[prediction.{table}]\nsigma_speed_m_s = 1.0\n"
                    "sigma_speed_m_per_sqrt_s = 2.0\n", encoding="utf-8")
    with pytest.raises(FormatError, match="sigma_speed_m_s"):
        load_config(both)


def test_a_relative_survey_path_is_read_from_the_config_files_folder(tmp_path: Path) -> None:
    (tmp_path / "site").mkdir()
    p = tmp_path / "site" / "cfg.toml"
    p.write_text('[prediction.radio_map]\nsurvey = "walk.csv"\n', encoding="utf-8")
    assert load_config(p).prediction.radio_map["survey"] == str(tmp_path / "site" / "walk.csv")
    p.write_text(f'[prediction.radio_map]\nsurvey = "{tmp_path / "a.csv"}"\n', encoding="utf-8")
    assert load_config(p).prediction.radio_map["survey"] == str(tmp_path / "a.csv")
