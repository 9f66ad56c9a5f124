"""Commands ``hrtls simulate`` and ``hrtls evaluate``.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import sim as sim_cli
    app.command("simulate")(sim_cli.simulate)
    app.command("evaluate")(sim_cli.evaluate)

``hrtls simulate SCENARIO -o DIR [--seed N] [-O key=value ...]`` writes a session with ground
truth, or for a simulated mission (``inderst_hybrid_mission``) a mission folder
(:mod:`hrtls.io.mission`, tracked by ``hrtls mission track``); ``hrtls simulate --list`` lists
the scenarios and missions. ``hrtls evaluate RESULT_DIR --truth
SESSION_DIR`` scores ``RESULT_DIR/trajectory.csv`` (and ``steps.csv``) against the session's
``truth.csv``, ``checkpoints.csv``, ``truth_steps.csv`` and ``activity.csv`` (or any recording
with ground truth), prints a table and writes ``evaluation.json`` and PNG plots into the result
folder (or ``--output``); see :mod:`hrtls.jobs.evaluate`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import reports_errors
from hrtls.data import activity_codes
from hrtls.errors import InputError
from hrtls.io.intervals import read_intervals

console = Console(highlight=False)


# --------------------------------------------------------------------------------------------
# simulate
# --------------------------------------------------------------------------------------------
def parse_options(items: list[str]) -> dict[str, Any]:
    """``key=value`` strings to a dict; values become bool, int, float or stay text."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"option {item!r}", where="--option", expected="key=value")
        key, text = item.split("=", 1)
        value: Any = text
        low = text.strip().lower()
        if low in ("true", "false"):
            value = low == "true"
        else:
            for cast in (int, float):
                try:
                    value = cast(text)
                    break
                except ValueError:
                    continue
        out[key.strip()] = value
    return out


def scenario_table() -> Table:
    """Rich table of the registered scenarios."""
    import dataclasses

    from hrtls.sim.mission import MISSIONS, MissionOptions
    from hrtls.sim.scenarios import SCENARIOS

    table = Table("scenario", "what", "options (-O key=value, defaults)")
    for name, spec in SCENARIOS.items():
        table.add_row(name, spec.summary,
                      ", ".join(f"{k}={v}" for k, v in spec.options.items()))
    defaults = ", ".join(f"{k}={v}" for k, v in dataclasses.asdict(MissionOptions()).items())
    for name, run in MISSIONS.items():
        table.add_row(name, "mission folder: " + (run.__doc__ or "").strip().splitlines()[0],
                      defaults)
    return table


def run_simulation(scenario: str, output: Path, *, seed: int = 0,
                   options: dict[str, Any] | None = None, overwrite: bool = False) -> Path:
    """Simulate ``scenario`` and write its session (or mission) folder; returns the folder."""
    from hrtls.sim.mission import MISSIONS, run_mission, write_mission_result
    from hrtls.sim.scenarios import run_scenario, write_result

    if scenario in MISSIONS:
        mission = run_mission(scenario, seed, **(options or {}))
        return write_mission_result(mission, output, overwrite=overwrite)
    result = run_scenario(scenario, seed, **(options or {}))
    return write_result(result, output, overwrite=overwrite)


@reports_errors
def simulate(
    scenario: Annotated[str | None, typer.Argument(help="Scenario name (see --list).")] = None,
    output: Annotated[Path | None, typer.Option("--output", "-o",
                                                help="Session folder to write.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    option: Annotated[list[str] | None, typer.Option(
        "--option", "-O", help="Scenario option key=value (repeatable).")] = None,
    list_scenarios: Annotated[bool, typer.Option("--list", help="List scenarios.")] = False,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing session.")] = False,
) -> None:
    """Simulate a paper scenario into a session folder with ground truth.

    A simulated mission (see --list) becomes a mission folder instead: one session per agent,
    mission.json, network.json (node ids) and network_truth.json (for scoring only).
    """
    if list_scenarios:
        console.print(scenario_table())
        return
    if scenario is None or output is None:
        raise InputError("missing scenario or output", where="hrtls simulate",
                         expected="SCENARIO -o DIR (or --list)")
    out = run_simulation(scenario, output, seed=seed, options=parse_options(option or []),
                         overwrite=overwrite)
    console.print(f"wrote {out} (scenario {scenario}, seed {seed})")


# --------------------------------------------------------------------------------------------
# evaluate
# --------------------------------------------------------------------------------------------
def read_activity_intervals(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``activity.csv`` (``t_start,t_end,activity``) as a step function (times, codes)."""
    iv = read_intervals(path, columns={"activity": "str"})
    return iv.t_start, activity_codes(iv.table.str("activity"), where=f"{path} activity")


def report_table(report: dict[str, Any]) -> Table:
    """The headline numbers of a report as a rich table."""
    table = Table("metric", "value")

    def fmt(v: Any, unit: str = "", pct: bool = False) -> str:
        if v is None:
            return "-"
        return f"{100 * v:.2f} %" if pct else f"{v:.3f}{unit}"

    pos = report.get("position")
    if pos:
        for k in ("mean", "rmse", "median", "p75", "p90", "p95", "max", "final_m"):
            table.add_row(f"position {k.removesuffix('_m')}", fmt(pos.get(k), " m"))
        table.add_row("final error / distance", fmt(pos.get("final_fraction_of_distance"),
                                                    pct=True))
        table.add_row("mean error / distance", fmt(pos.get("mean_fraction_of_distance"),
                                                   pct=True))
    cp = report.get("checkpoints")
    if cp:
        table.add_row("checkpoint mean", fmt(cp.get("mean"), " m"))
        table.add_row("checkpoint max", fmt(cp.get("max"), " m"))
        if "integral_mean_error_fraction" in cp:
            table.add_row("integral mean error (Basso)",
                          fmt(cp.get("integral_mean_error_fraction"), pct=True))
    if "heading" in report:
        table.add_row("heading RMSE", fmt(report["heading"].get("rmse"), " rad"))
    if "velocity" in report:
        table.add_row("velocity RMSE", fmt(report["velocity"].get("rmse_m_s"), " m/s"))
    st = report.get("steps")
    if st:
        table.add_row("steps est / true", f"{st['n_estimated']} / {st['n_true']}")
        table.add_row("step length error (sum)", fmt(st.get("length_error_fraction"), pct=True))
        table.add_row("step length RMSE", fmt(st.get("step_length_rmse_m"), " m"))
    if "activity" in report:
        table.add_row("activity accuracy", fmt(report["activity"].get("accuracy"), pct=True))
    return table


@reports_errors
def evaluate(
    result_dir: Annotated[Path, typer.Argument(help="Result folder of `hrtls track`.")],
    truth: Annotated[Path, typer.Option("--truth", help="Any recording with ground truth "
                                        "(or a reference orientation).")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="Where to write evaluation.json and plots (default RESULT_DIR).")
    ] = None,
    plots: Annotated[bool, typer.Option(help="Write PNG plots.")] = True,
    fmt: Annotated[str | None, typer.Option(
        "--format", "-f", help="Format of --truth (default: detected).")] = None,
    trial: Annotated[str | None, typer.Option(
        "--trial", help="Trial of a multi-trial truth recording (mobgap).")] = None,
) -> None:
    """Score a result folder against ground truth; write evaluation.json and plots beside it.

    The track's own files (report.json, tables, GeoJSON) are left as they are. The truth may be
    any supported recording; its time span must overlap the result's.

    RESULT_DIR may instead be the CSV of ``hrtls attitude``: it is scored against the reference
    orientation ``--truth`` (CSV or BROAD trial) and ``<stem>_orientation.json`` is written.
    """
    if result_dir.is_file():
        from hrtls.cli.attitude import evaluate_orientation, orientation_table

        console.print(orientation_table(evaluate_orientation(result_dir, truth, output)))
        return
    from hrtls.cli.paths import check_writable
    from hrtls.jobs.evaluate import EVALUATION_FILE, evaluate_result

    if output is not None:
        check_writable(output, flag="--output", folder=True)
    report = evaluate_result(result_dir, truth, output=output, plots=plots, fmt=fmt,
                             trial=trial)
    console.print(report_table(report))
    console.print(f"wrote {(output or result_dir) / EVALUATION_FILE}")
