"""The benchmark's split of the agents' NEES by node use (``benchmarks/_mission_nees.py``)."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import pytest


@pytest.fixture(scope="module")
def split(benchmark_import: Callable[[str], ModuleType]) -> ModuleType:
    return benchmark_import("_mission_nees")


def test_since_bins(split: ModuleType) -> None:
    assert split.since_label(0.0) == "00-5 s"
    assert split.since_label(5.0) == "05-15 s"
    assert split.since_label(59.9) == "30-60 s"
    assert split.since_label(60.0) == ">= 60 s"


def test_table_pools_sums_over_seeds(split: ModuleType) -> None:
    """Hand case: bin a holds NEES sums 4 and 8 over 2 + 2 samples (mean 3), bin b 1 over 4
    samples; shares within the split 0.5 / 0.5."""
    per_seed = [{"s: a": [4.0, 2.0], "s: b": [1.0, 2.0]}, {"s: a": [8.0, 2.0], "s: b": [0.0, 2.0]}]
    lines = split.nees_split_table(per_seed).splitlines()
    assert lines[2] == "| s: a | 3.00 | 0.50 | 2 |"
    assert lines[3] == "| s: b | 0.25 | 0.50 | 2 |"
