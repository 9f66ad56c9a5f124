"""Causality: the tracker's output up to time t does not change when data after t are added.

For every preset, the office session is tracked whole and cut at random times; rows older
than the cut by more than the release latency of the gait stage (``LATENCY_S``: a step is
reported a few seconds after it ends, tag reads and RSS windows wait for their windows to
close) must be identical, bit for bit. A whole-recording estimate anywhere (hard iron,
mounting, channel, step scale) would change rows long before the cut.
"""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.pipeline import PRESETS, Tracker, preset
from hrtls.pipeline.chunks import session_window
from hrtls.pipeline.tracker import LIVE_LATENCY_S
from hrtls.sim.scenarios import SimulationResult

LATENCY_S = 2.0 * LIVE_LATENCY_S
"""Rows this much older than the cut are final (steps released late, windows closing)."""


@pytest.mark.parametrize("name", PRESETS)
def test_prefix_does_not_depend_on_later_data(office: SimulationResult, name: str) -> None:
    s = office.session
    t0, t1 = s.time_span()
    cfg = preset(name)
    whole = Tracker(cfg).run(s).trajectory
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    earliest = t0 + cfg.attitude.mounting_window_s + 2.0 * LATENCY_S
    for t_cut in rng.uniform(earliest, t1 - 5.0, size=2):
        part = session_window(s, t0, float(t_cut))
        assert part is not None
        cut = Tracker(cfg).run(part).trajectory
        n = int(np.searchsorted(whole.t, t_cut - LATENCY_S, side="right"))
        assert n > 10
        assert len(cut) >= n
        np.testing.assert_array_equal(cut.t[:n], whole.t[:n])
        np.testing.assert_array_equal(cut.xyz[:n], whole.xyz[:n])
        np.testing.assert_array_equal(cut.heading_rad[:n], whole.heading_rad[:n])
        np.testing.assert_array_equal(cut.cov_xy[:n], whole.cov_xy[:n])


def test_two_pass_uses_the_future(office: SimulationResult) -> None:
    """The offline option refits on the whole recording: early rows change with a cut."""
    s = office.session
    t0, _ = s.time_span()
    cfg = preset("default")
    cfg = cfg.model_copy(update={"offline": cfg.offline.model_copy(update={"two_pass": True})})
    whole = Tracker(cfg).run(s).trajectory
    part = session_window(s, t0, t0 + 60.0)
    assert part is not None
    cut = Tracker(cfg).run(part).trajectory
    n = int(np.searchsorted(whole.t, t0 + 60.0 - LATENCY_S, side="right"))
    assert np.any(cut.xyz[:n] != whole.xyz[:n])
