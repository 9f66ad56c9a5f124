"""A mission's sensor network: declare the dropped nodes, read the live node estimates."""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, HTTPException
from pydantic import Field
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from hrtls.errors import InputError
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.smoother_modes import MODES, smoother_mode
from hrtls.service.deps import Commander, DbDep, Reader, ServicesDep, mission_or_404
from hrtls.service.limits import retry_after_header
from hrtls.service.mission_runner import mission_params, network_nodes
from hrtls.service.models import MissionNetwork, MissionSnapshot, NetworkRangeBatch
from hrtls.service.network_log import pack
from hrtls.service.schemas import Strict

router = APIRouter(tags=["missions"])

LIVE_PARAMS = ("chunk_s", "pass_gap_s", "refresh_fraction", "cooperate", "loop_closure_ratio",
               "silent_after_s", "smoother")
"""Fields of :class:`~hrtls.mission.tracker.MissionParams` a mission may set."""


class NodeIn(Strict):
    """A dropped node: an id, no position."""

    id: str = Field(min_length=1, max_length=200)


class NetworkIn(Strict):
    """The dropped nodes of a mission and the mission estimator's parameters."""

    nodes: list[NodeIn] = Field(max_length=10000)
    params: dict[str, float | bool | str] = Field(default_factory=dict, max_length=20)


MAX_RANGE_ROWS = 20000
"""Most ranges in one ``POST /missions/{id}/network/ranges`` batch."""

NodeId = Annotated[str, Field(min_length=1, max_length=200)]


class NetworkRangesIn(Strict):
    """One numbered batch of ranges measured between two dropped nodes (mission time s, m)."""

    seq: int = Field(ge=0, lt=2**31)
    t_s: list[float] = Field(min_length=1, max_length=MAX_RANGE_ROWS)
    node_a: list[NodeId] = Field(min_length=1, max_length=MAX_RANGE_ROWS)
    node_b: list[NodeId] = Field(min_length=1, max_length=MAX_RANGE_ROWS)
    range_m: list[float] = Field(min_length=1, max_length=MAX_RANGE_ROWS)


def _params(values: dict[str, float | bool | str]) -> dict[str, Any]:
    unknown = sorted(set(values) - set(LIVE_PARAMS))
    if unknown:
        raise HTTPException(422, f"params.{unknown[0]}: unknown (one of "
                                 f"{', '.join(LIVE_PARAMS)})")
    for k, v in values.items():
        if isinstance(v, str) != (k == "smoother"):
            expected = "one of " + ", ".join(MODES) if k == "smoother" else "a number or bool"
            raise HTTPException(422, f"params.{k}: {v!r} (expected {expected})")
    try:
        prm = mission_params(values)
    except InputError as exc:
        raise HTTPException(422, f"params: {exc}") from None
    out = {k: v for k, v in dataclasses.asdict(prm).items() if k in LIVE_PARAMS}
    out["smoother"] = smoother_mode(prm.smoother)
    return out


@router.put("/missions/{mission_id}/network")
def put_network(mission_id: int, body: NetworkIn, who: Commander, db: DbDep,
                services: ServicesDep) -> dict[str, Any]:
    """Declare the mission's sensor network: its estimator runs in the service from now on.

    Refused (409) once the estimator runs or stored a snapshot.
    """
    mission_or_404(db, mission_id)
    ids = [n.id for n in body.nodes]
    if len(set(ids)) != len(ids):
        dup = next(i for i in ids if ids.count(i) > 1)
        raise HTTPException(422, f"nodes: id {dup!r} twice")
    params = _params(body.params)
    started = db.scalars(select(MissionSnapshot.id)
                         .where(MissionSnapshot.mission_id == mission_id).limit(1)).first()
    if started is not None or mission_id in services.missions.missions:
        raise HTTPException(409, f"mission {mission_id}: the network estimator has started")
    net = db.get(MissionNetwork, mission_id)
    if net is None:
        net = MissionNetwork(mission_id=mission_id, nodes=ids, params=params, estimates={},
                             horizon_s=None)
        db.add(net)
    else:
        net.nodes, net.params = ids, params
    db.commit()
    return {"mission": mission_id, "nodes": ids, "params": params}


@router.get("/missions/{mission_id}/network")
def get_network(mission_id: int, who: Reader, db: DbDep) -> dict[str, Any]:
    """The declared and heard nodes with their newest estimates, and the processed horizon."""
    mission_or_404(db, mission_id)
    net = db.get(MissionNetwork, mission_id)
    if net is None:
        raise HTTPException(404, f"mission {mission_id} declared no sensor network")
    return {"mission": mission_id, "params": net.params, "horizon_s": net.horizon_s,
            "nodes": network_nodes(db, mission_id)}


def _ranges(body: NetworkRangesIn, declared: set[str]) -> NetworkRanges:
    """The batch as ranges between declared nodes, else 422 naming the field."""
    n = len(body.t_s)
    for name in ("node_a", "node_b", "range_m"):
        if len(getattr(body, name)) != n:
            raise HTTPException(422, f"{name}: {len(getattr(body, name))} values for {n} "
                                     "times in t_s (one per range)")
    for name in ("node_a", "node_b"):
        bad = next((i for i, v in enumerate(getattr(body, name)) if v not in declared), None)
        if bad is not None:
            raise HTTPException(422, f"{name}[{bad}]: {getattr(body, name)[bad]!r} is not a "
                                     "node of the declared network (PUT .../network)")
    try:
        return NetworkRanges(t_s=np.asarray(body.t_s, float), node_a=np.asarray(body.node_a),
                             node_b=np.asarray(body.node_b),
                             range_m=np.asarray(body.range_m, float))
    except InputError as exc:
        raise HTTPException(422, str(exc)) from None


@router.post("/missions/{mission_id}/network/ranges")
def post_network_ranges(mission_id: int, body: NetworkRangesIn, who: Commander, db: DbDep,
                        services: ServicesDep) -> dict[str, Any]:
    """Store ranges the dropped nodes measured between themselves (idempotent per ``seq``).

    The mission estimator takes them at its next poll; ranges older than its processed
    horizon by then are late (counted, logged, not used).
    """
    mission_or_404(db, mission_id)
    wait = services.agent_rate.take(("network", mission_id))
    if wait > 0:
        raise HTTPException(429, f"mission {mission_id}: network ranges exceed "
                                 f"{services.settings.rate_per_agent_hz:g} requests/s",
                            headers=retry_after_header(wait))
    net = db.get(MissionNetwork, mission_id)
    if net is None:
        raise HTTPException(404, f"mission {mission_id} declared no sensor network "
                                 "(PUT /missions/{id}/network first)")
    ranges = _ranges(body, set(net.nodes))
    ack = {"mission": mission_id, "seq": body.seq, "rows": len(ranges.t_s)}
    dup = select(NetworkRangeBatch.id).where(NetworkRangeBatch.mission_id == mission_id,
                                             NetworkRangeBatch.seq == body.seq)
    if db.scalars(dup).first() is not None:
        return {**ack, "status": "duplicate"}
    db.add(NetworkRangeBatch(mission_id=mission_id, seq=body.seq,
                             received_unix=services.clock(),
                             t_first=float(ranges.t_s.min()), t_last=float(ranges.t_s.max()),
                             rows=len(ranges.t_s), body=pack(ranges)))
    try:
        db.commit()
    except IntegrityError:      # the same seq stored by a concurrent request
        db.rollback()
        return {**ack, "status": "duplicate"}
    return {**ack, "status": "accepted"}
