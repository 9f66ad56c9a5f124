"""``hrtls agent replay``, ``hrtls mission simulate|export``, ``hrtls mission track``.

``agent replay``, ``mission simulate`` and ``mission export`` are clients of ``hrtls serve``;
``mission track`` tracks a mission folder offline (:mod:`hrtls.jobs.mission`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from hrtls.cli.errors import reports_errors
from hrtls.service.settings import DEFAULT_DB

agent_app = typer.Typer(no_args_is_help=True, add_completion=False,
                        help="Live agents: stream a recording to a running service.")
mission_app = typer.Typer(
    no_args_is_help=True, add_completion=False,
    help="Missions: track a folder offline; on a service: simulate, floor images, export.")

ServerOption = Annotated[str, typer.Option("--server", help="Service URL, e.g. "
                                           "http://127.0.0.1:8600")]
SpeedOption = Annotated[float, typer.Option(
    "--speed", help="Replay factor: 1 = real time, 10 = ten times faster, 0 = as fast as "
                    "the service acknowledges.")]


@agent_app.callback()
def _agent() -> None:
    """Live agents: stream a recording to a running service."""


@mission_app.callback()
def _mission() -> None:
    """Missions: track a folder offline; on a service: simulate, floor images, export."""


def _speed(speed: float) -> float:
    from hrtls.errors import InputError

    if not math.isfinite(speed) or speed < 0:
        raise InputError(f"{speed}", where="--speed", expected="a factor >= 0 (0: no pacing)")
    return math.inf if speed == 0 else speed


@agent_app.command("replay")
@reports_errors
def agent_replay(
    session: Annotated[Path, typer.Argument(help="Recording (any format hrtls reads).")],
    server: ServerOption,
    token: Annotated[str, typer.Option("--token", help="The agent's ingest token.")],
    speed: SpeedOption = 1.0,
    fmt: Annotated[str | None, typer.Option("--format", "-f", help="Input format.")] = None,
) -> None:
    """Stream a recorded or simulated session as a live agent (its start = now)."""
    from hrtls.recordings import read_any
    from hrtls.service.missions import stream_agent

    pace = _speed(speed)
    recording = read_any(session, fmt=fmt)
    client = stream_agent(server, token, recording, speed=pace)
    typer.echo(f"sent {client.stats.acked} batches ({client.stats.duplicates} duplicates, "
               f"{client.stats.retries_429} retries after 429, {client.stats.gaps} gaps); "
               f"unacknowledged: {len(client.outbox)}")
    client.close()


@mission_app.command("simulate")
@reports_errors
def mission_simulate(
    name: Annotated[str, typer.Argument(help="inderst_two_users, inderst_multifloor, office "
                                        "or inderst_hybrid_mission (with a sensor network).")],
    server: ServerOption,
    token: Annotated[str, typer.Option("--token", help="A commander token.")],
    speed: SpeedOption = 1.0,
    seed: Annotated[int, typer.Option("--seed", help="Seed of a networked mission.")] = 0,
    options: Annotated[list[str] | None, typer.Option(
        "--option", "-O", help="Networked mission: a simulator option or a mission estimator "
        "parameter (chunk_s, silent_after_s, cooperate, ...), key=value (repeatable).")] = None,
) -> None:
    """Create a simulated mission with its agents and stream them all live."""
    from hrtls.service.client import AgentClient
    from hrtls.service.missions import create_mission, stream_team, team
    from hrtls.sim.mission import MISSIONS

    pace = _speed(speed)
    if name in MISSIONS:
        _simulate_network(name, server, token, pace, seed, options or [])
        return
    if options:
        from hrtls.errors import InputError

        raise InputError(f"-O {options[0]}", where=f"hrtls mission simulate {name}",
                         expected="options only for " + ", ".join(MISSIONS))
    members = team(name)
    with AgentClient(server, token) as commander:
        mid, agents = create_mission(commander, name, members)
    typer.echo(f"mission {mid} '{name}': " + ", ".join(
        f"{m.name} (agent {aid}, {m.kind})" for m, aid, _ in agents))
    typer.echo(f"dashboard: {server.rstrip('/')}/?mission={mid}")
    clients = stream_team(server, agents, speed=pace)
    total = sum(c.stats.acked for c in clients)
    left = sum(len(c.outbox) for c in clients)
    typer.echo(f"streamed {total} batches of {len(clients)} agents; unacknowledged: {left}")
    for c in clients:
        c.close()


def _simulate_network(name: str, server: str, token: str, pace: float, seed: int,
                      items: list[str]) -> None:
    """``mission simulate`` of a networked mission: the service runs its mission estimator."""
    import dataclasses

    from hrtls.cli.sim import parse_options
    from hrtls.errors import InputError
    from hrtls.service.client import AgentClient
    from hrtls.service.network_sim import create_network_mission, network_team, stream_network
    from hrtls.service.routes.network import LIVE_PARAMS
    from hrtls.sim.mission import MissionOptions

    values = parse_options(items)
    sim_keys = {f.name for f in dataclasses.fields(MissionOptions)}
    bad = sorted(set(values) - sim_keys - set(LIVE_PARAMS))
    if bad:
        raise InputError(f"unknown option {bad[0]!r}", where="--option",
                         expected="one of " + ", ".join(sorted(sim_keys | set(LIVE_PARAMS))))
    mission, members = network_team(name, seed=seed, options={
        k: v for k, v in values.items() if k in sim_keys})
    with AgentClient(server, token) as commander:
        mid, agents = create_network_mission(commander, name, mission, members, params={
            k: v for k, v in values.items() if k in LIVE_PARAMS})
        typer.echo(f"mission {mid} '{name}' seed {seed}: {len(mission.node_truth_m)} nodes; "
                   + ", ".join(f"{m.name} (agent {aid}, {m.kind})" for m, aid, _ in agents))
        typer.echo(f"dashboard: {server.rstrip('/')}/?mission={mid}")
        clients = stream_network(server, commander, mid, agents, speed=pace,
                                 network=mission.network_ranges)
        net = commander.request("GET", f"/missions/{mid}/network")
    localized = sum(1 for n in net["nodes"] if n["localized"])
    typer.echo(f"streamed {sum(c.stats.acked for c in clients)} batches of {len(clients)} "
               f"agents; unacknowledged: {sum(len(c.outbox) for c in clients)}; nodes "
               f"localized so far: {localized} of {len(net['nodes'])} (the last windows follow "
               "once every agent is silent)")
    for c in clients:
        c.close()


@mission_app.command("floor-image")
@reports_errors
def mission_floor_image(
    mission: Annotated[int, typer.Argument(help="Mission id.")],
    floor: Annotated[int, typer.Argument(help="Floor index (the floor must exist).")],
    image: Annotated[Path, typer.Argument(help="PNG or JPEG plan of the floor.")],
    server: ServerOption,
    token: Annotated[str, typer.Option("--token", help="A commander token.")],
    origin_m: Annotated[tuple[float, float], typer.Option(
        "--origin-m", help="x y of the image's lower-left corner in the mission frame, m.")],
    m_per_px: Annotated[float, typer.Option("--m-per-px", help="Scale: metres per pixel.")],
) -> None:
    """Upload a floor's plan image; the dashboard draws it under the plan."""
    from hrtls.errors import InputError
    from hrtls.service.client import AgentClient, ServiceError

    media = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
    media_type = media.get(image.suffix.lower())
    if media_type is None:
        raise InputError(f"{image.name}", where="IMAGE", expected="a .png, .jpg or .jpeg file")
    try:
        data = image.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {image} ({exc.strerror})", where="IMAGE") from None
    with AgentClient(server, token) as commander:
        try:
            out = commander.request(
                "PUT", f"/missions/{mission}/floors/{floor}/image", content=data,
                headers={"Content-Type": media_type},
                params={"origin_x_m": origin_m[0], "origin_y_m": origin_m[1],
                        "m_per_px": m_per_px})
        except ServiceError as exc:
            raise InputError(f"HTTP {exc.status}: {exc.detail}", where=f"{server} (upload of "
                             f"{image.name})") from None
    i = out["image"]
    typer.echo(f"floor {floor} of mission {mission}: {i['width_px']} x {i['height_px']} px, "
               f"{i['width_px'] * i['m_per_px']:.1f} x {i['height_px'] * i['m_per_px']:.1f} m "
               f"from ({i['origin_x_m']:g}, {i['origin_y_m']:g}) m")


@mission_app.command("export")
@reports_errors
def mission_export(
    mission: Annotated[int, typer.Argument(help="Mission id.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Folder to write.")],
    db: Annotated[str, typer.Option("--db", help="The service's database (as for serve).")
                  ] = DEFAULT_DB,
) -> None:
    """Write one session folder per agent (readable by `hrtls track`) plus mission.json."""
    from hrtls.service.missions import export_mission
    from hrtls.service.settings import Settings

    written = export_mission(Settings(db=db).db_url, mission, output)
    for folder in written:
        typer.echo(f"wrote {folder}")
    typer.echo(f"wrote {output / 'mission.json'}")


@mission_app.command("track")
@reports_errors
def mission_track(
    mission_dir: Annotated[Path, typer.Argument(help="Mission folder (mission.json, the "
                                                "agents' sessions, network.json).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Result folder to write.")],
    cooperate: Annotated[bool, typer.Option(
        "--cooperate/--no-cooperate", help="Give localized nodes to the agents as range "
        "anchors (--no-cooperate: every agent alone).")] = True,
    chunk_s: Annotated[float, typer.Option("--chunk-s", help="Common time window of the "
                                           "agents, s.")] = 5.0,
    config: Annotated[Path | None, typer.Option("--config", "-c",
                                                help="Tracker configuration (TOML).")] = None,
    preset_name: Annotated[str | None, typer.Option(
        "--preset", "-p", help="Tracker preset of every agent (default: default).")] = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also write each agent's track.png."
                                       )] = False,
    repair: Annotated[bool, typer.Option("--repair", help="Repair bad rows of the agents' "
                                         "sessions (warns).")] = False,
    overwrite: Annotated[bool, typer.Option(help="Replace existing results.")] = False,
    smoother: Annotated[str | None, typer.Option(
        "--smoother", help="Range-SLAM smoother of the agents' paths and the nodes: off, nodes "
        "(it localizes the nodes) or feedback (it also corrects the rescuers); the run's "
        "line and report.json say which ran (default: the library's).")] = None,
) -> None:
    """Track a mission folder offline: every agent's track, the dropped nodes, report.json."""
    import dataclasses

    from rich.console import Console

    from hrtls.cli.config import chosen_config
    from hrtls.errors import InputError
    from hrtls.io.mission import read_mission
    from hrtls.jobs.mission import (
        check_mission_output,
        mission_summary,
        track_mission,
        write_mission_outputs,
    )
    from hrtls.jobs.warmup import mark_compiled
    from hrtls.mission.smoother_modes import MODES, smoother_params
    from hrtls.mission.tracker import MissionParams

    cfg = chosen_config(config, preset_name, command="hrtls mission track")
    if smoother is not None and smoother not in MODES:
        raise InputError(f"{smoother}", where="--smoother", expected=" or ".join(MODES))
    if not math.isfinite(chunk_s) or chunk_s <= 0:
        raise InputError(f"{chunk_s}", where="--chunk-s", expected="a window > 0 s")
    folder = read_mission(mission_dir, repair=repair)
    check_mission_output(list(folder.agents), output, overwrite=overwrite)
    console = Console(highlight=False)
    with console.status("tracking the mission"):
        prm = MissionParams(cooperate=cooperate, chunk_s=chunk_s)
        if smoother is not None:
            prm = dataclasses.replace(prm, smoother=smoother_params(smoother))
        run = track_mission(folder, config=cfg, params=prm)
    write_mission_outputs(run, output, overwrite=overwrite, plot=plot)
    summary = mission_summary(run)
    console.print(f"[bold]{run.folder.name or mission_dir}[/bold]: {len(run.agents)} agents, "
                  f"cooperation {'on' if cooperate else 'off'}, smoother "
                  f"{summary['params']['smoother']}, {run.tracker_s:.2f} s")
    Console(highlight=False, width=max(console.width, 120)).print(_agents_table(summary))
    console.print(_nodes_line(summary))
    console.print(f"wrote {output}")
    mark_compiled()


def _m(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _agents_table(summary: dict[str, Any]) -> Any:
    """Per-agent figures of a mission summary (errors only for agents with ground truth)."""
    from rich.table import Table

    table = Table("agent", "kind", "steps", "walked m", "range fixes", "nodes ranged",
                  "position mean m", "p90 m", "max m", "checkpoint mean m", "checkpoint max m")
    for name, a in summary["agents"].items():
        ev = a["evaluation"] or {}
        pos, cp = ev.get("position") or {}, ev.get("checkpoints") or {}
        table.add_row(name, a["kind"], str(a["steps"]), f"{a['distance_walked_m']:.1f}",
                      str(a["range_corrections"].get("accepted", 0)),
                      str(len(a["contributed_to"])), _m(pos.get("mean")), _m(pos.get("p90")),
                      _m(pos.get("max")), _m(cp.get("mean")), _m(cp.get("max")))
    return table


def _nodes_line(summary: dict[str, Any]) -> str:
    n = summary["nodes"]
    text = (f"nodes: {n['localized']} localized of {summary['mission']['nodes_listed']} listed "
            f"({n['heard']} heard)")
    score = n["score"]
    if score is not None:
        text += (f"; against network_truth.json: {score['localized']} of {score['nodes']}, "
                 f"RMSE {_m(score['rmse_m'])} m, max {_m(score['max_m'])} m, "
                 f"mean NEES {_m(score['nees_mean'])} (2 expected)")
    return text
