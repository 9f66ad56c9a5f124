"""Estimates as the contract's JSON objects and as database rows."""

from __future__ import annotations

from typing import Any

from hrtls.pipeline.output import Estimates
from hrtls.service.models import EstimateRow
from hrtls.service.runner import activity_label, finite_or_none


def estimate_dict(agent_id: int, e: Estimates, i: int, *, stale: bool,
                  received_t: float) -> dict[str, Any]:
    """Row ``i`` of ``e`` as the contract's Estimate."""
    c = e.cov_xy[i]
    return {"agent": agent_id, "t": float(e.t[i]), "x": float(e.xyz[i, 0]),
            "y": float(e.xyz[i, 1]), "z": float(e.xyz[i, 2]), "floor": int(e.floor[i]),
            "cov_xy": [[float(c[0, 0]), float(c[0, 1])], [float(c[1, 0]), float(c[1, 1])]],
            "heading_rad": float(e.heading_rad[i]), "var_heading": float(e.var_heading[i]),
            "activity": activity_label(int(e.activity[i])),
            "since_correction_s": finite_or_none(float(e.since_correction_s[i])),
            "stale": stale, "received_t": received_t}


def row_dict(r: EstimateRow) -> dict[str, Any]:
    """A stored estimate as the contract's Estimate."""
    return {"agent": r.agent_id, "t": r.t, "x": r.x, "y": r.y, "z": r.z, "floor": r.floor,
            "cov_xy": [[r.cxx, r.cxy], [r.cxy, r.cyy]], "heading_rad": r.heading_rad,
            "var_heading": r.var_heading, "activity": r.activity,
            "since_correction_s": r.since_correction_s, "stale": r.stale,
            "received_t": r.received_t}


def rows_to_db(mission_id: int, agent_id: int, e: Estimates, *, stale: bool,
                received_t: float) -> list[dict[str, Any]]:
    """Rows of ``e`` as ``estimates`` table rows."""
    out = []
    for i in range(len(e)):
        d = estimate_dict(agent_id, e, i, stale=stale, received_t=received_t)
        c = d.pop("cov_xy")
        d.pop("agent")
        out.append({**d, "mission_id": mission_id, "agent_id": agent_id, "cxx": c[0][0],
                    "cxy": c[0][1], "cyy": c[1][1]})
    return out
