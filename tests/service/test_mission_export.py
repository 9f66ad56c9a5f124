"""A mission exported from a live service is a mission folder that `hrtls mission track` reads."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import numpy as np
from sqlalchemy import select
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.io.mission import read_mission
from hrtls.io.tables import decode_table, read_trajectory
from hrtls.service.client import AgentClient, session_batches
from hrtls.service.db import make_engine, session_factory
from hrtls.service.missions import export_mission
from hrtls.service.models import EstimateRow

from .conftest import Live, new_agent
from .streams import API, mission_for, office, start_pose

runner = CliRunner()


def test_export_tracks_offline_as_the_agent_alone(live: Live, commander: httpx.Client,
                                                  tmp_path: Path) -> None:
    session = office(20.0)
    mid, aid, token = mission_for(commander, session, name="Rescuer A")
    idle = new_agent(commander, mid, name="Rescuer B")["agent"]["id"]
    with AgentClient(live.url, token, fmt="json") as agent:
        agent.checkin(start_pose(session))
        for _, b in session_batches(session, chunk_s=1.0):
            agent.submit(b)
        assert agent.outbox == {}
    assert commander.get(f"{API}/missions/{mid}").status_code == 200
    out = tmp_path / "exp"
    export_mission(live.settings.db_url, mid, out)

    estimates = decode_table((out / f"agent-{aid}" / "service_estimates.csv").read_bytes(),
                             table="estimates", name="service_estimates.csv")
    engine = make_engine(live.settings.db_url)
    try:
        with session_factory(engine)() as db:
            stored = db.execute(select(EstimateRow.t, EstimateRow.x, EstimateRow.activity)
                                .where(EstimateRow.agent_id == aid)
                                .order_by(EstimateRow.t)).all()
    finally:
        engine.dispose()
    assert estimates.n_rows == len(stored) > 0
    t, x, activity = zip(*stored, strict=True)
    np.testing.assert_array_equal(estimates.float("t"), t)
    np.testing.assert_array_equal(estimates.float("x"), x)
    assert estimates.str("activity").tolist() == list(activity)

    spec = json.loads((out / "mission.json").read_text())
    assert spec["service"]["id"] == mid and spec["service"]["t0_unix"] > 0
    assert [a["session"] for a in spec["agents"]] == [f"agent-{aid}"]
    assert any(f"id {idle}" in n for n in spec["notes"])
    folder = read_mission(out)
    assert list(folder.agents) == ["Rescuer A"] and folder.agents["Rescuer A"].kind == "rescuer"

    res = runner.invoke(app, ["mission", "track", str(out), "-o", str(tmp_path / "m")])
    assert res.exit_code == 0, res.output
    alone = runner.invoke(app, ["track", str(out / f"agent-{aid}"), "-o", str(tmp_path / "t")])
    assert alone.exit_code == 0, alone.output
    got = read_trajectory(tmp_path / "m" / "agents" / "Rescuer A" / "trajectory.csv")
    want = read_trajectory(tmp_path / "t" / "trajectory.csv")
    np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    np.testing.assert_allclose(got.xyz, want.xyz, atol=1e-6)
    report = json.loads((tmp_path / "m" / "agents" / "Rescuer A" / "report.json").read_text())
    assert report["corrections"]["range"]["accepted"] > 0
