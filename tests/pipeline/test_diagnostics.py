"""The diagnostics log: lazy rows equal the Python records; counts and rejections."""

from __future__ import annotations

import numpy as np

from hrtls.fusion.gating import skipped, summarize
from hrtls.pipeline.chunks import session_window, split_session
from hrtls.pipeline.diagnostics import DiagnosticsBlock, DiagnosticsLog
from hrtls.sim.scenarios import SimulationResult


def test_log_counts_and_rows() -> None:
    log = DiagnosticsLog()
    log.append(skipped("fix", 0.5, "user not moving"))
    log.add_block(DiagnosticsBlock(
        ["rss", "rss", "range", "range"], np.array([1.0, 2.0, 3.0, 4.0]),
        np.array([0, 1, 2, 4]), np.array([0.5, 20.0, np.nan, np.nan]),
        np.array([1.0, 2.0, np.nan, np.nan]), np.array([0.1, 3.0, np.nan, np.nan]),
        ["A1", "A2", "N1", "N9"], ["", "", "", "node without a known position"], 10.8))
    assert len(log) == 5
    rows = list(log)
    assert [d.status for d in rows] == ["skipped", "accepted", "rejected", "rejected",
                                        "skipped"]
    assert rows[2].reason == "failed the chi-square gate" and rows[2].nis == 20.0
    assert rows[3].reason == "estimate on top of the node"
    assert log.counts() == summarize(rows)
    rej = log.first_rejected(1)
    assert len(rej) == 1 and rej[0].source == "A2"
    assert log[1].source == "A1" and log[-1].source == "N9"


def test_windows_cover_the_session(office: SimulationResult) -> None:
    s = office.session
    parts = list(split_session(s, 7.0))
    assert s.rss is not None and s.imu is not None
    assert sum(len(p.rss) for p in parts if p.rss is not None) == len(s.rss)
    assert sum(len(p.imu.accel) for p in parts if p.imu is not None) == len(s.imu.accel)
    _, t1 = s.time_span()
    assert session_window(s, t1 + 10.0, t1 + 20.0) is None
