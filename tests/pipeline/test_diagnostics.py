"""The diagnostics log: lazy rows equal the Python records; counts and rejections."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.fusion.gating import rejected, skipped, summarize
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


def test_block_with_two_dimensional_and_reason_rows() -> None:
    """Scan rows: dof 2 updates, a WLS jump (accepted with reason) and collinear anchors."""
    from hrtls.pipeline.diagnostics import ACCEPTED, ACCEPTED_REASON, GATE, REJECTED_REASON

    nan = np.nan
    block = DiagnosticsBlock(
        np.array(["rss", "rss", "rss", "range", "rss"], dtype=object),
        np.array([1.0, 2.0, 3.0, 4.0, 5.0]),
        np.array([ACCEPTED, ACCEPTED_REASON, REJECTED_REASON, GATE, GATE]),
        np.array([1.5, nan, nan, 30.0, 40.0]), np.array([nan, nan, nan, 2.0, nan]),
        np.array([nan, nan, nan, 7.0, nan]), np.array(["a,b,c", "a,b,c", "a,b", "N1", "a,b,c"]),
        ["", "WLS position (RSS alone)", "anchors are collinear", "", ""], 10.8,
        dof=np.array([2, 2, 2, 1, 2]), nu2=np.array([[0.5, -0.5]] * 5),
        s2=np.array([[2.0, 0.1, 3.0]] * 5), threshold2=13.8)
    log = DiagnosticsLog()
    log.add_block(block)
    rows = list(log)
    assert [d.status for d in rows] == ["accepted", "accepted", "rejected", "rejected",
                                        "rejected"]
    assert rows[0].dof == 2 and rows[0].threshold == 13.8
    np.testing.assert_array_equal(rows[0].innovation_cov, [[2.0, 0.1], [0.1, 3.0]])
    assert rows[1].reason == "WLS position (RSS alone)" and rows[1].dof == 2
    assert rows[2].reason == "anchors are collinear" and rows[2].dof == 0
    assert rows[3].dof == 1 and rows[3].threshold == 10.8 and rows[3].nis == 30.0
    assert all(isinstance(d.source, str) and isinstance(d.kind, str) for d in rows)
    assert log.counts() == summarize(rows)
    assert [d.t for d in log.first_rejected(2)] == [3.0, 4.0]
    assert [d.t for d in log.first_rejected(10)] == [3.0, 4.0, 5.0]
    assert block.status_names() == [d.status for d in rows]


def test_first_rejected_across_blocks_and_records() -> None:
    log = DiagnosticsLog()
    for k in range(4):
        log.append(skipped("fix", float(k), "user not moving"))
        log.add_block(DiagnosticsBlock(
            ["rss"] * 3, np.array([k + 0.1, k + 0.2, k + 0.3]), np.array([0, 1 if k % 2 else 0, 4]),
            np.array([0.1, 20.0, np.nan]), np.array([1.0] * 3), np.array([0.1] * 3),
            ["A", "B", "C"], ["", "", "anchor without a known position"], 10.8))
    rej = log.first_rejected(5)
    assert [d.t for d in rej] == [1.2, 3.2]
    assert log.counts() == summarize(list(log))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.lists(st.sampled_from([0, 1, 2, 4]), max_size=6),
                          st.booleans(), st.integers(1, 8)), min_size=1, max_size=12))
def test_incremental_counts_and_rejections_equal_a_fresh_read(
        steps: list[tuple[list[int], bool, int]]) -> None:
    """Reading counts and rejections between appends gives what a log read once gives."""
    log = DiagnosticsLog()
    t = 0.0
    for codes, record_rejected, limit in steps:
        n = len(codes)
        log.add_block(DiagnosticsBlock(
            ["rss"] * n, t + np.arange(n, dtype=np.float64), np.array(codes, dtype=np.int64),
            np.full(n, 20.0), np.ones(n), np.ones(n), [f"A{i}" for i in range(n)], [""] * n,
            10.8))
        t += n
        if record_rejected:
            log.append(rejected("tag", t, "too far"))
            t += 1.0
        rows = list(log)
        assert log.counts() == summarize(rows)
        want = [d for d in rows if d.status == "rejected"][:limit]
        assert [d.t for d in log.first_rejected(limit)] == [d.t for d in want]
        assert log.first_rejected_dicts(limit) == [d.to_dict() for d in want]
