"""Random sequences of predictions and corrections keep the filter sane."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data.landmarks import Landmark
from hrtls.fusion.fixes import FixCorrector, FixParams, FixSchedule
from hrtls.fusion.floors import floor_level_update
from hrtls.fusion.gating import is_spd
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.ranges import range_update
from hrtls.fusion.rss import rss_update
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import TagCorrector, TagParams, bearing_heading_correction
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor

OPS = ["step", "step_state", "velocity", "fix", "range", "rss", "tag", "tag_kalman",
       "bearing", "bearing_kalman", "floor"]


@settings(max_examples=80, deadline=None)
@given(st.lists(st.sampled_from(OPS), min_size=1, max_size=30), st.integers(0, 100_000))
def test_random_sequences_keep_covariance_spd(ops: list[str], seed: int) -> None:
    rng = np.random.default_rng(seed)
    s = FilterState.initial(xyz=tuple(rng.uniform(-10, 10, 3)), heading_rad=rng.uniform(-4, 4),
                            sigma_xy_m=rng.uniform(0.01, 5.0))
    model = PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=5.0)
    for op in ops:
        t = s.t + float(rng.uniform(0.0, 1.0))
        anchor = np.array([*rng.uniform(-20, 20, 2), 0.0])
        if op == "step":
            s = StepPredictor().predict(s, t=t, length_m=rng.uniform(0, 1.5),
                                        heading_rad=rng.uniform(-10, 10), dz_m=rng.normal(),
                                        activity=int(rng.integers(-1, 5)))
        elif op == "step_state":
            s = StepPredictor(StepPredictionParams(heading_mode="state")).predict(
                s, t=t, length_m=rng.uniform(0, 1.5), heading_rad=rng.uniform(-10, 10),
                activity=int(rng.integers(-1, 5)))
        elif op == "velocity":
            n = int(rng.integers(1, 50))
            tt = s.t + np.cumsum(rng.uniform(0.001, 0.05, n))
            mode = "state" if rng.random() < 0.5 else "input"
            s = VelocityPredictor(VelocityPredictionParams(heading_mode=mode)).run(  # type: ignore[arg-type]
                s, tt, rng.uniform(0, 3, n), rng.uniform(-7, 7, n)).state
        elif op == "fix":
            s = FixCorrector(FixParams(period_s=None)).update(
                s, FixSchedule(), t=t, xyz=rng.uniform(-15, 15, 3),
                sigma_m=rng.uniform(0.01, 3)).state
        elif op == "range":
            s = range_update(s, anchor, rng.uniform(0, 30), rng.uniform(0.05, 3)).state
        elif op == "rss":
            s = rss_update(s, anchor, rng.uniform(-100, -40), model).state
        elif op in ("tag", "tag_kalman"):
            k = int(rng.integers(1, 4))
            tags = [Landmark(id=f"t{i}", position=(*rng.uniform(-15, 15, 2), 2.0),
                             lobe_orientation_rad=float(rng.uniform(-4, 4)),
                             accuracy_m=float(rng.uniform(0.5, 3))) for i in range(k)]
            strat = "kalman" if op == "tag_kalman" else "paper"
            s = TagCorrector(TagParams(strategy=strat)).update(s, t=t, tags=tags).state  # type: ignore[arg-type]
        elif op in ("bearing", "bearing_kalman"):
            mode_b = "kalman" if op == "bearing_kalman" else "replace"
            s = bearing_heading_correction(s, rng.uniform(-4, 4, int(rng.integers(1, 4))),
                                           mode=mode_b).state  # type: ignore[arg-type]
        elif op == "floor":
            s = floor_level_update(s, 3.0)[0]
        assert is_spd(s.P + 1e-12 * np.eye(4)), op
        assert np.all(np.isfinite(s.x)), op
        assert -np.pi < s.heading <= np.pi, op
        assert np.min(np.linalg.eigvalsh(s.P)) > -1e-9 * max(1.0, float(np.max(s.P))), op
