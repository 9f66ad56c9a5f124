import json

import networkx as nx
import numpy as np
import pytest

from hrtls.errors import FormatError, InputError
from hrtls.wsn.network import (
    build_adjacency,
    connected_components,
    corner_seed_network,
    disk_graph,
    load_network,
    network_from_dict,
    network_from_positions,
    network_to_dict,
    random_network,
    save_network,
)

DOC = {
    "radius": 1.5,
    "site": "hall B",
    "nodes": [
        {"id": "n1", "anchor": True, "position": [0.0, 0.0], "color": "red"},
        {"id": "n2", "anchor": True, "position": [1.0, 0.0]},
        {"id": "n3", "position": [0.0, 1.0]},
        {"id": "n4"},
    ],
    "links": [
        {"a": "n1", "b": "n2", "distance": 1.0},
        {"a": "n3", "b": "n1", "distance": 1.0, "rssi": -60},
        {"a": "n2", "b": "n3", "distance": 1.4142135623730951},
    ],
}


def test_json_round_trip_keeps_extra_keys(tmp_path):
    net = network_from_dict(DOC)
    assert net.ids == ("n1", "n2", "n3", "n4")
    assert net.anchor.tolist() == [True, True, False, False]
    assert net.has_position.tolist() == [True, True, True, False]
    assert net.edges.tolist() == [[0, 1], [0, 2], [1, 2]]
    p = tmp_path / "net.json"
    save_network(p, net)
    back = json.loads(p.read_text())
    assert back["site"] == "hall B"
    assert back["nodes"][0]["color"] == "red"
    assert back["links"][1]["rssi"] == -60
    assert "position" not in back["nodes"][3]
    net2 = load_network(p)
    assert np.array_equal(net2.edges, net.edges)
    assert np.allclose(net2.distance_m, net.distance_m)


def test_results_written_per_node():
    net = network_from_dict(DOC)
    est = np.array([[0, 0], [1, 0], [0, 1], [0, 0]], dtype=float)
    out = network_to_dict(net, estimate_m=est,
                          method=["anchor", "anchor", "trilateration", "unlocalized"])
    assert out["nodes"][2]["method"] == "trilateration"
    assert out["nodes"][2]["estimate"] == [0.0, 1.0]
    assert out["nodes"][3]["method"] == "unlocalized"
    assert "estimate" not in out["nodes"][3]


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d["nodes"][0].pop("position"), "anchor without"),
        (lambda d: d["links"].append({"a": "n1", "b": "zz", "distance": 1}), "unknown node"),
        (lambda d: d["links"].append({"a": "n2", "b": "n1", "distance": 1}), "duplicate link"),
        (lambda d: d["links"].__setitem__(0, {"a": "n1", "b": "n2", "distance": -1}), "distance"),
        (lambda d: d["nodes"].append({"id": "n1"}), "duplicate node"),
        (lambda d: d.__setitem__("radius", 0), "radius"),
        (lambda d: d["nodes"][2].__setitem__("position", [1, "a"]), "position"),
        (lambda d: d["links"].append({"a": "n1", "b": "n1", "distance": 1}), "self link"),
    ],
)
def test_bad_documents_name_the_problem(mutate, match):
    d = json.loads(json.dumps(DOC))
    mutate(d)
    with pytest.raises(FormatError, match=match):
        network_from_dict(d)


def test_invalid_json_file(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(FormatError, match="line 1"):
        load_network(p)
    with pytest.raises(InputError):
        load_network(tmp_path / "missing.json")


def test_disk_graph_matches_brute_force():
    rng = np.random.default_rng(4)
    p = rng.uniform(size=(300, 2))
    e, d = disk_graph(p, 0.1)
    dd = np.linalg.norm(p[:, None] - p[None], axis=2)
    i, j = np.nonzero(np.triu(dd <= 0.1, 1))
    assert sorted(map(tuple, e.tolist())) == sorted(zip(i.tolist(), j.tolist(), strict=True))
    assert np.allclose(d, dd[e[:, 0], e[:, 1]])


def test_adjacency_is_symmetric_csr():
    net = random_network(np.random.default_rng(1), n_nodes=60, radius_m=0.25, anchors="none")
    adj = net.adjacency
    g = {(int(i), int(adj.indices[k])) for i in range(net.n_nodes)
         for k in range(adj.indptr[i], adj.indptr[i + 1])}
    assert all((b, a) in g for a, b in g)
    assert len(g) == 2 * net.edges.shape[0]
    empty = build_adjacency(3, np.zeros((0, 2), dtype=np.int64), np.zeros(0))
    assert empty.indptr.tolist() == [0, 0, 0, 0]


def test_corner_seeds_are_a_linked_triangle():
    for s in range(20):
        net = corner_seed_network(np.random.default_rng(s))
        assert net.anchor[:3].all() and not net.anchor[3:].any()
        pairs = {tuple(e) for e in net.edges.tolist()}
        assert {(0, 1), (0, 2), (1, 2)} <= pairs
        assert np.all(net.position_m[:3] <= 0.1)


def test_noise_changes_distances_not_links():
    rng = np.random.default_rng(0)
    p = rng.uniform(size=(80, 2))
    exact = network_from_positions(p, radius_m=0.2)
    noisy = network_from_positions(p, radius_m=0.2, rng=np.random.default_rng(1),
                                   range_noise_fraction=0.02)
    assert np.array_equal(exact.edges, noisy.edges)
    rel = noisy.distance_m / exact.distance_m - 1
    assert 0.01 < rel.std() < 0.03


def test_components_against_networkx():
    net = random_network(np.random.default_rng(7), n_nodes=70, radius_m=0.12, anchors="none")
    lab = connected_components(net)
    g = nx.Graph()
    g.add_nodes_from(range(net.n_nodes))
    g.add_edges_from(net.edges.tolist())
    for comp in nx.connected_components(g):
        assert len({int(lab[i]) for i in comp}) == 1
    assert lab.max() + 1 == nx.number_connected_components(g)
    lab2 = connected_components(net, radius_m=0.24)
    assert lab2.max() <= lab.max()
