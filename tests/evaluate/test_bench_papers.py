"""``hrtls bench papers``: seeds, statistics over seeds, verdicts, engines."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.jobs.bench import (
    DEV_SEEDS,
    HELD_OUT_SEEDS,
    BenchRow,
    SeedStats,
    bearing_gain,
    describe_seeds,
    markdown_table,
    parse_seeds,
    run_bench,
)
from hrtls.parallel import LocalEngine


def test_dev_and_held_out_seeds_do_not_overlap() -> None:
    assert set(DEV_SEEDS).isdisjoint(HELD_OUT_SEEDS)
    assert tuple(range(100, 130)) == HELD_OUT_SEEDS
    assert parse_seeds("held-out") == HELD_OUT_SEEDS
    assert parse_seeds("dev") == DEV_SEEDS
    assert parse_seeds("3-5") == (3, 4, 5)
    assert parse_seeds("7,2") == (7, 2)
    assert describe_seeds(HELD_OUT_SEEDS) == "held-out seeds 100-129 (30)"
    assert describe_seeds((3, 5)) == "development seeds 3, 5"
    for bad in ("5-3", "x", "", "-1"):
        with pytest.raises(InputError, match="--seeds"):
            parse_seeds(bad)


def test_seed_stats_hand_computed() -> None:
    v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0]
    st = SeedStats.of(v, higher_is_better=False)
    assert st.mean == pytest.approx(5.5)
    assert st.p90 == pytest.approx(9.1)  # linear interpolation between 9 and 10
    assert st.worst == 10.0
    hi = SeedStats.of(v, higher_is_better=True)
    assert hi.p90 == pytest.approx(1.9) and hi.worst == 1.0  # the bad side is low
    assert math.isnan(SeedStats.of([1.0, math.nan], higher_is_better=False).mean)


def test_bearing_gain_is_a_paired_difference() -> None:
    mean, se, worst = bearing_gain([1.0, 2.0, 4.0], [2.0, 2.0, 3.0])
    d = np.array([-1.0, 0.0, 1.0])
    assert mean == pytest.approx(0.0)
    assert se == pytest.approx(np.std(d, ddof=1) / np.sqrt(3))
    assert worst == pytest.approx(1.0)


def test_markdown_escapes_cell_bars_and_compares_the_mean_with_the_paper() -> None:
    row = BenchRow("s", "max(|ex|)", "1.0 (Table 2)", "p", SeedStats(1.0, 2.0, 3.0),
                   SeedStats(0.5, 0.75, 1.25), "<= 1", True, 30)
    text = markdown_table([row])
    assert text.splitlines()[2] == ("| s | max(\\|ex\\|) | 1.0 (Table 2) | p: 1.00 / 2.00 / 3.00 "
                                    "| 0.50 / 0.75 / 1.25 | yes | <= 1 | yes |")
    assert BenchRow.from_dict(row.to_dict()) == row
    gain = BenchRow("s", "gain", "~1.5 (Sec. IV)", "p", SeedStats(1.0, 1.0, 1.0),
                    SeedStats(1.2, 1.1, 1.0), ">= 1.5", False, 30, higher_is_better=True)
    assert gain.paper_value == 1.5 and gain.beats_paper is False
    assert BenchRow("s", "m", "lower than without", "p", SeedStats(1, 1, 1),
                    SeedStats(1, 1, 1), "-", None, 3).beats_paper is None


def test_pool_of_two_workers_gives_the_rows_of_one_process() -> None:
    kw = {"seeds": [100, 101], "only": ["colombo_circle Tp=16"]}
    one = run_bench(**kw)
    two = run_bench(**kw, engine=LocalEngine(workers=2))
    assert [r.to_dict() for r in one] == [r.to_dict() for r in two]
    assert one[0].n_seeds == 2
    # met judges the 90th percentile over the seeds
    assert one[0].met == (one[0].default_stats.p90 <= 0.5)


def test_activity_correct_hand_computed() -> None:
    """Samples take the activity of the last row at or before them; outside the track: none."""
    from types import SimpleNamespace

    from hrtls.data import Trajectory
    from hrtls.jobs.bench import activity_correct

    n = 3
    track = Trajectory(np.array([0.0, 1.0, 2.0]), np.zeros((n, 3)), np.zeros(n),
                       np.tile(np.eye(2), (n, 1, 1)), np.zeros(n), np.array([1, 1, 3]))
    # samples at -1 (before the track), 0, 0.5, 1.5 (row 1: walking), 2.0 (row 2: upstairs), 3
    # (after the track): 4 samples inside, of which 0.5 and 2.0 are labelled like the truth
    sim = SimpleNamespace(activity_t=np.array([-1.0, 0.0, 0.5, 1.5, 2.0, 3.0]),
                          activity=np.array([1, 0, 1, 3, 3, 1]))
    got = activity_correct(SimpleNamespace(trajectory=track), sim)  # type: ignore[arg-type]
    assert got == pytest.approx(50.0)
