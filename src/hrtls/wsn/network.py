"""Sensor-network model: nodes, anchors, the disk graph of links and measured distances.

A wireless sensor network (Inderst thesis, Sec. 3.5, eq. 3.9) is a set of planar nodes
``p_j = [x_j, y_j]`` (ENU metres) with an isotropic radio of range ``rho``: two nodes are linked
(and measure their distance) iff ``||p_i - p_j|| <= rho`` (the disk graph ``G = {V, E}``).
Anchors know their position. Other nodes may carry a ground-truth position (simulation only).

JSON form (extra keys are allowed and kept on a round trip)::

    {"radius": rho,
     "nodes": [{"id": "n1", "anchor": true, "position": [x, y]}, {"id": "n2"}, ...],
     "links": [{"a": "n1", "b": "n2", "distance": d}, ...]}

The disk graph of a deployment is built with a k-d tree (``scipy.spatial.cKDTree``), so building
a 10,000-node network costs milliseconds.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from hrtls.errors import FormatError, InputError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

METHOD_NAMES: tuple[str, ...] = ("unlocalized", "anchor", "trilateration", "shadow-edge", "agent")
"""Names of the localization methods, indexed by the method codes below."""
UNLOCALIZED, ANCHOR, TRILATERATION, SHADOW_EDGE, AGENT = range(5)

_NODE_KEYS = {"id", "anchor", "position"}
_LINK_KEYS = {"a", "b", "distance"}


@dataclass(frozen=True)
class Adjacency:
    """Compressed sparse rows of the undirected link graph.

    Neighbours of node ``i`` are ``indices[indptr[i]:indptr[i + 1]]`` with the measured distances
    ``distance_m[indptr[i]:indptr[i + 1]]`` (each link appears in both rows).
    """

    indptr: IntArray
    indices: IntArray
    distance_m: FloatArray


def build_adjacency(n_nodes: int, edges: IntArray, distance_m: FloatArray) -> Adjacency:
    """Build :class:`Adjacency` from an ``(m, 2)`` edge list and its distances (vectorized)."""
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    d = np.asarray(distance_m, dtype=np.float64).reshape(-1)
    src = np.concatenate([e[:, 0], e[:, 1]])
    dst = np.concatenate([e[:, 1], e[:, 0]])
    dd = np.concatenate([d, d])
    order = np.lexsort((dst, src))
    src, dst, dd = src[order], dst[order], dd[order]
    counts = np.bincount(src, minlength=n_nodes)
    indptr = np.zeros(n_nodes + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    return Adjacency(indptr=indptr, indices=dst.astype(np.int64), distance_m=dd)


def disk_graph(positions_m: FloatArray, radius_m: float) -> tuple[IntArray, FloatArray]:
    """Links of the disk graph: all pairs closer than or at ``radius_m`` (k-d tree query).

    Returns
    -------
    edges, distance_m:
        ``(m, 2)`` node index pairs with ``i < j`` (sorted) and their exact distances.
    """
    p = np.asarray(positions_m, dtype=np.float64)
    if p.shape[0] < 2:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    pairs = cKDTree(p).query_pairs(radius_m, output_type="ndarray").astype(np.int64)
    if pairs.size == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0)
    pairs.sort(axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    d = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1)
    return pairs, d


@dataclass(frozen=True, eq=False)
class Network:
    """A sensor network (disk graph with measured distances).

    Attributes
    ----------
    ids:
        Node identifiers (unique strings), index ``i`` refers to ``ids[i]``.
    radius_m:
        Communication radius ``rho`` (m).
    anchor:
        ``(n,)`` True for nodes whose position is known.
    position_m:
        ``(n, 2)`` known positions: anchors' positions and ground truth where given (zeros where
        ``has_position`` is False).
    has_position:
        ``(n,)`` True where ``position_m`` is meaningful.
    edges:
        ``(m, 2)`` linked node index pairs, ``i < j``, no duplicates.
    distance_m:
        ``(m,)`` measured distances of the links (exact or noisy), m.
    extra, node_extra, link_extra:
        Extra JSON keys (top level, per node, per link) kept for a round trip.
    """

    ids: tuple[str, ...]
    radius_m: float
    anchor: BoolArray
    position_m: FloatArray
    has_position: BoolArray
    edges: IntArray
    distance_m: FloatArray
    extra: Mapping[str, Any] = field(default_factory=dict)
    node_extra: tuple[Mapping[str, Any], ...] = ()
    link_extra: tuple[Mapping[str, Any], ...] = ()

    def __post_init__(self) -> None:
        n = len(self.ids)
        if not (np.isfinite(self.radius_m) and self.radius_m > 0):
            raise InputError(
                f"radius is {self.radius_m}", where="network radius", expected="a positive number"
            )
        if len(set(self.ids)) != n:
            dup = sorted({i for i in self.ids if self.ids.count(i) > 1})
            raise InputError(f"duplicate node ids {dup[:5]}", where="network nodes",
                             expected="unique ids")
        for name, arr, shape in (
            ("anchor", self.anchor, (n,)),
            ("position_m", self.position_m, (n, 2)),
            ("has_position", self.has_position, (n,)),
        ):
            if np.shape(arr) != shape:
                raise InputError(f"{name} has shape {np.shape(arr)}", where="network",
                                 expected=f"shape {shape}")
        if not np.all(np.isfinite(self.position_m)):
            raise InputError("non-finite position", where="network position_m",
                             expected="finite numbers")
        bad = np.flatnonzero(self.anchor & ~self.has_position)
        if bad.size:
            raise InputError("anchor without position", where=f"node '{self.ids[bad[0]]}'",
                             expected="a 'position' [x, y] for every anchor")
        e = self.edges
        m = e.shape[0]
        if e.ndim != 2 or e.shape[1] != 2 or self.distance_m.shape != (m,):
            raise InputError(f"edges {e.shape} / distances {self.distance_m.shape}",
                             where="network links", expected="(m, 2) edges and (m,) distances")
        if m:
            if e.min() < 0 or e.max() >= n:
                raise InputError("link index out of range", where="network links",
                                 expected=f"indices in [0, {n})")
            if np.any(e[:, 0] >= e[:, 1]):
                k = int(np.flatnonzero(e[:, 0] >= e[:, 1])[0])
                raise InputError("link is a self loop or not ordered",
                                 where=f"link {k} ({self.ids[e[k, 0]]}, {self.ids[e[k, 1]]})",
                                 expected="two different nodes, a < b")
            key = e[:, 0] * n + e[:, 1]
            if np.unique(key).size != m:
                raise InputError("duplicate link", where="network links",
                                 expected="each pair of nodes at most once")
            bad_d = np.flatnonzero(~np.isfinite(self.distance_m) | (self.distance_m <= 0))
            if bad_d.size:
                k = int(bad_d[0])
                raise InputError(f"distance {self.distance_m[k]}",
                                 where=f"link {k} ({self.ids[e[k, 0]]}, {self.ids[e[k, 1]]})",
                                 expected="a positive finite distance in metres")

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return len(self.ids)

    @cached_property
    def adjacency(self) -> Adjacency:
        """CSR adjacency of the links (built once)."""
        return build_adjacency(self.n_nodes, self.edges, self.distance_m)

    @cached_property
    def index(self) -> dict[str, int]:
        """Map from node id to index."""
        return {s: i for i, s in enumerate(self.ids)}

    def degree(self) -> IntArray:
        """Number of links of each node."""
        return np.diff(self.adjacency.indptr)

    def with_anchors(self, anchor: BoolArray) -> Network:
        """Return a copy with another anchor set (all anchors must have a position)."""
        return Network(
            ids=self.ids, radius_m=self.radius_m, anchor=np.asarray(anchor, dtype=bool),
            position_m=self.position_m, has_position=self.has_position, edges=self.edges,
            distance_m=self.distance_m, extra=self.extra, node_extra=self.node_extra,
            link_extra=self.link_extra,
        )


# ------------------------------------------------------------------------------------------
# Construction
# ------------------------------------------------------------------------------------------
def network_from_positions(
    positions_m: FloatArray,
    *,
    radius_m: float,
    anchor: BoolArray | None = None,
    rng: np.random.Generator | None = None,
    range_noise_fraction: float = 0.0,
    ids: Sequence[str] | None = None,
) -> Network:
    """Disk-graph network of nodes at known (ground-truth) positions.

    Parameters
    ----------
    positions_m:
        ``(n, 2)`` true node positions, m.
    radius_m:
        Communication radius ``rho``, m.
    anchor:
        ``(n,)`` anchor mask (default: no anchors).
    rng:
        Random generator for the range noise (needed when ``range_noise_fraction > 0``).
    range_noise_fraction:
        Standard deviation of the measured distance as a fraction of the true distance
        (``0.02`` = 2 %); the link set stays the true disk graph.
    ids:
        Node ids (default ``"n0"``, ``"n1"``, ...).
    """
    p = np.asarray(positions_m, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise InputError(f"positions have shape {p.shape}", where="positions_m",
                         expected="(n, 2)")
    n = p.shape[0]
    edges, d = disk_graph(p, radius_m)
    if range_noise_fraction < 0:
        raise InputError("negative range noise", where="range_noise_fraction", expected=">= 0")
    if range_noise_fraction > 0:
        if rng is None:
            raise InputError("noise requested without a random generator", where="rng",
                             expected="a numpy Generator")
        d = d * (1.0 + range_noise_fraction * rng.standard_normal(d.size))
        d = np.maximum(d, 1e-9 * radius_m)
    a = np.zeros(n, dtype=bool) if anchor is None else np.asarray(anchor, dtype=bool)
    names = tuple(f"n{i}" for i in range(n)) if ids is None else tuple(ids)
    return Network(
        ids=names, radius_m=float(radius_m), anchor=a, position_m=p.copy(),
        has_position=np.ones(n, dtype=bool), edges=edges, distance_m=d,
        node_extra=tuple({} for _ in range(n)), link_extra=tuple({} for _ in range(edges.shape[0])),
    )


def corner_seed_positions(
    rng: np.random.Generator,
    *,
    n_nodes: int,
    radius_m: float,
    width_m: float = 1.0,
    height_m: float = 1.0,
    min_seed_area_fraction: float = 0.02,
) -> FloatArray:
    """Random deployment with three seed nodes in the lower-left corner (thesis Fig. 6.11).

    The first three nodes are drawn uniformly in ``[0, rho/2]^2`` (so they are always mutually
    linked) and redrawn until their triangle area exceeds ``min_seed_area_fraction * rho^2``
    (clearly non-collinear); the other ``n_nodes - 3`` are uniform in the rectangle.
    """
    if n_nodes < 3:
        raise InputError(f"{n_nodes} nodes", where="n_nodes", expected="at least 3")
    half = 0.5 * radius_m
    while True:
        s = rng.uniform(0.0, half, size=(3, 2))
        u, v = s[1] - s[0], s[2] - s[0]
        area = 0.5 * abs(float(u[0] * v[1] - u[1] * v[0]))
        if area >= min_seed_area_fraction * radius_m**2:
            break
    rest = rng.uniform((0.0, 0.0), (width_m, height_m), size=(n_nodes - 3, 2))
    return np.vstack([s, rest])


def corner_seed_network(
    rng: np.random.Generator,
    *,
    n_nodes: int = 50,
    radius_m: float = 0.2,
    width_m: float = 1.0,
    height_m: float = 1.0,
    range_noise_fraction: float = 0.0,
) -> Network:
    """The thesis' loose-cooperation study network (Sec. 6.4.1): seeds in a corner are anchors."""
    p = corner_seed_positions(rng, n_nodes=n_nodes, radius_m=radius_m, width_m=width_m,
                              height_m=height_m)
    anchor = np.zeros(n_nodes, dtype=bool)
    anchor[:3] = True
    return network_from_positions(p, radius_m=radius_m, anchor=anchor, rng=rng,
                                  range_noise_fraction=range_noise_fraction)


def random_network(
    rng: np.random.Generator,
    *,
    n_nodes: int,
    radius_m: float,
    width_m: float = 1.0,
    height_m: float = 1.0,
    anchors: str = "corner",
    range_noise_fraction: float = 0.0,
) -> Network:
    """Uniform random deployment in a ``width_m x height_m`` rectangle.

    ``anchors`` is ``"corner"`` (three seeds in the lower-left corner, see
    :func:`corner_seed_positions`) or ``"none"`` (tight cooperation: no anchors).
    """
    if anchors == "corner":
        return corner_seed_network(rng, n_nodes=n_nodes, radius_m=radius_m, width_m=width_m,
                                   height_m=height_m, range_noise_fraction=range_noise_fraction)
    if anchors == "none":
        p = rng.uniform((0.0, 0.0), (width_m, height_m), size=(n_nodes, 2))
        return network_from_positions(p, radius_m=radius_m, rng=rng,
                                      range_noise_fraction=range_noise_fraction)
    raise InputError(f"anchors={anchors!r}", where="random_network", expected="'corner' or 'none'")


def connected_components(net: Network, *, radius_m: float | None = None) -> IntArray:
    """Component label of every node of the link graph (or of the disk graph at ``radius_m``).

    With ``radius_m`` the graph is rebuilt from the ground-truth positions (all nodes must have
    one); this is how Theorem 2's reachability at the agent's radio range ``d_r`` is checked.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as cc

    if radius_m is None:
        e = net.edges
    else:
        if not np.all(net.has_position):
            raise InputError("a node has no position", where="connected_components",
                             expected="ground truth for every node")
        e, _ = disk_graph(net.position_m, radius_m)
    n = net.n_nodes
    g = coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(n, n))
    _, labels = cc(g, directed=False)
    return labels.astype(np.int64)


# ------------------------------------------------------------------------------------------
# JSON
# ------------------------------------------------------------------------------------------
def _xy(value: Any, where: str) -> tuple[float, float]:
    if (
        not isinstance(value, list | tuple)
        or len(value) != 2
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        or not all(np.isfinite(v) for v in value)
    ):
        raise FormatError(f"position is {value!r}", where=where,
                          expected="[x, y], two finite numbers in metres")
    return float(value[0]), float(value[1])


def network_from_dict(obj: Any, *, where: str = "network") -> Network:
    """Parse the documented JSON form (see module docstring); extra keys are kept."""
    if not isinstance(obj, Mapping):
        raise FormatError("top level is not an object", where=where,
                          expected='{"radius": ..., "nodes": [...], "links": [...]}')
    for key in ("radius", "nodes"):
        if key not in obj:
            raise FormatError(f"missing key '{key}'", where=where,
                              expected='{"radius": ..., "nodes": [...], "links": [...]}')
    rho = obj["radius"]
    if not isinstance(rho, int | float) or isinstance(rho, bool) or not rho > 0:
        raise FormatError(f"radius is {rho!r}", where=f"{where} 'radius'",
                          expected="a positive number (m)")
    nodes = obj["nodes"]
    links = obj.get("links", [])
    if not isinstance(nodes, list) or not isinstance(links, list):
        raise FormatError("'nodes' or 'links' is not a list", where=where, expected="lists")
    n = len(nodes)
    ids: list[str] = []
    anchor = np.zeros(n, dtype=bool)
    pos = np.zeros((n, 2))
    has = np.zeros(n, dtype=bool)
    node_extra: list[dict[str, Any]] = []
    for i, nd in enumerate(nodes):
        w = f"{where} nodes[{i}]"
        if not isinstance(nd, Mapping) or "id" not in nd:
            raise FormatError("node without 'id'", where=w, expected='{"id": "name", ...}')
        nid = nd["id"]
        if not isinstance(nid, str) or not nid:
            raise FormatError(f"id is {nid!r}", where=w, expected="a non-empty string")
        ids.append(nid)
        a = nd.get("anchor", False)
        if not isinstance(a, bool):
            raise FormatError(f"anchor is {a!r}", where=w, expected="true or false")
        anchor[i] = a
        if "position" in nd and nd["position"] is not None:
            pos[i] = _xy(nd["position"], f"{w} 'position'")
            has[i] = True
        elif a:
            raise FormatError("anchor without 'position'", where=w,
                              expected="a 'position' [x, y] for every anchor")
        node_extra.append({k: v for k, v in nd.items() if k not in _NODE_KEYS})
    index = {s: i for i, s in enumerate(ids)}
    if len(index) != n:
        dup = sorted({s for s in ids if ids.count(s) > 1})
        raise FormatError(f"duplicate node ids {dup[:5]}", where=f"{where} nodes",
                          expected="unique ids")
    pairs: dict[tuple[int, int], int] = {}
    edges = np.zeros((len(links), 2), dtype=np.int64)
    dist = np.zeros(len(links))
    link_extra: list[dict[str, Any]] = []
    for k, ln in enumerate(links):
        w = f"{where} links[{k}]"
        if not isinstance(ln, Mapping) or not {"a", "b", "distance"} <= set(ln):
            raise FormatError("link needs 'a', 'b' and 'distance'", where=w,
                              expected='{"a": id, "b": id, "distance": d}')
        a_id, b_id, d = ln["a"], ln["b"], ln["distance"]
        if a_id not in index or b_id not in index:
            missing = a_id if a_id not in index else b_id
            raise FormatError(f"unknown node id {missing!r}", where=w,
                              expected="ids listed in 'nodes'")
        if not isinstance(d, int | float) or isinstance(d, bool) or not np.isfinite(d) or d <= 0:
            raise FormatError(f"distance is {d!r}", where=w, expected="a positive number (m)")
        i, j = index[a_id], index[b_id]
        if i == j:
            raise FormatError("self link", where=w, expected="two different nodes")
        pair_key = (min(i, j), max(i, j))
        if pair_key in pairs:
            raise FormatError(f"duplicate link ({a_id}, {b_id})", where=w,
                              expected=f"each pair once (first at links[{pairs[pair_key]}])")
        pairs[pair_key] = k
        edges[k] = pair_key
        dist[k] = float(d)
        link_extra.append({kk: v for kk, v in ln.items() if kk not in _LINK_KEYS})
    extra = {k: v for k, v in obj.items() if k not in {"radius", "nodes", "links"}}
    return Network(ids=tuple(ids), radius_m=float(rho), anchor=anchor, position_m=pos,
                   has_position=has, edges=edges, distance_m=dist, extra=extra,
                   node_extra=tuple(node_extra), link_extra=tuple(link_extra))


def network_to_dict(
    net: Network,
    *,
    estimate_m: FloatArray | None = None,
    method: Sequence[str] | None = None,
    covariance_m2: FloatArray | None = None,
    include_truth: bool = True,
) -> dict[str, Any]:
    """Serialize to the documented JSON form, optionally with per-node results.

    ``estimate_m`` and ``method`` (one name of :data:`METHOD_NAMES` per node) are written as
    ``"estimate"`` and ``"method"``; unlocalized nodes get ``"method": "unlocalized"`` and no
    estimate. ``covariance_m2`` (``(n, 2, 2)``) adds ``"covariance"`` for localized nodes.
    """
    nodes: list[dict[str, Any]] = []
    for i, nid in enumerate(net.ids):
        nd: dict[str, Any] = {"id": nid}
        if net.anchor[i]:
            nd["anchor"] = True
        if net.has_position[i] and (include_truth or net.anchor[i]):
            nd["position"] = [float(net.position_m[i, 0]), float(net.position_m[i, 1])]
        extra = net.node_extra[i] if i < len(net.node_extra) else {}
        for name, v in extra.items():
            if method is not None and name in ("estimate", "method", "covariance"):
                continue
            nd[name] = v
        if method is not None:
            nd["method"] = method[i]
            if method[i] != "unlocalized" and estimate_m is not None:
                nd["estimate"] = [float(estimate_m[i, 0]), float(estimate_m[i, 1])]
                if covariance_m2 is not None:
                    nd["covariance"] = [[float(c) for c in row] for row in covariance_m2[i]]
        nodes.append(nd)
    links: list[dict[str, Any]] = []
    for k in range(net.edges.shape[0]):
        ln: dict[str, Any] = {"a": net.ids[net.edges[k, 0]], "b": net.ids[net.edges[k, 1]],
                              "distance": float(net.distance_m[k])}
        if k < len(net.link_extra):
            ln.update(net.link_extra[k])
        links.append(ln)
    out: dict[str, Any] = {"radius": net.radius_m, **dict(net.extra)}
    out["nodes"] = nodes
    out["links"] = links
    return out


def load_network(path: str | Path) -> Network:
    """Read a network JSON file (see module docstring)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", where=str(p),
                         expected="a readable JSON file") from exc
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"invalid JSON ({exc.msg})", where=f"{p} line {exc.lineno}",
                          expected="a JSON object") from exc
    return network_from_dict(obj, where=str(p))


def save_network(path: str | Path, net: Network, **results: Any) -> None:
    """Write a network JSON file; keyword arguments as in :func:`network_to_dict`."""
    Path(path).write_text(json.dumps(network_to_dict(net, **results), indent=1) + "\n",
                          encoding="utf-8")
