"""Commands ``hrtls simulate`` and ``hrtls evaluate``.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import sim as sim_cli
    app.command("simulate")(sim_cli.simulate)
    app.command("evaluate")(sim_cli.evaluate)

``hrtls simulate SCENARIO -o DIR [--seed N] [-O key=value ...]`` writes a session with ground
truth; ``hrtls simulate --list`` lists the scenarios. ``hrtls evaluate RESULT_DIR --truth
SESSION_DIR`` scores ``RESULT_DIR/trajectory.csv`` (and ``steps.csv``) against the session's
``truth.csv``, ``checkpoints.csv``, ``truth_steps.csv`` and ``activity.csv``, prints a table and
writes ``report.json`` and PNG plots into the result folder (or ``--output``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import reports_errors
from hrtls.data import Checkpoints, GroundTruth, Landmark, StepEvents, activity_codes
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
    from hrtls.sim.scenarios import SCENARIOS

    table = Table("scenario", "what", "options (-O key=value, defaults)")
    for name, spec in SCENARIOS.items():
        table.add_row(name, spec.summary,
                      ", ".join(f"{k}={v}" for k, v in spec.options.items()))
    return table


def run_simulation(scenario: str, output: Path, *, seed: int = 0,
                   options: dict[str, Any] | None = None, overwrite: bool = False) -> Path:
    """Simulate ``scenario`` and write its session folder; returns the folder."""
    from hrtls.sim.scenarios import run_scenario, write_result

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
    """Simulate a paper scenario into a session folder with ground truth."""
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
def _read_truth(folder: Path) -> tuple[GroundTruth | None, Checkpoints | None]:
    from hrtls.io.csvtable import read_table

    truth = None
    path = folder / "truth.csv"
    if path.exists():
        table = read_table(path.read_bytes(), name=str(path),
                           kinds=dict.fromkeys(("t", "x", "y", "z", "heading"), "float"),
                           required=("t", "x", "y", "z"))
        xyz = np.column_stack([table.float(c) for c in ("x", "y", "z")])
        heading = table.float("heading") if "heading" in table.present else None
        truth = GroundTruth(table.float("t"), xyz, heading, name=str(path))
    cps = None
    path = folder / "checkpoints.csv"
    if path.exists():
        table = read_table(path.read_bytes(), name=str(path),
                           kinds={"t": "float", "x": "float", "y": "float", "z": "float",
                                  "label": "str"}, required=("t", "x", "y", "z"))
        xyz = np.column_stack([table.float(c) for c in ("x", "y", "z")])
        labels = (table.str("label") if "label" in table.present
                  else np.full(table.n_rows, "", dtype=np.str_))
        cps = Checkpoints(table.float("t"), xyz, labels, name=str(path))
    return truth, cps


def read_activity_intervals(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``activity.csv`` (``t_start,t_end,activity``) as a step function (times, codes)."""
    iv = read_intervals(path, columns={"activity": "str"})
    return iv.t_start, activity_codes(iv.table.str("activity"), where=f"{path} activity")


def _read_landmarks(folder: Path) -> dict[str, Landmark]:
    path = folder / "landmarks.json"
    if not path.exists():
        return {}
    items = json.loads(path.read_text())
    out = {}
    for item in items:
        lm = Landmark.model_validate(item)
        out[lm.id] = lm
    return out


def evaluate_result(result_dir: Path, truth_dir: Path, *, output: Path | None = None,
                    plots: bool = True) -> dict[str, Any]:
    """Score ``result_dir`` against ``truth_dir``; write ``report.json`` (+ plots); return it."""
    from hrtls.evaluate.metrics import checkpoint_errors, position_errors
    from hrtls.evaluate.report import EvaluationInputs, build_report
    from hrtls.io.tables import read_steps, read_trajectory

    traj_path = result_dir / "trajectory.csv"
    if not traj_path.exists():
        raise InputError("no trajectory.csv", where=str(result_dir),
                         expected="a result folder written by `hrtls track`")
    if not truth_dir.is_dir():
        raise InputError("not a folder", where=str(truth_dir), expected="a session folder")
    estimate = read_trajectory(traj_path)
    steps = read_steps(result_dir / "steps.csv") if (result_dir / "steps.csv").exists() else None
    truth, cps = _read_truth(truth_dir)
    if truth is None and cps is None:
        raise InputError("no truth.csv or checkpoints.csv", where=str(truth_dir),
                         expected="a session with ground truth")
    true_steps: StepEvents | None = None
    if (truth_dir / "truth_steps.csv").exists():
        true_steps = read_steps(truth_dir / "truth_steps.csv")
    activity = None
    if (truth_dir / "activity.csv").exists():
        activity = read_activity_intervals(truth_dir / "activity.csv")
    reference: dict[str, Any] = {}
    if (truth_dir / "scenario.json").exists():
        reference = json.loads((truth_dir / "scenario.json").read_text()).get("reference", {})
    report = build_report(EvaluationInputs(estimate=estimate, estimated_steps=steps,
                                           truth=truth, checkpoints=cps, true_steps=true_steps,
                                           true_activity=activity, reference=reference))
    out = output or result_dir
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    if plots:
        from hrtls.evaluate.plots import plot_cdf, plot_error_over_time, plot_trajectory

        plot_trajectory(out / "trajectory.png", estimate, truth, checkpoints=cps,
                        landmarks=_read_landmarks(truth_dir), title=result_dir.name)
        t_e, e = position_errors(estimate, truth) if truth is not None else (np.zeros(0),
                                                                              np.zeros(0))
        t_c, e_c = (checkpoint_errors(estimate, cps)[:2] if cps is not None
                    else (None, None))
        plot_error_over_time(out / "error.png", t_e, e, checkpoint_t=t_c,
                             checkpoint_error_m=e_c)
        sets = {"continuous truth": e} if e.size else {}
        if e_c is not None and len(e_c):
            sets["checkpoints"] = e_c
        plot_cdf(out / "cdf.png", sets)
    return report


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
    result_dir: Annotated[Path, typer.Argument(help="Folder with trajectory.csv [steps.csv].")],
    truth: Annotated[Path, typer.Option("--truth", help="Session folder with ground truth "
                                        "(or a reference orientation).")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="Where to write report.json and plots (default RESULT_DIR).")
    ] = None,
    plots: Annotated[bool, typer.Option(help="Write PNG plots.")] = True,
) -> None:
    """Score an estimated trajectory against ground truth; write report.json and plots.

    RESULT_DIR may instead be the CSV of ``hrtls attitude``: it is scored against the reference
    orientation ``--truth`` (CSV or BROAD trial) and ``<stem>_orientation.json`` is written.
    """
    if result_dir.is_file():
        from hrtls.cli.attitude import evaluate_orientation, orientation_table

        console.print(orientation_table(evaluate_orientation(result_dir, truth, output)))
        return
    report = evaluate_result(result_dir, truth, output=output, plots=plots)
    console.print(report_table(report))
    console.print(f"wrote {(output or result_dir) / 'report.json'}")
