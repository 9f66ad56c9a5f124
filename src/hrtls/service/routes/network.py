"""A mission's sensor network: declare the dropped nodes, read the live node estimates."""

from __future__ import annotations

import dataclasses
from typing import Any

from fastapi import APIRouter, HTTPException
from pydantic import Field
from sqlalchemy import select

from hrtls.errors import InputError
from hrtls.mission.smoother_modes import MODES, smoother_mode
from hrtls.service.deps import Commander, DbDep, Reader, ServicesDep, mission_or_404
from hrtls.service.mission_runner import mission_params, network_nodes
from hrtls.service.models import MissionNetwork, MissionSnapshot
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
