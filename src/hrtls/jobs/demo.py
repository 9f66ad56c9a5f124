"""The demo: the thesis' rescue missions simulated, tracked with and without infrastructure."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hrtls.jobs.track import evaluate_track, write_track_outputs
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.config import FixesConfig, RangesConfig, RssConfig, TagsConfig
from hrtls.pipeline.finish import finish_track
from hrtls.sim.scenarios import run_scenario, write_result

MISSIONS: tuple[tuple[str, dict[str, Any], str], ...] = (
    ("inderst_ring", {}, "500 m in a ring-shaped office corridor with 9 RFID tags"),
    ("inderst_multifloor", {}, "280 m over two floors with stairs (no infrastructure)"),
)


@dataclass(frozen=True, slots=True)
class DemoRow:
    """One mission tracked one way."""

    mission: str
    method: str
    folder: Path
    steps: int
    distance_m: float
    checkpoint_mean_m: float | None
    checkpoint_max_m: float | None
    error_p90_m: float | None
    seconds: float
    corrections: dict[str, Any]


def dead_reckoning(config: TrackerConfig) -> TrackerConfig:
    """The same tracker with every infrastructure correction switched off."""
    return config.model_copy(update={
        "name": f"{config.name} (dead reckoning)",
        "fixes": FixesConfig(enabled=False), "rss": RssConfig(mode="off"),
        "tags": TagsConfig(enabled=False), "ranges": RangesConfig(enabled=False)})


def run_demo(out_dir: Path, *, seed: int = 0, overwrite: bool = False,
             progress: Callable[[str], None] | None = None) -> list[DemoRow]:
    """Simulate each mission, track it twice, write sessions, results and plots under out_dir."""
    rows: list[DemoRow] = []
    full = preset("default")
    for mission, options, _ in MISSIONS:
        if progress:
            progress(f"simulating {mission}")
        sim = run_scenario(mission, seed, **options)
        write_result(sim, out_dir / mission / "session", overwrite=overwrite)
        runs = [("dead reckoning", dead_reckoning(full))]
        session = sim.session
        if any(part is not None for part in (session.fixes, session.rss, session.tags,
                                             session.ranges)):
            runs.append(("with infrastructure", full))
        for label, cfg in runs:
            if progress:
                progress(f"tracking {mission}: {label}")
            start = time.perf_counter()
            result = finish_track(Tracker(cfg).run(sim.session), sim.session, cfg)
            seconds = time.perf_counter() - start
            evaluation = evaluate_track(result, sim.session, sim.reference)
            folder = out_dir / mission / label.replace(" ", "_")
            write_track_outputs(result, sim.session, folder, overwrite=overwrite, plot=True,
                                evaluation=evaluation)
            cps = (evaluation or {}).get("checkpoints") or {}
            pos = (evaluation or {}).get("position") or {}
            rows.append(DemoRow(mission, label, folder, len(result.steps),
                                result.steps.distance_m, cps.get("mean"), cps.get("max"),
                                pos.get("p90"), seconds, result.report["corrections"]))
    return rows
