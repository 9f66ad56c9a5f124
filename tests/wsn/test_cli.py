import json

import numpy as np
import typer
from typer.testing import CliRunner

from hrtls.cli.wsn import app as wsn_app

root = typer.Typer()
root.add_typer(wsn_app, name="wsn")
runner = CliRunner()


def _invoke(*args):
    res = runner.invoke(root, ["wsn", *map(str, args)])
    return res


def test_simulate_localize_plan(tmp_path):
    net = tmp_path / "net.json"
    r = _invoke("simulate", "-o", net, "--seed", "3", "--plot", tmp_path / "net.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "net.png").stat().st_size > 1000
    out = tmp_path / "out.json"
    r = _invoke("localize", net, "-o", out, "--method", "sela", "--plot", tmp_path / "l.png")
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    methods = {n["method"] for n in doc["nodes"]}
    assert methods <= {"anchor", "trilateration", "shadow-edge", "agent", "unlocalized"}
    for n in doc["nodes"]:
        if n["method"] != "unlocalized":
            assert np.allclose(n["estimate"], n["position"], atol=1e-9)
    r = _invoke("localize", net, "--method", "tla", "--refine")
    assert r.exit_code == 0, r.output
    wp = tmp_path / "wp.csv"
    r = _invoke("plan", net, "-o", wp, "--plot", tmp_path / "p.png")
    assert r.exit_code == 0, r.output
    assert wp.read_text().startswith("index,x,y,kind,targets")
    final = tmp_path / "final.json"
    r = _invoke("plan", net, "--simulate", "--network-output", final)
    assert r.exit_code == 0, r.output
    assert "way points" in r.output
    assert json.loads(final.read_text())["nodes"][10]["method"] != ""


def test_localize_with_agent_path(tmp_path):
    net = tmp_path / "net.json"
    assert _invoke("simulate", "-o", net, "--seed", "1").exit_code == 0
    doc = json.loads(net.read_text())
    pos = np.array([n["position"] for n in doc["nodes"]])
    path = tmp_path / "agent.csv"
    # an agent standing on a few unlocalized nodes' true positions
    rows = ["t,x,y"] + [f"{k},{pos[k, 0]},{pos[k, 1]}" for k in range(3, 40, 3)]
    path.write_text("\n".join(rows) + "\n")
    out = tmp_path / "out.json"
    r0 = _invoke("localize", net, "-o", out)
    n0 = sum(n["method"] != "unlocalized" for n in json.loads(out.read_text())["nodes"])
    r = _invoke("localize", net, "--agent", path, "-o", out, "--plot", tmp_path / "a.png")
    assert r0.exit_code == 0 and r.exit_code == 0, r.output
    got = json.loads(out.read_text())["nodes"]
    assert sum(n["method"] != "unlocalized" for n in got) > n0
    for n in got:
        if n["method"] != "unlocalized":
            assert np.allclose(n["estimate"], n["position"], atol=1e-9)
    # explicit ranges file: times must match the path
    rng = tmp_path / "ranges.csv"
    rng.write_text("t,node,range\n99,n0,0.1\n")
    r = _invoke("localize", net, "--agent", path, "--ranges", rng)
    assert r.exit_code == 2 and "not a row of the agent path" in r.output


def test_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"radius": 1, "nodes": [{"id": "a", "anchor": true}]}')
    r = _invoke("localize", bad)
    assert r.exit_code == 2
    assert "anchor without 'position'" in r.output
    r = _invoke("localize", bad, "--method", "xyz")
    assert r.exit_code == 2


def test_experiment_small(tmp_path):
    r = _invoke("experiment", "--networks", "2", "--noise-networks", "1", "--plot",
                tmp_path / "e.png", "--tight-plot", tmp_path / "t.png")
    assert r.exit_code == 0, r.output
    assert "Loose cooperation" in r.output and "Tight cooperation" in r.output
    assert "Range noise" in r.output
    assert (tmp_path / "e.png").exists() and (tmp_path / "t.png").exists()


def test_default_localize_explains_and_points_to_the_agent(tmp_path):
    net = tmp_path / "net.json"
    assert _invoke("simulate", "-o", net).exit_code == 0
    r = _invoke("localize", net)
    assert r.exit_code == 0, r.output
    assert "fewer than three localized neighbours" in r.output
    assert f"hrtls wsn plan {net} --simulate" in r.output


def test_plan_simulate_never_repeats_a_way_point(tmp_path):
    net = tmp_path / "net.json"
    wp = tmp_path / "wp.csv"
    assert _invoke("simulate", "-o", net).exit_code == 0
    r = _invoke("plan", net, "--simulate", "-o", wp)
    assert r.exit_code == 0, r.output
    xy = np.loadtxt(wp, delimiter=",", skiprows=1, usecols=(1, 2))
    gaps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert xy.shape[0] > 3
    assert gaps.min() > 1e-6
