"""Floor plans for simulated missions: corridors around the simulated routes, per floor.

The thesis' missions come without drawings, so the plan is ours: every stretch of a route at a
floor's level becomes a corridor ``corridor_width_m`` wide, the stretches between floor levels a
stairs polygon (drawn on both floors it joins), and the first position of the first route the
exit. The output is a GeoJSON FeatureCollection in local mission metres (x east, y north), one
feature per corridor/wall/stairs/exit with ``properties.floor`` (int) and ``properties.kind``, the
shape the dashboard (hrtls.web) and the mission folder's ``floorplan.geojson`` use.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from shapely.geometry import LineString, MultiPolygon, Point, Polygon, mapping
from shapely.ops import unary_union

from hrtls.errors import InputError


def floor_of(z_m: np.ndarray, *, floor_height_m: float) -> np.ndarray:
    """Nearest floor index of heights above the ground floor (m)."""
    return np.rint(np.asarray(z_m, dtype=float) / floor_height_m).astype(int)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Start and end (exclusive) of each run of True in mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _polygons(shape: Any) -> list[Polygon]:
    if isinstance(shape, Polygon):
        return [] if shape.is_empty else [shape]
    if isinstance(shape, MultiPolygon):
        return list(shape.geoms)
    return []


def route_floorplan(routes: Sequence[np.ndarray], *, floor_height_m: float,
                    corridor_width_m: float = 2.4, level_tolerance_m: float = 0.25,
                    simplify_m: float = 0.1) -> dict[str, Any]:
    """Floor plan (GeoJSON dict) of corridors around routes given as (n, 3) positions in m."""
    if floor_height_m <= 0 or corridor_width_m <= 0:
        raise InputError(f"floor height {floor_height_m} m, corridor width {corridor_width_m} m",
                         where="route_floorplan", expected="both > 0")
    corridors: dict[int, list[Any]] = {}
    stairs: dict[int, list[Any]] = {}
    half = corridor_width_m / 2
    for k, route in enumerate(routes):
        xyz = np.asarray(route, dtype=float)
        if xyz.ndim != 2 or xyz.shape[1] != 3 or len(xyz) < 2 or not np.isfinite(xyz).all():
            raise InputError(f"route {k} has shape {xyz.shape}", where="route_floorplan",
                             expected="(n >= 2, 3) finite positions in m")
        floors = floor_of(xyz[:, 2], floor_height_m=floor_height_m)
        level = np.abs(xyz[:, 2] - floors * floor_height_m) <= level_tolerance_m
        for start, end in _runs(level):
            seg = xyz[start:end]
            floor = int(floors[start])
            shape = (LineString(seg[:, :2]) if len(seg) > 1 else Point(seg[0, :2])).buffer(half)
            corridors.setdefault(floor, []).append(shape)
        for start, end in _runs(~level):
            lo, hi = max(start - 1, 0), min(end + 1, len(xyz))
            seg = xyz[lo:hi]
            shape = LineString(seg[:, :2]).buffer(0.6, cap_style="flat") if len(seg) > 1 \
                else Point(seg[0, :2]).buffer(0.6)
            for floor in {int(floors[lo]), int(floors[hi - 1])}:
                stairs.setdefault(floor, []).append(shape)
    features: list[dict[str, Any]] = []

    def add(shape: Any, floor: int, kind: str, name: str | None = None) -> None:
        props: dict[str, Any] = {"floor": floor, "kind": kind}
        if name:
            props["name"] = name
        features.append({"type": "Feature", "properties": props, "geometry": mapping(shape)})

    for floor in sorted(set(corridors) | set(stairs)):
        area = unary_union(corridors.get(floor, [])).simplify(simplify_m)
        steps = unary_union(stairs.get(floor, [])).simplify(simplify_m)
        for poly in _polygons(area):
            add(poly, floor, "corridor")
            add(LineString(poly.exterior.coords), floor, "wall")
            for ring in poly.interiors:
                add(LineString(ring.coords), floor, "wall")
        for poly in _polygons(steps):
            add(poly, floor, "stairs", "stairs")
    if routes:
        first = np.asarray(routes[0], dtype=float)[0]
        exit_floor = int(floor_of(first[2:3], floor_height_m=floor_height_m)[0])
        add(Point(first[:2]).buffer(0.8), exit_floor, "exit", "exit")
    return {"type": "FeatureCollection", "features": features}
