"""Sensor-network commands: ``hrtls wsn simulate | localize | plan | experiment``.

Register in :mod:`hrtls.cli.app` with::

    from hrtls.cli import wsn as wsn_cli
    app.add_typer(wsn_cli.app, name="wsn")

Network files use the JSON form documented in :mod:`hrtls.wsn.network`. An agent path for
``localize --agent`` is a CSV with the header ``t,x,y`` (s, m, m): every row is a place where the
agent stood and measured ranges (a temporary node). Its ranges come from ``--ranges`` (the session
format ``t,node,range[,sigma]`` with ``node`` a node id and ``t`` equal to a path row's time), or,
without that file, are simulated from the nodes' ground-truth ``position`` (all nodes need one).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer

from hrtls.cli.errors import reports_errors
from hrtls.errors import FormatError, InputError

if TYPE_CHECKING:
    from hrtls.parallel import Engine

app = typer.Typer(no_args_is_help=True,
                  help="Sensor-network self-localization with mobile agents (Inderst Ch. 5-6).")


def _plot(path: Path | None, *args: Any, **kwargs: Any) -> None:
    if path is None:
        return
    from hrtls.wsn.plotting import plot_network, save_figure

    save_figure(plot_network(*args, **kwargs), path)
    typer.echo(f"plot written to {path}")


def _read_csv(path: Path, required: list[str]) -> list[dict[str, str]]:
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
            header = [h.strip() for h in (rows[0].keys() if rows else [])]
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", where=str(path),
                         expected="a readable CSV file") from exc
    if not rows:
        raise FormatError("no data rows", where=str(path),
                          expected=f"a header {','.join(required)} and rows")
    missing = [c for c in required if c not in header]
    if missing:
        raise FormatError(f"missing columns {missing}", where=f"{path} line 1",
                          expected=",".join(required))
    return [{k.strip(): (v or "").strip() for k, v in r.items() if k is not None} for r in rows]


def _float(value: str, where: str, what: str) -> float:
    try:
        v = float(value)
    except ValueError:
        raise FormatError(f"{what} is {value!r}", where=where, expected="a number") from None
    if not np.isfinite(v):
        raise FormatError(f"{what} is {value!r}", where=where, expected="a finite number")
    return v


def read_agent_path(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times ``(k,)`` and positions ``(k, 2)`` of an agent path CSV (``t,x,y``)."""
    rows = _read_csv(path, ["t", "x", "y"])
    t = np.array([_float(r["t"], f"{path} line {i + 2}", "t") for i, r in enumerate(rows)])
    xy = np.array([[_float(r["x"], f"{path} line {i + 2}", "x"),
                    _float(r["y"], f"{path} line {i + 2}", "y")] for i, r in enumerate(rows)])
    return t, xy


def _agent_links(net: Any, t: np.ndarray, xy: np.ndarray,
                 ranges: Path | None) -> list[tuple[int, int, float]]:
    links: list[tuple[int, int, float]] = []
    if ranges is None:
        if not np.all(net.has_position):
            k = int(np.flatnonzero(~net.has_position)[0])
            raise InputError("node has no ground-truth position to simulate agent ranges",
                             where=f"node '{net.ids[k]}'",
                             expected="'position' for every node, or a --ranges file")
        for w in range(xy.shape[0]):
            d = np.linalg.norm(net.position_m - xy[w], axis=1)
            links.extend((w, int(k), float(d[k])) for k in np.flatnonzero(d <= net.radius_m))
        return links
    rows = _read_csv(ranges, ["t", "node", "range"])
    row_of = {float(v): i for i, v in enumerate(t)}
    for i, r in enumerate(rows):
        where = f"{ranges} line {i + 2}"
        tt = _float(r["t"], where, "t")
        if tt not in row_of:
            raise FormatError(f"time {tt} is not a row of the agent path", where=where,
                              expected="t equal to a t of the --agent file")
        if r["node"] not in net.index:
            raise FormatError(f"unknown node {r['node']!r}", where=where,
                              expected="a node id of the network")
        rr = _float(r["range"], where, "range")
        if rr < 0:
            raise FormatError(f"range {rr}", where=where, expected=">= 0 m")
        links.append((row_of[tt], net.index[r["node"]], rr))
    return links


@app.command("simulate")
@reports_errors
def simulate(
    output: Annotated[Path, typer.Option("-o", "--output", help="Network JSON to write.")],
    nodes: Annotated[int, typer.Option(help="Number of nodes.")] = 50,
    radius: Annotated[float, typer.Option(help="Communication radius rho, m.")] = 0.2,
    width: Annotated[float, typer.Option(help="Deployment width, m.")] = 1.0,
    height: Annotated[float, typer.Option(help="Deployment height, m.")] = 1.0,
    anchors: Annotated[str, typer.Option(help="'corner' (3 seeds) or 'none'.")] = "corner",
    noise: Annotated[float, typer.Option(help="Relative range noise (0.02 = 2 %).")] = 0.0,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    plot: Annotated[Path | None, typer.Option(help="PNG plot of the network.")] = None,
) -> None:
    """Random deployment (disk graph, k-d tree) written as network JSON with ground truth."""
    from hrtls.wsn.network import random_network, save_network

    net = random_network(np.random.default_rng(seed), n_nodes=nodes, radius_m=radius,
                         width_m=width, height_m=height, anchors=anchors,
                         range_noise_fraction=noise)
    save_network(output, net)
    typer.echo(f"{net.n_nodes} nodes, {net.edges.shape[0]} links, "
               f"{int(net.anchor.sum())} anchors -> {output}")
    _plot(plot, net, title=f"{nodes} nodes, rho = {radius:g} m")


def _ids(net: Any, idx: np.ndarray, limit: int = 12) -> str:
    names = [net.ids[int(i)] for i in idx[:limit]]
    return ", ".join(names) + (f" and {idx.size - limit} more" if idx.size > limit else "")


def _explain_unlocalized(net: Any, loc: Any, network: Path, *, with_agent: bool) -> None:
    """Say why nodes stayed unlocalized and which command localizes them."""
    from hrtls.wsn.diagnostics import unlocalized_reasons

    why = unlocalized_reasons(net, loc)
    if why.n_unlocalized == 0:
        return
    typer.echo(f"{why.n_unlocalized} nodes unlocalized:")
    if why.under_covered.size:
        typer.echo(f"  {why.under_covered.size} have fewer than three localized neighbours "
                   f"(propagation needs three ranges, or two and a shadow edge): "
                   f"{_ids(net, why.under_covered)}")
    if why.inconsistent.size:
        typer.echo(f"  {why.inconsistent.size} had ranges that fit no candidate position and were "
                   f"left out (check --noise): {_ids(net, why.inconsistent)}")
    if why.unreachable.size:
        typer.echo(f"  {why.unreachable.size} have no chain of links to a localized node: "
                   f"{_ids(net, why.unreachable)}")
    if why.under_covered.size and not with_agent:
        typer.echo(f"next: a mobile agent adds the missing ranges: `hrtls wsn plan {network} "
                   "--simulate` (simulated rescuer and planner), or a measured walk with "
                   "`--agent PATH.csv --ranges RANGES.csv`")
    if why.unreachable.size:
        typer.echo("next: parts without links to the localized part are reached by an agent "
                   "passing within radio range, or by a robot that searches beyond the links "
                   "(tight cooperation, `hrtls wsn experiment --study tight`)")


@app.command("localize")
@reports_errors
def localize(
    network: Annotated[Path, typer.Argument(help="Network JSON.")],
    output: Annotated[Path | None, typer.Option("-o", "--output",
                                                help="Network JSON with estimates.")] = None,
    method: Annotated[str, typer.Option(help="'tla' or 'sela'.")] = "sela",
    agent: Annotated[Path | None, typer.Option(help="Agent path CSV t,x,y (temporary nodes).")]
    = None,
    ranges: Annotated[Path | None, typer.Option(help="Agent ranges CSV t,node,range.")] = None,
    noise: Annotated[float, typer.Option(help="Relative range noise to tolerate.")] = 0.0,
    refine: Annotated[bool, typer.Option(help="Least-squares refinement + covariance.")] = False,
    plot: Annotated[Path | None, typer.Option(help="PNG plot.")] = None,
) -> None:
    """Localize a network from its anchors by TLA or SELA (optionally with agent ranges)."""
    from hrtls.wsn.network import METHOD_NAMES, load_network, save_network
    from hrtls.wsn.planner import AugmentedFramework
    from hrtls.wsn.refine import RefineParams, refine_network
    from hrtls.wsn.trilateration import PropagationParams, propagate, seeds_of

    if method not in ("tla", "sela"):
        raise InputError(f"method {method!r}", where="--method", expected="'tla' or 'sela'")
    if noise < 0 or noise >= 0.5:
        raise InputError(f"noise {noise}", where="--noise", expected="a fraction in [0, 0.5)")
    net = load_network(network)
    pp = PropagationParams.for_noise(noise)
    links: list[tuple[int, int, float]] = []
    xy = np.zeros((0, 2))
    if agent is not None:
        t, xy = read_agent_path(agent)
        links = _agent_links(net, t, xy, ranges)
        aug = AugmentedFramework(net, temp_m=list(xy), temp_links=links)
        if method == "sela":
            loc_all = aug.localize(pp)
        else:
            pos = np.vstack([seeds_of(net)[0], xy])
            mask = np.concatenate([net.anchor, np.ones(xy.shape[0], dtype=bool)])
            loc_all = propagate(aug.n_total, aug.adjacency(), net.radius_m, positions_m=pos,
                                localized=mask, use_shadow=False, params=pp)
        from hrtls.wsn.planner import real_nodes

        loc = real_nodes(loc_all, net.n_nodes)
    else:
        pos, mask = seeds_of(net)
        loc = propagate(net.n_nodes, net.adjacency, net.radius_m, positions_m=pos,
                        localized=mask, use_shadow=method == "sela", params=pp)
        loc_all = loc
    est = loc.estimate_m
    cov = None
    if refine:
        if not net.anchor.any() and agent is None:
            raise InputError("refinement needs anchors or agent ranges", where="--refine",
                             expected="a network with anchors")
        r = refine_network(net, loc, params=RefineParams(range_sigma_fraction=max(noise, 1e-3)),
                           agent_positions_m=xy, agent_links=links)
        est = np.where(loc.localized[:, None], r.estimate_m, est)
        cov = r.covariance_m2
    names = [METHOD_NAMES[int(m)] for m in loc.method]
    counts = {k: names.count(k) for k in METHOD_NAMES}
    typer.echo(f"{loc.n_localized}/{net.n_nodes} localized: "
               + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    _explain_unlocalized(net, loc, network, with_agent=agent is not None)
    if net.has_position.any():
        m = loc.localized & net.has_position & ~net.anchor
        if m.any():
            e = np.linalg.norm(est[m] - net.position_m[m], axis=1)
            typer.echo(f"error vs ground truth: rmse {np.sqrt(np.mean(e**2)):.4g} m, "
                       f"max {e.max():.4g} m ({int(m.sum())} nodes)")
    if output is not None:
        save_network(output, net, estimate_m=est, method=names, covariance_m2=cov)
        typer.echo(f"written {output}")
    _plot(plot, net, loc_all if agent is not None else loc, title=f"{method.upper()}",
          waypoints_m=xy if agent is not None else None, agent_links=links or None,
          covariance_m2=cov)


@app.command("plan")
@reports_errors
def plan(
    network: Annotated[Path, typer.Argument(help="Network JSON with anchors.")],
    output: Annotated[Path | None, typer.Option("-o", "--output", help="Way points CSV.")]
    = None,
    simulate_walk: Annotated[bool, typer.Option(
        "--simulate/--no-simulate",
        help="Run the full Safe Navigation loop with a simulated rescuer (needs ground truth).",
    )] = False,
    network_output: Annotated[Path | None, typer.Option(
        help="With --simulate: network JSON with the final estimates.")] = None,
    noise: Annotated[float, typer.Option(help="Relative range noise to tolerate.")] = 0.0,
    plot: Annotated[Path | None, typer.Option(help="PNG plot.")] = None,
) -> None:
    """Way points of the loose-cooperation planner (thesis Sec. 5.3)."""
    from hrtls.wsn.agents import RangeWorld, RescuerAgent, RescuerParams
    from hrtls.wsn.network import load_network, save_network
    from hrtls.wsn.planner import AugmentedFramework, plan_waypoints, safe_navigation
    from hrtls.wsn.trilateration import PropagationParams

    if noise < 0 or noise >= 0.5:
        raise InputError(f"noise {noise}", where="--noise", expected="a fraction in [0, 0.5)")
    pp = PropagationParams.for_noise(noise)
    net = load_network(network)
    if not net.anchor.any():
        raise InputError("no anchors", where=str(network),
                         expected="anchors (loose cooperation starts from seeds)")
    if simulate_walk:
        if not np.all(net.has_position):
            raise InputError("--simulate needs ground truth", where=str(network),
                             expected="'position' for every node")
        world = RangeWorld(true_positions_m=net.position_m, link_radius_m=net.radius_m,
                           radio_range_m=net.radius_m)
        start = net.position_m[int(np.flatnonzero(net.anchor)[0])]
        nav = safe_navigation(net, RescuerAgent(world, start, params=RescuerParams(),
                                                rng=np.random.default_rng(0)), prop_params=pp)
        wps = list(nav.waypoints)
        loc = nav.augmented
        typer.echo(f"SELA alone: {nav.initial.n_localized}/{net.n_nodes}; with {len(wps)} way "
                   f"points: {nav.localization.n_localized}/{net.n_nodes} "
                   f"({'complete' if nav.complete else 'incomplete'}), "
                   f"walked {nav.distance_m:.3g} m")
        _explain_unlocalized(net, nav.localization, network, with_agent=True)
        if network_output is not None:
            save_network(network_output, net, estimate_m=nav.localization.estimate_m,
                         method=nav.localization.method_names)
        temps = nav.temp_positions_m
        links = list(nav.temp_links)
        path = nav.path_m
    else:
        aug = AugmentedFramework(net)
        loc = aug.localize(pp)
        wps = plan_waypoints(aug, loc, prop_params=pp)
        typer.echo(f"SELA: {int(loc.localized.sum())}/{net.n_nodes}; {len(wps)} way points "
                   "planned for this round")
        temps = np.array([w.position_m for w in wps]).reshape(-1, 2)
        links = []
        path = None
    for k, w in enumerate(wps):
        tg = " ".join(net.ids[t] for t in w.targets if t < net.n_nodes)
        typer.echo(f"{k:3d} {w.kind:9s} x={w.position_m[0]:.4f} y={w.position_m[1]:.4f} "
                   f"targets: {tg}")
    if output is not None:
        with output.open("w", encoding="utf-8") as fh:
            fh.write("index,x,y,kind,targets\n")
            for k, w in enumerate(wps):
                tg = " ".join(net.ids[t] for t in w.targets if t < net.n_nodes)
                fh.write(f"{k},{w.position_m[0]:.9g},{w.position_m[1]:.9g},{w.kind},{tg}\n")
        typer.echo(f"written {output}")
    _plot(plot, net, loc, title="Safe Navigation way points", waypoints_m=temps,
          agent_links=links or None, agent_path_m=path)


def _print_studies(study: str, *, networks: int, noise_networks: int, seed: int,
                   engine: Engine) -> None:
    """Run the chosen studies (seeds ``seed`` to ``seed + 3``) and print their tables."""
    from hrtls.wsn import experiment as ex

    if study in ("loose", "all"):
        s = ex.loose_study(n_networks=networks, seed=seed, engine=engine)
        typer.echo(f"\nLoose cooperation (Fig. 6.11): {s.n_nodes} nodes in the unit square, "
                   f"rho = {s.radius_m:g}, seeds in a corner, {networks} networks")
        typer.echo(ex.format_table(s.rows))
        typer.echo(f"way point kinds: {s.waypoint_kinds}")
    if study in ("tight", "all"):
        for n_nodes, side in ((50, 1.0), (10, 0.5), (15, 1.0)):
            t = ex.tight_study(n_networks=networks, n_nodes=n_nodes, side_m=side, seed=seed + 1,
                               engine=engine)
            typer.echo(f"\nTight cooperation with a robot (Fig. 6.13-6.17): {n_nodes} nodes in "
                       f"a {side:g} m square, rho = {t.radius_m:g}, d_r = 2 rho, "
                       f"Delta = {t.delta_m:g} m, {networks} networks")
            typer.echo(ex.format_table(t.rows))
    if study in ("noise", "all"):
        z = ex.noise_study(n_networks=noise_networks, seed=seed + 2, engine=engine)
        typer.echo(f"\nRange noise {100 * z.noise_fraction:g} % (refinement: least squares)")
        typer.echo(ex.format_table(z.rows))
        t = ex.tight_study(n_networks=noise_networks, range_noise_fraction=z.noise_fraction,
                           seed=seed + 3, engine=engine)
        typer.echo(f"\nTight cooperation with {100 * z.noise_fraction:g} % range noise "
                   f"(robot odometry exact), {noise_networks} networks")
        typer.echo(ex.format_table(t.rows))


def _plot_loose_example(path: Path, *, seed: int) -> None:
    """PNG of a random connected corner-seed network after the Safe Navigation planner."""
    from hrtls.wsn.agents import RangeWorld, RescuerAgent, RescuerParams
    from hrtls.wsn.network import connected_components, corner_seed_network
    from hrtls.wsn.planner import safe_navigation

    rng = np.random.default_rng(seed)
    while True:
        net = corner_seed_network(rng)
        if connected_components(net).max() == 0:
            break
    world = RangeWorld(true_positions_m=net.position_m, link_radius_m=net.radius_m,
                       radio_range_m=net.radius_m)
    nav = safe_navigation(net, RescuerAgent(world, net.position_m[0],
                                            params=RescuerParams(), rng=rng))
    _plot(path, net, nav.augmented, title=f"SELA + planner: {len(nav.waypoints)} way points",
          waypoints_m=nav.temp_positions_m, agent_links=list(nav.temp_links),
          agent_path_m=nav.path_m)


def _plot_tight_example(path: Path, *, seed: int) -> None:
    """PNG of a tight-cooperation run on a disconnected 12-node graph (Fig. 6.14)."""
    from hrtls.wsn.agents import RangeWorld, RobotAgent, RobotParams
    from hrtls.wsn.network import connected_components, random_network
    from hrtls.wsn.tight import TightParams, tight_cooperation

    rng = np.random.default_rng(seed)
    while True:  # a disconnected 12-node graph whose parts are within d_r (Fig. 6.14)
        net = random_network(rng, n_nodes=12, radius_m=0.2, width_m=0.6, height_m=0.6,
                             anchors="none")
        if connected_components(net).max() == 1 and connected_components(
                net, radius_m=0.4).max() == 0:
            break
    world = RangeWorld(true_positions_m=net.position_m, link_radius_m=0.2,
                       radio_range_m=0.4)
    robot = RobotAgent(world, np.zeros(3), params=RobotParams(arrival_radius_m=0.002))
    res = tight_cooperation(net, robot, params=TightParams(
        delta_m=0.01, radio_range_m=0.4, search_region_m=(0.0, 0.0, 0.6, 0.6)))
    _plot(path, net, res.localization, agent_path_m=res.path_m, labels=True,
          title=f"Tight cooperation: {len(res.assigned)} nodes assigned by the robot, "
                f"{res.legs} legs")


@app.command("experiment")
@reports_errors
def experiment(
    study: Annotated[str, typer.Option(help="'loose', 'tight', 'noise' or 'all'.")] = "all",
    networks: Annotated[int, typer.Option(help="Random networks per study.")] = 1000,
    noise_networks: Annotated[int, typer.Option(help="Networks of the noise study.")] = 200,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    plot: Annotated[Path | None, typer.Option(help="PNG of one example loose-cooperation "
                                                   "network after the planner.")] = None,
    tight_plot: Annotated[Path | None, typer.Option(
        help="PNG of one example tight-cooperation run (robot path, disconnected graph).")]
    = None,
    engine_name: Annotated[str, typer.Option(
        "--engine", help="Where the networks run: local | ray (same numbers either way).")]
    = "local",
    workers: Annotated[int | None, typer.Option(
        help="Networks simulated at once (default: all cores).")] = None,
    ray_address: Annotated[str | None, typer.Option(
        help="With --engine ray: cluster address (default: a local Ray).")] = None,
) -> None:
    """Run the thesis' studies (Fig. 6.11, 6.13-6.17, 2 % noise) and print tables."""
    from hrtls.runner import make_engine

    if study not in ("loose", "tight", "noise", "all"):
        raise InputError(f"study {study!r}", where="--study",
                         expected="loose, tight, noise or all")
    if networks < 1 or noise_networks < 1:
        raise InputError("network count < 1", where="--networks", expected=">= 1")
    engine = make_engine(engine_name, workers=workers, ray_address=ray_address)
    _print_studies(study, networks=networks, noise_networks=noise_networks, seed=seed,
                   engine=engine)
    if plot is not None:
        _plot_loose_example(plot, seed=seed)
    if tight_plot is not None:
        _plot_tight_example(tight_plot, seed=seed + 1)
