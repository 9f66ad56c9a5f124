"""Command ``hrtls ipin``: track an IPIN logfile of a hand-held phone, score it at the landmarks.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import ipin as ipin_cli
    app.command("ipin")(ipin_cli.ipin)
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, cast

import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import reports_errors

if TYPE_CHECKING:
    from hrtls.data import ChannelModel
    from hrtls.jobs.ipin_eval import LandmarkErrors, Mounting, RssFloors
    from hrtls.pipeline.config import TrackerConfig

console = Console(highlight=False)


def _checked_choices(*, mounting: str, rss_floors: str, rss_window_s: float
                     ) -> tuple[Mounting, RssFloors]:
    """``--mounting`` and ``--rss-floors`` as their types; a bad value or window raises."""
    from hrtls.errors import InputError

    if mounting not in ("handheld", "unknown"):
        raise InputError(f"{mounting!r}", where="--mounting", expected="handheld | unknown")
    if rss_floors not in ("same", "all"):
        raise InputError(f"{rss_floors!r}", where="--rss-floors", expected="same | all")
    if not rss_window_s >= 0:
        raise InputError(f"{rss_window_s}", where="--rss-window", expected=">= 0 s")
    return cast("Mounting", mounting), cast("RssFloors", rss_floors)


def _calibration(train: Path | None, *, cfg: TrackerConfig, beacons: Path | None,
                 weinberg_k: float | None, mounting: Mounting, rss_floors: RssFloors,
                 rss_window_s: float) -> tuple[float | None, ChannelModel | None]:
    """Weinberg constant (the given one, else fitted on ``train``) and path-loss law.

    The channel is fitted on ``train`` when RSS is used; without ``train`` both stay as given.
    """
    from hrtls.io.readers.ipin import read_ipin
    from hrtls.jobs.ipin_eval import calibrate_channel, calibrate_weinberg_k, prepare_session

    channel = None
    if train is not None:
        training = read_ipin(train, beacons=beacons, trim_to_start=True)
        if weinberg_k is None:
            weinberg_k = calibrate_weinberg_k(
                prepare_session(training, mounting=mounting, rss_floors=rss_floors), cfg)
        if cfg.rss.mode != "off":
            channel = calibrate_channel(training, rss_window_s=rss_window_s)
        console.print(f"calibrated on {train.name}: Weinberg k = {weinberg_k:.3f}" + (
            "" if channel is None else f", A = {channel.a_dbm:.1f} dBm, eta = "
            f"{channel.eta:.2f}, sigma = {channel.sigma_db:.1f} dB"))
    elif cfg.rss.mode != "off" and not cfg.rss.estimate_channel:
        console.print("note: RSS with a fixed channel but no --train file: the default "
                      "path-loss law (A = -59 dBm, eta = 2) is used")
    return weinberg_k, channel


def _print_landmark_errors(e: LandmarkErrors, *, title: str) -> None:
    """Error per landmark as a table, then their statistics beside the IPIN 2021 best."""
    from hrtls.jobs.ipin_eval import REFERENCE_P75_M

    table = Table(title=title)
    for col in ("landmark", "t [s]", "error [m]", "floor est/true"):
        table.add_column(col, justify="right")
    for i in range(len(e.t)):
        table.add_row(str(e.label[i]), f"{e.t[i]:.1f}", f"{e.horizontal_m[i]:.2f}",
                      f"{e.floor_estimated[i]}/{e.floor_true[i]}")
    console.print(table)
    st = e.stats
    console.print(f"landmarks {st.n}: mean {st.mean:.2f} m, median {st.median:.2f} m, "
                  f"p75 {st.p75:.2f} m (IPIN 2021 best: {REFERENCE_P75_M} m), "
                  f"max {st.max:.2f} m, floors {e.floor_hits}/{st.n}")


@reports_errors
def ipin(
    logfile: Annotated[Path, typer.Argument(help="IPIN logfile (GetSensorData .txt).")],
    output: Annotated[Path | None, typer.Option("--output", "-o",
                                                help="Write the track outputs here.")] = None,
    config: Annotated[Path | None, typer.Option("--config", "-c",
                                                help="Tracker configuration (TOML).")] = None,
    beacons: Annotated[Path | None, typer.Option(
        "--beacons", help="Beacon CSV (default: BLE_Locations.csv beside the file).")] = None,
    mounting: Annotated[str, typer.Option(
        help="handheld (phone in front, top edge forward) | unknown")] = "handheld",
    rss_floors: Annotated[str, typer.Option(
        help="same (beacons on the start floor only) | all")] = "same",
    weinberg_k: Annotated[float | None, typer.Option(
        help="Weinberg step constant (e.g. calibrated on another file).")] = None,
    train: Annotated[Path | None, typer.Option(
        "--train", help="Training logfile (same venue, with POSI): calibrates the Weinberg "
        "constant and, when RSS is used, the path-loss law on it.")] = None,
    rss_window: Annotated[float, typer.Option(
        help="Average RSS per beacon over this window, s (0: every reading).")] = 4.0,
    plot: Annotated[bool, typer.Option("--plot", help="Also write track.png.")] = False,
    overwrite: Annotated[bool, typer.Option(help="Replace existing results.")] = False,
) -> None:
    """Track from the first POSI (start, heading unknown); errors at the later POSI landmarks."""
    from hrtls.errors import DegradedInputWarning, InputError
    from hrtls.io.readers.ipin import read_ipin
    from hrtls.jobs.ipin_eval import (
        IpinCase,
        make_config,
        prepare_session,
        run_case,
        with_weinberg_k,
    )
    from hrtls.jobs.track import write_track_outputs
    from hrtls.pipeline import load_config

    mount, floors = _checked_choices(mounting=mounting, rss_floors=rss_floors,
                                     rss_window_s=rss_window)
    cfg = load_config(config) if config is not None else make_config(name="ipin-handheld")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        weinberg_k, channel = _calibration(train, cfg=cfg, beacons=beacons,
                                           weinberg_k=weinberg_k, mounting=mount,
                                           rss_floors=floors, rss_window_s=rss_window)
        cfg = with_weinberg_k(cfg, weinberg_k)
        session = read_ipin(logfile, beacons=beacons, trim_to_start=True)
        case = IpinCase(cfg.name, cfg, mounting=mount, rss_floors=floors,
                        rss_window_s=rss_window)
        res = run_case(session, case, file=logfile.name, channel=channel)
    if res.errors is None or res.result is None:
        raise InputError(f"tracking failed: {res.error}", where=str(logfile),
                         expected="a trackable logfile")
    _print_landmark_errors(res.errors, title=f"{logfile.name}: {cfg.name}, mounting {mounting}")
    if output is not None:
        prepared = prepare_session(session, mounting=case.mounting, rss_floors=case.rss_floors,
                                   rss_window_s=case.rss_window_s, channel=channel)
        write_track_outputs(res.result, prepared, output, overwrite=overwrite, plot=plot)
        console.print(f"wrote {output}")
