"""The sensor-network studies of the thesis (Sec. 6.4), as reproducible simulations.

* :func:`loose_study` - Fig. 6.11 setting: ``n`` random nodes in the unit square, ``rho = 0.2``,
  three seeds in the lower-left corner; localized fraction of TLA, SELA and SELA with the Safe
  Navigation planner (a perfectly tracked rescuer), number of way points; every connected network
  must end fully localized.
* :func:`tight_study` - Fig. 6.13-6.17 setting: no anchors, a unicycle robot with the via-point
  controller and range EKF explores and runs Algorithm 1; results per connectivity class
  (connected, disconnected but connected at the robot's radio range ``d_r = 2 rho`` - the case of
  Theorem 2 - and the rest); position RMSE before and after refinement.
* :func:`noise_study` - ranges with relative noise (2 %): SELA (+ planner) with noise-aware
  tolerances, then least-squares refinement; RMSE as a fraction of ``rho`` and the number of nodes
  more than ``rho / 2`` from the truth before and after refinement (gross errors: accumulated
  drift along chains from the small seed triangle, or flips).

Each study returns a frozen dataclass of rows; :func:`format_table` renders rows as text.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.parallel import Engine, LocalEngine, values_or_raise
from hrtls.wsn.agents import (
    RangeWorld,
    RescuerAgent,
    RescuerParams,
    RobotAgent,
    RobotParams,
)
from hrtls.wsn.network import (
    Network,
    connected_components,
    corner_seed_network,
    random_network,
)
from hrtls.wsn.planner import PlannerParams, safe_navigation
from hrtls.wsn.refine import RefineParams, refine_network
from hrtls.wsn.shadow_edge import shadow_edge_localize
from hrtls.wsn.tight import TightParams, tight_cooperation
from hrtls.wsn.trilateration import PropagationParams, trilaterate_network


def _seeds(seed: int, count: int) -> list[np.random.SeedSequence]:
    """One independent seed per network (the same wherever the network is simulated)."""
    return list(np.random.SeedSequence(seed).spawn(count))


def _run(engine: Engine | None, fn: Any, tasks: list[Any], where: str) -> list[Any]:
    return values_or_raise((engine or LocalEngine()).map(fn, tasks), where=where)


def _groups(records: Sequence[tuple[Any, ...]], *, names: Sequence[str],
            key: Callable[[tuple[Any, ...]], str]) -> list[tuple[str, int, np.ndarray]]:
    """``(name, networks, numbers)`` of each non-empty group of the per-network records.

    Group ``"all"`` holds every record, group ``name`` those with ``key(record) == name``;
    ``numbers`` stacks the fields after the first (the class), one row per network.
    """
    out = []
    for name in ("all", *names):
        g = [r for r in records if name == "all" or key(r) == name]
        if g:
            out.append((name, len(g), np.array([r[1:] for r in g], dtype=float)))
    return out


def _max_error(net: Network, est: np.ndarray, mask: np.ndarray) -> float:
    if not mask.any():
        return 0.0
    return float(np.max(np.linalg.norm(est[mask] - net.position_m[mask], axis=1)))


# ------------------------------------------------------------------------------------------
_LooseRecord = tuple[bool, float, float, float, bool, int, float, float, float, float]


@dataclass(frozen=True, kw_only=True)
class _LooseTask:
    seed: np.random.SeedSequence
    n_nodes: int
    radius_m: float
    planner: PlannerParams | None
    rescuer: RescuerParams | None
    prop_params: PropagationParams | None


def _loose_one(task: _LooseTask) -> tuple[_LooseRecord, dict[str, int]]:
    """One network of the loose-cooperation study: its record and way-point kinds."""
    rng = np.random.default_rng(task.seed)
    n_nodes, radius_m = task.n_nodes, task.radius_m
    net = corner_seed_network(rng, n_nodes=n_nodes, radius_m=radius_m)
    tla = trilaterate_network(net)
    sela = shadow_edge_localize(net)
    world = RangeWorld(true_positions_m=net.position_m, link_radius_m=radius_m,
                       radio_range_m=radius_m)
    agent = RescuerAgent(world, net.position_m[0], params=task.rescuer or RescuerParams(),
                         rng=rng)
    nav = safe_navigation(net, agent, params=task.planner, prop_params=task.prop_params)
    kinds: dict[str, int] = {}
    for w in nav.waypoints:
        kinds[w.kind] = kinds.get(w.kind, 0) + 1
    connected = bool(connected_components(net).max() == 0)
    loc = nav.localization
    err = max(_max_error(net, r.estimate_m, r.localized) for r in (tla, sela, loc))
    mm = loc.localized & ~net.anchor
    sq = float(np.sum((loc.estimate_m[mm] - net.position_m[mm]) ** 2))
    return ((connected, tla.n_localized / n_nodes, sela.n_localized / n_nodes,
             loc.n_localized / n_nodes, nav.complete, len(nav.waypoints), nav.distance_m,
             err / radius_m, sq, float(mm.sum())), kinds)


@dataclass(frozen=True)
class LooseRow:
    """One group of networks of the loose-cooperation study (fractions of all nodes)."""

    group: str
    networks: int
    tla: float
    sela: float
    sela_planner: float
    complete: float
    waypoints_mean: float
    waypoints_median: float
    waypoints_max: int
    distance_mean_m: float
    rmse_over_rho: float
    max_error_over_rho: float


@dataclass(frozen=True)
class LooseStudy:
    """Result of :func:`loose_study`."""

    rows: tuple[LooseRow, ...]
    waypoint_kinds: dict[str, int]
    n_nodes: int
    radius_m: float


def loose_study(
    *,
    n_networks: int = 1000,
    n_nodes: int = 50,
    radius_m: float = 0.2,
    seed: int = 0,
    planner: PlannerParams | None = None,
    rescuer: RescuerParams | None = None,
    prop_params: PropagationParams | None = None,
    engine: Engine | None = None,
) -> LooseStudy:
    """Fig. 6.11 study: TLA vs SELA vs SELA + planner over random corner-seed networks.

    The default rescuer is perfectly tracked (the thesis' setting); pass ``rescuer`` with
    dead-reckoning noise to see how the agent's tracking error enters the node positions.
    ``engine`` spreads the networks over processes or a cluster (same numbers as one process).
    """
    if n_networks < 1:
        raise InputError(f"{n_networks} networks", where="loose_study", expected=">= 1")
    tasks = [_LooseTask(seed=sq, n_nodes=n_nodes, radius_m=radius_m, planner=planner,
                        rescuer=rescuer, prop_params=prop_params)
             for sq in _seeds(seed, n_networks)]
    results = _run(engine, _loose_one, tasks, "loose_study")
    rec = [r[0] for r in results]
    kinds: dict[str, int] = {}
    for _, k in results:
        for name, count in k.items():
            kinds[name] = kinds.get(name, 0) + count
    rows = []
    for name, networks, a in _groups(
            rec, names=("connected", "disconnected"),
            key=lambda r: "connected" if r[0] else "disconnected"):
        rows.append(LooseRow(
            group=name, networks=networks, tla=float(a[:, 0].mean()), sela=float(a[:, 1].mean()),
            sela_planner=float(a[:, 2].mean()), complete=float(a[:, 3].mean()),
            waypoints_mean=float(a[:, 4].mean()), waypoints_median=float(np.median(a[:, 4])),
            waypoints_max=int(a[:, 4].max()), distance_mean_m=float(a[:, 5].mean()),
            rmse_over_rho=float(np.sqrt(a[:, 7].sum() / max(a[:, 8].sum(), 1.0))) / radius_m,
            max_error_over_rho=float(a[:, 6].max()),
        ))
    return LooseStudy(rows=tuple(rows), waypoint_kinds=kinds, n_nodes=n_nodes,
                      radius_m=radius_m)


# ------------------------------------------------------------------------------------------
_TightRecord = tuple[str, float, bool, int, int, float, float, float, float]


@dataclass(frozen=True, kw_only=True)
class _TightTask:
    seed: np.random.SeedSequence
    index: int
    base_seed: int
    n_nodes: int
    radius_m: float
    side_m: float
    delta_m: float
    range_noise_fraction: float
    robot: RobotParams


def _tight_one(task: _TightTask) -> _TightRecord:
    """One network of the tight-cooperation study."""
    rng = np.random.default_rng(task.seed)
    n_nodes, radius_m, side_m = task.n_nodes, task.radius_m, task.side_m
    delta, noise = task.delta_m, task.range_noise_fraction
    d_r = 2.0 * radius_m
    net = random_network(rng, n_nodes=n_nodes, radius_m=radius_m, width_m=side_m,
                         height_m=side_m, anchors="none", range_noise_fraction=noise)
    if connected_components(net).max() == 0:
        group = "connected"
    elif connected_components(net, radius_m=d_r).max() == 0:
        group = "disconnected, d_r-connected"
    else:
        group = "disconnected beyond d_r"
    world = RangeWorld(true_positions_m=net.position_m, link_radius_m=radius_m,
                       radio_range_m=d_r, range_noise_fraction=noise, rng=rng)
    agent = RobotAgent(world, np.zeros(3), params=task.robot,
                       seed=task.base_seed * 7919 + task.index)
    res = tight_cooperation(net, agent, params=TightParams(
        delta_m=delta, radio_range_m=d_r, search_region_m=(0.0, 0.0, side_m, side_m),
        range_noise_fraction=noise))
    loc = res.localization
    m = loc.localized
    err = np.linalg.norm(loc.estimate_m[m] - net.position_m[m], axis=1)
    prior = np.full(n_nodes, np.inf)
    prior[res.assigned] = delta
    ref = refine_network(net, loc, prior_sigma_m=prior, params=RefineParams(
        range_sigma_fraction=max(noise, 0.002), covariance=False))
    err_r = np.linalg.norm(ref.estimate_m[m] - net.position_m[m], axis=1)
    return (group, loc.n_localized / n_nodes, res.complete, len(res.assigned), res.legs,
            res.distance_m, float(np.sum(err**2)), float(np.sum(err_r**2)),
            float(err.max(initial=0.0)))


@dataclass(frozen=True)
class TightRow:
    """One connectivity class of the tight-cooperation study."""

    group: str
    networks: int
    localized: float
    complete: float
    assigned_mean: float
    legs_mean: float
    distance_mean_m: float
    rmse_over_rho: float
    rmse_refined_over_rho: float
    max_error_over_rho: float


@dataclass(frozen=True)
class TightStudy:
    """Result of :func:`tight_study`."""

    rows: tuple[TightRow, ...]
    n_nodes: int
    radius_m: float
    delta_m: float


def tight_study(
    *,
    n_networks: int = 1000,
    n_nodes: int = 50,
    radius_m: float = 0.2,
    side_m: float = 1.0,
    delta_fraction: float = 0.05,
    range_noise_fraction: float = 0.0,
    robot: RobotParams | None = None,
    seed: int = 1,
    engine: Engine | None = None,
) -> TightStudy:
    """Fig. 6.13-6.17 study: anchor-free random networks localized by a robot (Algorithm 1).

    Nodes are uniform in a ``side_m`` square; the robot starts at the origin heading east,
    hears nodes within ``d_r = 2 rho`` and assigns its position to a node heard within
    ``Delta = delta_fraction * rho``.
    """
    if n_networks < 1:
        raise InputError(f"{n_networks} networks", where="tight_study", expected=">= 1")
    delta = delta_fraction * radius_m
    rp = robot or RobotParams(arrival_radius_m=0.2 * delta,
                              range_noise_fraction=range_noise_fraction)
    tasks = [_TightTask(seed=sq, index=k, base_seed=seed, n_nodes=n_nodes, radius_m=radius_m,
                        side_m=side_m, delta_m=delta, range_noise_fraction=range_noise_fraction,
                        robot=rp)
             for k, sq in enumerate(_seeds(seed, n_networks))]
    rec = _run(engine, _tight_one, tasks, "tight_study")
    rows = []
    classes = ("connected", "disconnected, d_r-connected", "disconnected beyond d_r")
    for name, networks, a in _groups(rec, names=classes, key=lambda r: r[0]):
        nloc = float(np.sum(a[:, 0]) * n_nodes)
        rows.append(TightRow(
            group=name, networks=networks, localized=float(a[:, 0].mean()),
            complete=float(a[:, 1].mean()), assigned_mean=float(a[:, 2].mean()),
            legs_mean=float(a[:, 3].mean()), distance_mean_m=float(a[:, 4].mean()),
            rmse_over_rho=float(np.sqrt(np.sum(a[:, 5]) / max(nloc, 1.0))) / radius_m,
            rmse_refined_over_rho=float(np.sqrt(np.sum(a[:, 6]) / max(nloc, 1.0))) / radius_m,
            max_error_over_rho=float(a[:, 7].max()) / radius_m,
        ))
    return TightStudy(rows=tuple(rows), n_nodes=n_nodes, radius_m=radius_m, delta_m=delta)


# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class _NoiseTask:
    seed: np.random.SeedSequence
    n_nodes: int
    radius_m: float
    noise_fraction: float
    planner: bool
    prop_params: PropagationParams


@dataclass(frozen=True, kw_only=True)
class _NoiseRecord:
    flagged: int
    n_localized: int = 0
    sq_before: float = 0.0
    sq_after: float = 0.0
    gross_before: int = 0
    gross_after: int = 0
    refined_over_rho: tuple[float, ...] = ()
    nees: tuple[float, ...] = ()


def _noise_one(task: _NoiseTask) -> _NoiseRecord:
    """One network of the range-noise study."""
    rng = np.random.default_rng(task.seed)
    rho, noise, pp = task.radius_m, task.noise_fraction, task.prop_params
    net = corner_seed_network(rng, n_nodes=task.n_nodes, radius_m=rho,
                              range_noise_fraction=noise)
    if task.planner:
        world = RangeWorld(true_positions_m=net.position_m, link_radius_m=rho,
                           radio_range_m=rho, range_noise_fraction=noise, rng=rng)
        agent = RescuerAgent(world, net.position_m[0], params=RescuerParams(), rng=rng)
        nav = safe_navigation(net, agent, prop_params=pp)
        loc = nav.localization
        temps, links = nav.temp_positions_m, nav.temp_links
    else:
        loc = shadow_edge_localize(net, params=pp)
        temps, links = np.zeros((0, 2)), ()
    m = loc.localized & ~net.anchor
    flagged = int(loc.inconsistent().size)
    if not m.any():
        return _NoiseRecord(flagged=flagged)
    e0 = np.linalg.norm(loc.estimate_m[m] - net.position_m[m], axis=1)
    ref = refine_network(net, loc, params=RefineParams(range_sigma_fraction=noise),
                         agent_positions_m=temps, agent_links=links)
    d1 = ref.estimate_m[m] - net.position_m[m]
    e1 = np.linalg.norm(d1, axis=1)
    cov = ref.covariance_m2[m]
    ok = np.linalg.det(cov) > 0
    nees: tuple[float, ...] = ()
    if ok.any():
        nees = tuple(np.einsum("ni,nij,nj->n", d1[ok], np.linalg.inv(cov[ok]), d1[ok]).tolist())
    return _NoiseRecord(flagged=flagged, n_localized=int(m.sum()),
                        sq_before=float(np.sum(e0**2)), sq_after=float(np.sum(e1**2)),
                        gross_before=int(np.sum(e0 > 0.5 * rho)),
                        gross_after=int(np.sum(e1 > 0.5 * rho)),
                        refined_over_rho=tuple((e1 / rho).tolist()), nees=nees)


@dataclass(frozen=True)
class NoiseRow:
    """One configuration of the range-noise study."""

    setting: str
    networks: int
    localized: float
    inconsistent_flagged: float
    gross_before: int
    gross_after: int
    rmse_over_rho: float
    rmse_refined_over_rho: float
    median_refined_over_rho: float
    nees: float


@dataclass(frozen=True)
class NoiseStudy:
    """Result of :func:`noise_study`."""

    rows: tuple[NoiseRow, ...]
    noise_fraction: float


def noise_study(
    *,
    n_networks: int = 300,
    noise_fraction: float = 0.02,
    seed: int = 2,
    max_gdops: Sequence[float] = (2.0, 2.5, 3.0),
    with_planner: bool = True,
    engine: Engine | None = None,
) -> NoiseStudy:
    """Ranges with relative noise: localized fraction, flips and RMSE before/after refinement.

    Settings: SELA on 100 nodes (``rho = 0.25``) for each ``max_gdop``, and, with
    ``with_planner``, SELA + planner on the Fig. 6.11 networks (50 nodes, ``rho = 0.2``).
    ``nees`` is the median normalized estimation error squared of the refined nodes (about
    1.39 for a well-calibrated 2-D covariance).
    """
    rows = []
    configs: list[tuple[str, int, float, float, bool]] = [
        (f"SELA 100 nodes rho=0.25 gdop<={g:g}", 100, 0.25, g, False) for g in max_gdops
    ]
    if with_planner:
        configs.append(("SELA+planner 50 nodes rho=0.2 gdop<=2.5", 50, 0.2, 2.5, True))
    for name, n_nodes, rho, gdop, plan in configs:
        pp = dataclasses.replace(PropagationParams.for_noise(noise_fraction), max_gdop=gdop)
        tasks = [_NoiseTask(seed=sq, n_nodes=n_nodes, radius_m=rho,
                            noise_fraction=noise_fraction, planner=plan, prop_params=pp)
                 for sq in _seeds(seed, n_networks)]
        parts = _run(engine, _noise_one, tasks, "noise_study")
        sq0 = sum(p.sq_before for p in parts)
        sq1 = sum(p.sq_after for p in parts)
        med = [v for p in parts for v in p.refined_over_rho]
        nees = [v for p in parts for v in p.nees]
        nloc = sum(p.n_localized for p in parts)
        flagged = sum(p.flagged for p in parts)
        gross0 = sum(p.gross_before for p in parts)
        gross1 = sum(p.gross_after for p in parts)
        rows.append(NoiseRow(
            setting=name, networks=n_networks,
            localized=nloc / (n_networks * (n_nodes - 3)),
            inconsistent_flagged=flagged / n_networks, gross_before=gross0, gross_after=gross1,
            rmse_over_rho=float(np.sqrt(sq0 / max(nloc, 1))) / rho,
            rmse_refined_over_rho=float(np.sqrt(sq1 / max(nloc, 1))) / rho,
            median_refined_over_rho=float(np.median(med)) if med else 0.0,
            nees=float(np.median(nees)) if nees else 0.0,
        ))
    return NoiseStudy(rows=tuple(rows), noise_fraction=noise_fraction)


# ------------------------------------------------------------------------------------------
def format_table(rows: Sequence[Any], *, digits: int = 3) -> str:
    """Plain-text table of dataclass rows (one column per field)."""
    if not rows:
        return "(no rows)"
    names = [f.name for f in dataclasses.fields(rows[0])]

    def cell(v: Any) -> str:
        if isinstance(v, float):
            if v != 0.0 and abs(v) < 10.0 ** (-digits):
                return f"{v:.1e}"
            return f"{v:.{digits}f}"
        return str(v)

    table = [names] + [[cell(getattr(r, n)) for n in names] for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(names))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in table]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
