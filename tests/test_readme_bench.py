"""The README's simulated paper table is the output of ``hrtls bench papers`` on held-out seeds."""

from __future__ import annotations

import json
from pathlib import Path

from hrtls.jobs.bench import DEV_SEEDS, HELD_OUT_SEEDS, BenchRow, describe_seeds, markdown_table

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
BEGIN = "<!-- bench_papers.md: begin -->\n"
END = "<!-- bench_papers.md: end -->"


def _readme_table() -> str:
    text = (ROOT / "README.md").read_text()
    assert text.count(BEGIN) == 1 and text.count(END) == 1
    return text.split(BEGIN, 1)[1].split(END, 1)[0]


def test_bench_json_is_on_the_held_out_seeds() -> None:
    data = json.loads((RESULTS / "bench_papers.json").read_text())
    seeds = tuple(int(s) for s in data["seeds"])
    assert seeds == HELD_OUT_SEEDS
    assert set(seeds).isdisjoint(DEV_SEEDS)
    assert all(d["n_seeds"] == len(seeds) for d in data["rows"])


def test_markdown_file_is_generated_from_the_json() -> None:
    data = json.loads((RESULTS / "bench_papers.json").read_text())
    rows = [BenchRow.from_dict(d) for d in data["rows"]]
    assert (RESULTS / "bench_papers.md").read_text() == markdown_table(rows)


def test_readme_table_is_the_markdown_file_and_names_its_seeds() -> None:
    assert _readme_table() == (RESULTS / "bench_papers.md").read_text()
    readme = (ROOT / "README.md").read_text()
    intro = readme.split(BEGIN, 1)[0].rsplit("\n## ", 1)[1]
    assert describe_seeds(HELD_OUT_SEEDS) in intro
    assert "development seeds 0-9" in intro
    assert "--json docs/results/bench_papers.json" in intro
