"""``hrtls demo``: the live job (supervisor + dashboard + a simulated team), or the batch run.

Live (the default): the supervisor on an embedded SQLite database in ``OUTPUT/live.db`` (a new
one each run), the dashboard at ``http://HOST:PORT/``, and the simulated two-floor team mission
(:mod:`hrtls.sim.team`: two rescuers, one of whom stops long enough for the PASS alarm, and a
robot) streamed live at ``--speed``. It stays up until Ctrl-C, or ``--duration-s``.
``--no-serve``: the batch comparison (missions tracked with and without infrastructure).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from hrtls.cli.errors import reports_errors
from hrtls.errors import InputError

console = Console(highlight=False)


@reports_errors
def demo(
    output: Annotated[Path, typer.Option("--output", "-o", help="Folder for the database (live) "
                                         "or sessions, results and plots (--no-serve).")
                      ] = Path("hrtls-demo"),
    seed: Annotated[int, typer.Option(help="Simulation seed.")] = 0,
    speed: Annotated[float, typer.Option(help="Replay factor of the live mission (1-32).")
                     ] = 4.0,
    host: Annotated[str, typer.Option(help="Interface of the supervisor.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port of the supervisor.")] = 8600,
    stop_s: Annotated[float, typer.Option(
        "--stop-s", help="How long rescuer B stands still (PASS alarm after 30 s).")] = 45.0,
    duration_s: Annotated[float | None, typer.Option(
        "--duration-s", help="Stop the live demo after this many seconds (default: Ctrl-C).")
    ] = None,
    no_serve: Annotated[bool, typer.Option(
        "--no-serve", help="Batch run instead: track the missions with and without "
        "infrastructure and print the comparison.")] = False,
) -> None:
    """Live supervisor and dashboard with a simulated team; --no-serve: the batch comparison."""
    from hrtls.jobs.precompile import start

    if start() is not None:  # a first run on an idle core: compiled in another process too
        console.print("[yellow]note:[/yellow] compiling in a background process too, while "
                      "the demo starts")
    if no_serve:
        from hrtls.cli.track import demo as batch_demo

        batch_demo(output=output, seed=seed)
        return
    if not 1.0 <= speed <= 32.0:
        raise InputError(f"--speed {speed}", where="hrtls demo --speed", expected="1 to 32")
    if duration_s is not None and not duration_s > 0:
        raise InputError(f"--duration-s {duration_s}", where="hrtls demo --duration-s",
                         expected="a positive number of seconds")
    _live(output, seed=seed, speed=speed, host=host, port=port, stop_s=stop_s,
          duration_s=duration_s)


def _live(output: Path, *, seed: int, speed: float, host: str, port: int, stop_s: float,
          duration_s: float | None) -> None:
    import uvicorn

    from hrtls.service.app import bootstrap, create_app
    from hrtls.service.settings import Settings
    from hrtls.service.team import stream_team_mission
    from hrtls.sim.team import team_mission

    output.mkdir(parents=True, exist_ok=True)
    db = output / "live.db"
    for stale in (db, db.with_name("live.db-wal"), db.with_name("live.db-shm")):
        stale.unlink(missing_ok=True)
    settings = Settings(db=str(db), host=host, port=port)
    token = bootstrap(settings)
    if token is None:
        raise InputError(f"{db} already has a commander", where="hrtls demo --output",
                         expected="a folder whose live.db can be replaced")
    server = uvicorn.Server(uvicorn.Config(create_app(settings), host=host, port=port,
                                           log_level="warning"))
    thread = threading.Thread(target=server.run, name="hrtls supervisor", daemon=True)
    thread.start()
    with console.status("simulating the team mission (two rescuers and a robot)"):
        mission = team_mission(seed, stop_s=stop_s)
    deadline = time.monotonic() + 30
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise InputError(f"the supervisor did not start on {host}:{port}",
                             where="hrtls demo --port", expected="a free port")
        time.sleep(0.05)
    url = f"http://{host}:{port}"
    stream = stream_team_mission(url, token, mission, speed=speed,
                                 on_error=lambda m: console.print(f"[red]stream:[/red] {m}"))
    console.print(f"[bold]{mission.name}[/bold], streamed live at {speed:g}x "
                  f"({mission.duration_s / speed:.0f} s):")
    for member in mission.members:
        console.print(f"  {member.name} ({member.kind}): {member.note}")
    console.print(f"dashboard  [bold]{url}/?mission={stream.mission_id}[/bold]")
    console.print(f"commander token (sign in with it)  [bold]{token}[/bold]")
    console.print(f"database {db}; Ctrl-C stops" if duration_s is None
                  else f"database {db}; stops after {duration_s:g} s")
    start = time.monotonic()
    announced = False
    try:
        while duration_s is None or time.monotonic() - start < duration_s:
            time.sleep(0.2)
            if stream.done and not announced:
                announced = True
                console.print("mission streamed; the dashboard stays up for replay "
                              "(Ctrl-C stops)")
    except KeyboardInterrupt:
        console.print("stopping")
    finally:
        server.should_exit = True
        thread.join(timeout=10)
