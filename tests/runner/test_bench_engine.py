"""The seed-looping benchmarks print the same tables in one process and on a process pool."""

import sys

import pytest

from hrtls.parallel import LocalEngine


@pytest.fixture
def bench_modules(benchmark_import):
    return benchmark_import("causal"), benchmark_import("_engine")


def test_causal_tables_equal_on_one_process_and_two_workers(bench_modules, monkeypatch, capsys):
    causal, _ = bench_modules
    out = {}
    for workers in ("1", "2"):
        monkeypatch.setattr(sys, "argv", ["causal.py", "--only", "basso_test1", "--seeds",
                                          "100-101", "--engine", "local", "--workers", workers])
        causal.main()
        out[workers] = capsys.readouterr().out
    assert "basso_test1" in out["1"] and "IME/L" in out["1"]
    assert out["1"] == out["2"]


def _refuse_two(x: int) -> int:
    if x == 2:
        raise ValueError("two is refused")
    return 10 * x


def test_a_failed_item_is_reported_and_fails_the_run(bench_modules, capsys):
    _, engine = bench_modules
    batch = engine.Batch(LocalEngine(workers=1))
    assert batch.map(_refuse_two, [1, 2, 3], label=lambda x: f"seed {x}") == [(1, 10), (3, 30)]
    err = capsys.readouterr().err
    assert "seed 2 failed, left out of the tables: ValueError: two is refused" in err
    with pytest.raises(SystemExit, match="1 item"):
        batch.finish()
