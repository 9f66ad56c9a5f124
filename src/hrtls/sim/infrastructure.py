"""Infrastructure seen by a moving person: cameras, beacons, RFID tags, radio nodes, WSNs.

Each model turns the ground-truth track (times, positions, headings, speeds) into the session
observations of ARCHITECTURE.md (``fixes.csv``, ``rss.csv``, ``tags.csv``, ``ranges.csv``) plus the
landmarks (location messages) that describe the infrastructure. All sampling is vectorized.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from hrtls.data import Landmark, PositionFixes, RangeMeasurements, RssReadings, TagDetections
from hrtls.errors import InputError
from hrtls.frames import wrap_angle

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class TrackSample:
    """Ground truth the infrastructure observes (uniform or not, strictly increasing times).

    Attributes
    ----------
    t: times, s. xyz: positions (person's floor-level point), m (N, 3).
    heading: body heading, rad. speed: horizontal speed, m/s.
    """

    t: FloatArray
    xyz: FloatArray
    heading: FloatArray
    speed: FloatArray

    def at(self, tq: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Positions, headings and speeds interpolated at ``tq``."""
        xyz = np.column_stack([np.interp(tq, self.t, c) for c in self.xyz.T])
        h_unwrapped = np.unwrap(self.heading)
        heading = wrap_angle(np.interp(tq, self.t, h_unwrapped))
        speed = np.interp(tq, self.t, self.speed)
        return xyz, heading, speed


def _query_times(track: TrackSample, rate_hz: float, rng: np.random.Generator) -> FloatArray:
    if not rate_hz > 0:
        raise InputError(f"rate {rate_hz}", where="rate_hz", expected="a positive rate in Hz")
    t0 = float(track.t[0]) + rng.uniform(0.0, 1.0 / rate_hz)
    return np.arange(t0, float(track.t[-1]), 1.0 / rate_hz)


# --------------------------------------------------------------------------------------------
# Cameras (Colombo Sec. IV-B, V)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class CameraSystem:
    """A vision tracker delivering position fixes.

    Attributes
    ----------
    period_s: time between fixes (Colombo's ``Tp``), s.
    sigma_m: 1-sigma horizontal noise of a fix, m.
    latency_s: uncompensated latency: a fix stamped ``t`` shows the position at ``t - latency``.
    coverage: area (shapely geometry) where the cameras see the person; None for everywhere.
    only_while_moving: deliver fixes only while the person walks (Colombo Sec. III-D).
    moving_speed_m_s: speed above which the person counts as moving.
    dropout_probability: probability that a fix is lost.
    """

    period_s: float = 1.0
    sigma_m: float = 0.05
    latency_s: float = 0.0
    coverage: BaseGeometry | None = None
    only_while_moving: bool = False
    moving_speed_m_s: float = 0.2
    dropout_probability: float = 0.0


def camera_fixes(camera: CameraSystem, track: TrackSample, rng: np.random.Generator
                 ) -> PositionFixes | None:
    """Fixes every ``period_s`` inside the coverage (None when there are none)."""
    tq = _query_times(track, 1.0 / camera.period_s, rng)
    xyz, _, speed = track.at(np.clip(tq - camera.latency_s, track.t[0], track.t[-1]))
    keep = rng.random(len(tq)) >= camera.dropout_probability
    if camera.only_while_moving:
        keep &= speed > camera.moving_speed_m_s
    if camera.coverage is not None:
        keep &= shapely.contains_xy(camera.coverage, xyz[:, 0], xyz[:, 1])
    if not np.any(keep):
        return None
    xyz = xyz[keep].copy()
    xyz[:, :2] += rng.normal(0.0, camera.sigma_m, (len(xyz), 2))
    return PositionFixes(tq[keep], xyz, np.full(len(xyz), camera.sigma_m), has_z=False,
                         name="fixes")


# --------------------------------------------------------------------------------------------
# RSS anchors (Tarrio eq. 1)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class RssChannel:
    """Log-normal path loss, Tarrio eq. 1: ``P = A - 10 eta log10(d / d0) + N(0, sigma)``.

    Attributes
    ----------
    a_dbm: received power at ``d0_m``, dBm. eta: path-loss exponent. sigma_db: shadowing, dB.
    d0_m: reference distance, m. sensitivity_dbm: readings below are lost.
    beacon_rate_hz: beacons per second of each anchor.
    anchor_offset_sigma_db: standard deviation of a constant per-anchor offset (walls,
        antenna differences: what a calibration-free channel model cannot know), dB.
    """

    a_dbm: float = -60.0
    eta: float = 2.5
    sigma_db: float = 5.0
    d0_m: float = 1.0
    sensitivity_dbm: float = -95.0
    beacon_rate_hz: float = 2.5
    anchor_offset_sigma_db: float = 0.0

    def coverage_radius_m(self) -> float:
        """Distance where the mean RSS equals the sensitivity, m."""
        return float(self.d0_m * 10 ** ((self.a_dbm - self.sensitivity_dbm) / (10 * self.eta)))


def anchor_landmarks(anchors: Mapping[str, Sequence[float]], *,
                     kind: Literal["anchor", "node", "beacon"] = "anchor"
                     ) -> dict[str, Landmark]:
    """Location messages of fixed anchors / nodes at known positions (m)."""
    return {k: Landmark(id=k, kind=kind, position=(float(p[0]), float(p[1]), float(p[2])))
            for k, p in anchors.items()}


def rss_readings(anchors: Mapping[str, Sequence[float]], channel: RssChannel,
                 track: TrackSample, rng: np.random.Generator, *, receiver_height_m: float = 1.0
                 ) -> RssReadings | None:
    """Beacons of each anchor heard along the track (Tarrio eq. 1 with sensitivity)."""
    if not anchors:
        return None
    ids = list(anchors)
    pos = np.asarray([anchors[k] for k in ids], dtype=np.float64)
    offsets = rng.normal(0.0, channel.anchor_offset_sigma_db, len(ids)) \
        if channel.anchor_offset_sigma_db > 0 else np.zeros(len(ids))
    t_all, a_all, p_all = [], [], []
    for j in range(len(ids)):
        tq = _query_times(track, channel.beacon_rate_hz, rng)
        xyz, _, _ = track.at(tq)
        xyz[:, 2] += receiver_height_m
        d = np.maximum(np.linalg.norm(xyz - pos[j], axis=1), 0.1 * channel.d0_m)
        rss = (channel.a_dbm - 10.0 * channel.eta * np.log10(d / channel.d0_m) + offsets[j]
               + rng.normal(0.0, channel.sigma_db, len(tq)))
        keep = rss >= channel.sensitivity_dbm
        t_all.append(tq[keep])
        a_all.append(np.full(int(keep.sum()), j))
        p_all.append(rss[keep])
    t = np.concatenate(t_all)
    if len(t) == 0:
        return None
    order = np.argsort(t, kind="stable")
    anchor = np.asarray(ids)[np.concatenate(a_all)[order]]
    return RssReadings(t[order], anchor, np.clip(np.concatenate(p_all)[order], -150, 30))


# --------------------------------------------------------------------------------------------
# Passive RFID tags (Inderst Sec. 4.3.2, 6.3.2, App. B)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class RfidTag:
    """A passive tag and its location message.

    Position in m (z above the path's floor-level z), lobe axis (rad, ENU) and half angle,
    detection radius, floor, and the bearings (rad) of the ways that lead through it.
    """

    id: str
    position: tuple[float, float, float]
    lobe_orientation_rad: float
    lobe_half_angle_rad: float = float(np.pi / 3)
    radius_m: float = 2.5
    floor: int | None = None
    bearings_rad: tuple[float, ...] = ()

    def landmark(self) -> Landmark:
        """The tag's location message."""
        return Landmark(id=self.id, kind="rfid", position=self.position, floor=self.floor,
                        bearings_rad=self.bearings_rad, accuracy_m=self.radius_m,
                        lobe_orientation_rad=float(wrap_angle(self.lobe_orientation_rad)),
                        lobe_half_angle_rad=self.lobe_half_angle_rad)


# App. B Table 1 (e = 66 %, hT = 149 cm, hR = 140 cm, theta = 0): efficiency vs distance and
# reader rotation phi; +phi and -phi columns averaged, |phi| >= pi/2 (reflection outliers) -> 0
_TABLE_D_M = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
_TABLE_PHI = np.array([0.0, np.pi / 4, np.pi / 2])
_TABLE_ETA = np.array([
    [1.0, 1.0, 1.0, 1.0, 1.0, 0.8, 0.0],      # phi = 0
    [1.0, 1.0, 1.0, 0.475, 0.0, 0.0, 0.0],    # |phi| = pi/4
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],      # |phi| = pi/2
])


@dataclass(frozen=True, slots=True, kw_only=True)
class RfidReader:
    """A shoulder-worn UHF reader.

    Attributes
    ----------
    query_rate_hz: queries per second (5 Hz in Inderst Sec. 6.3.2).
    height_m: antenna height above the floor (140 cm shoulder height, App. B).
    yaw_offset_rad: antenna direction relative to the body heading, rad.
    height_loss_per_m: efficiency lost per metre of |tag height - reader height| beyond 0.1 m
        (App. B Fig. 4 shows lower efficiency for a larger difference; value assumed).
    speed_loss_per_m_s: efficiency lost per m/s above 1 m/s (App. B Table 2; value assumed).
    """

    query_rate_hz: float = 5.0
    height_m: float = 1.4
    yaw_offset_rad: float = 0.0
    height_loss_per_m: float = 0.3
    speed_loss_per_m_s: float = 0.15


def rfid_detection_probability(distance_m: FloatArray, reader_rotation_rad: FloatArray,
                               azimuth_rad: FloatArray, half_angle_rad: float,
                               height_diff_m: FloatArray, speed_m_s: FloatArray,
                               reader: RfidReader) -> FloatArray:
    """Probability that one query reads the tag (App. B Table 1 interpolated, lobe, losses).

    ``distance_m`` is the 3-D tag-reader distance, ``reader_rotation_rad`` the angle between the
    antenna direction and the direction to the tag (``phi``), ``azimuth_rad`` the angle of the
    reader seen from the tag's lobe axis (``theta``).
    """
    d = np.clip(np.asarray(distance_m, dtype=np.float64), 0.0, _TABLE_D_M[-1])
    phi = np.clip(np.abs(wrap_angle(reader_rotation_rad)), 0.0, _TABLE_PHI[-1])
    j = np.clip(np.searchsorted(_TABLE_PHI, phi, side="right") - 1, 0, len(_TABLE_PHI) - 2)
    w = (phi - _TABLE_PHI[j]) / (_TABLE_PHI[j + 1] - _TABLE_PHI[j])
    lo = _interp_rows_table(d, j)
    hi = _interp_rows_table(d, j + 1)
    p = (1.0 - w) * lo + w * hi
    lobe = np.abs(wrap_angle(azimuth_rad)) <= half_angle_rad
    h_loss = np.clip(1.0 - reader.height_loss_per_m * np.maximum(np.abs(height_diff_m) - 0.1,
                                                                  0.0), 0.3, 1.0)
    v_loss = np.clip(1.0 - reader.speed_loss_per_m_s * np.maximum(speed_m_s - 1.0, 0.0),
                     0.5, 1.0)
    return np.asarray(np.where(lobe, p * h_loss * v_loss, 0.0), dtype=np.float64)


def _interp_rows_table(d: FloatArray, row: NDArray[np.int64]) -> FloatArray:
    """Piecewise-linear interpolation of table rows ``row`` at distances ``d`` (vectorized)."""
    k = np.clip(np.searchsorted(_TABLE_D_M, d, side="right") - 1, 0, len(_TABLE_D_M) - 2)
    f = (d - _TABLE_D_M[k]) / (_TABLE_D_M[k + 1] - _TABLE_D_M[k])
    return np.asarray((1 - f) * _TABLE_ETA[row, k] + f * _TABLE_ETA[row, k + 1],
                      dtype=np.float64)


def rfid_detections(tags: Sequence[RfidTag], reader: RfidReader, track: TrackSample,
                    rng: np.random.Generator) -> TagDetections | None:
    """Reads of the tags by the reader along the track (None when nothing was read)."""
    if not tags:
        return None
    tq = _query_times(track, reader.query_rate_hz, rng)
    xyz, heading, speed = track.at(tq)
    rpos = xyz + np.array([0.0, 0.0, reader.height_m])
    t_all, id_all = [], []
    for tag in tags:
        tp = np.asarray(tag.position)
        rel = rpos - tp  # tag -> reader
        dist = np.linalg.norm(rel, axis=1)
        near = dist <= 3.0
        if not np.any(near):
            continue
        az = np.arctan2(rel[near, 1], rel[near, 0]) - tag.lobe_orientation_rad
        to_tag = np.arctan2(-rel[near, 1], -rel[near, 0])
        phi = to_tag - (heading[near] + reader.yaw_offset_rad)
        p = rfid_detection_probability(dist[near], phi, az, tag.lobe_half_angle_rad,
                                       rel[near, 2], speed[near], reader)
        hit = rng.random(len(p)) < p
        t_all.append(tq[near][hit])
        id_all.append(np.full(int(hit.sum()), tag.id))
    if not t_all or sum(len(x) for x in t_all) == 0:
        return None
    t = np.concatenate(t_all)
    order = np.argsort(t, kind="stable")
    return TagDetections(t[order], np.concatenate(id_all)[order])


# --------------------------------------------------------------------------------------------
# Range-capable radio nodes (Inderst Sec. 4.3.3, 6.4)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class RangeModel:
    """Two-way ranging to nodes.

    Attributes
    ----------
    rate_hz: ranging attempts per node per second.
    sigma_m: 1-sigma Gaussian range noise independent of the distance, m.
    sigma_fraction: 1-sigma Gaussian range noise proportional to the true distance (0.02: 2 %);
        the two add in variance. ``ranges.csv`` reports ``sqrt(sigma_m^2 + (sigma_fraction
        r)^2)`` of the measured range ``r`` (what a radio's data sheet lets the agent compute).
    max_range_m: no measurement beyond this distance.
    nlos_bias_mean_m: mean of the exponential positive bias when the line of sight is blocked.
    walls: obstacles (shapely geometry); a segment crossing them is NLOS. None: always LOS.
    dropout_probability: probability that an attempt in range fails.
    agent_height_m: height of the agent's antenna above its floor-level position.
    """

    rate_hz: float = 1.0
    sigma_m: float = 0.3
    sigma_fraction: float = 0.0
    max_range_m: float = 5.0
    nlos_bias_mean_m: float = 1.0
    walls: BaseGeometry | None = None
    dropout_probability: float = 0.05
    agent_height_m: float = 1.0


@dataclass(frozen=True, slots=True)
class RangeDraw:
    """Readings of ranging attempts.

    Attributes
    ----------
    keep: which attempts gave a reading (eligible, within ``max_range_m``, not dropped), (N,).
    range_m: measured ranges of the kept attempts, m. sigma_m: their reported 1-sigma, m.
    """

    keep: NDArray[np.bool_]
    range_m: FloatArray
    sigma_m: FloatArray


def draw_ranges(*, distance_m: FloatArray, from_xy_m: FloatArray, to_xy_m: FloatArray,
                model: RangeModel, rng: np.random.Generator,
                eligible: NDArray[np.bool_] | None = None) -> RangeDraw:
    """Radio model of :class:`RangeModel` applied to attempts at true distances ``distance_m``.

    The one noise model of node ranges (:func:`range_measurements`) and inter-agent ranges
    (:func:`hrtls.sim.peers.peer_ranges`). Draws, in this order (a seeded simulation depends on
    it): a dropout uniform for every attempt; for the kept ones (if any) a standard normal,
    ``r = d + sqrt(sigma_m^2 + (sigma_fraction d)^2) N(0, 1)``; with ``walls`` and a positive
    ``nlos_bias_mean_m`` an exponential bias of that mean for each kept attempt, added where the
    segment ``from_xy_m -> to_xy_m`` (rows (N, 2), or one (2,) point) crosses the walls. The
    range is clipped at 0; the reported sigma is ``sqrt(sigma_m^2 + (sigma_fraction r)^2)``.
    """
    d = np.asarray(distance_m, dtype=np.float64)
    keep = (d <= model.max_range_m) & (rng.random(len(d)) >= model.dropout_probability)
    if eligible is not None:
        keep &= eligible
    n = int(keep.sum())
    if n == 0:
        return RangeDraw(keep, np.zeros(0), np.zeros(0))
    sd = np.hypot(model.sigma_m, model.sigma_fraction * d[keep])
    r = d[keep] + sd * rng.standard_normal(n)
    if model.walls is not None and model.nlos_bias_mean_m > 0:
        a = np.asarray(from_xy_m, dtype=np.float64)
        b = np.broadcast_to(np.asarray(to_xy_m, dtype=np.float64), a.shape)
        segs = shapely.linestrings(np.stack([a[keep], b[keep]], axis=1))
        r = r + shapely.intersects(segs, model.walls) * rng.exponential(model.nlos_bias_mean_m, n)
    r = np.maximum(r, 0.0)
    return RangeDraw(keep, r, np.hypot(model.sigma_m, model.sigma_fraction * r))


def range_measurements(nodes: Mapping[str, Sequence[float]], model: RangeModel,
                       track: TrackSample, rng: np.random.Generator
                       ) -> RangeMeasurements | None:
    """Range readings to the nodes within ``max_range_m`` (None when there are none)."""
    if not nodes:
        return None
    ids = list(nodes)
    pos = np.asarray([nodes[k] for k in ids], dtype=np.float64)
    tq = _query_times(track, model.rate_hz, rng)
    xyz, _, _ = track.at(tq)
    xyz[:, 2] += model.agent_height_m
    t_all, n_all, r_all, s_all = [], [], [], []
    for j in range(len(ids)):
        d = np.linalg.norm(xyz - pos[j], axis=1)
        got = draw_ranges(distance_m=d, from_xy_m=xyz[:, :2], to_xy_m=pos[j, :2], model=model,
                          rng=rng)
        if not np.any(got.keep):
            continue
        t_all.append(tq[got.keep])
        n_all.append(np.full(len(got.range_m), j))
        r_all.append(got.range_m)
        s_all.append(got.sigma_m)
    if not t_all:
        return None
    t = np.concatenate(t_all)
    order = np.argsort(t, kind="stable")
    return RangeMeasurements(t[order], np.asarray(ids)[np.concatenate(n_all)[order]],
                             np.concatenate(r_all)[order], np.concatenate(s_all)[order])


# --------------------------------------------------------------------------------------------
# Random wireless sensor networks (Inderst Sec. 6.4)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class WsnDeployment:
    """Nodes, which of them are anchors (known position), and the links within radio range.

    Attributes
    ----------
    ids: node ids. positions: true positions, (N, 2) or (N, 3), m.
    anchor: True for nodes whose position is known (seeds).
    radius: communication radius (same unit as positions).
    links: (M, 2) index pairs ``a < b`` within the radius.
    distance: measured link distances (true plus noise), (M,).
    """

    ids: list[str]
    positions: FloatArray
    anchor: NDArray[np.bool_]
    radius: float
    links: NDArray[np.int64]
    distance: FloatArray

    def to_json(self, *, truth: bool = False) -> dict[str, Any]:
        """The WSN JSON form ``{"radius", "nodes": [{"id", "anchor", "position"}], "links"}``.

        Positions of non-anchor nodes are ``null`` unless ``truth`` (then all are given).
        """
        nodes = []
        for i, k in enumerate(self.ids):
            known = truth or bool(self.anchor[i])
            nodes.append({"id": k, "anchor": bool(self.anchor[i]),
                          "position": [float(v) for v in self.positions[i]] if known else None})
        links = [{"a": self.ids[a], "b": self.ids[b], "distance": float(d)}
                 for (a, b), d in zip(self.links.tolist(), self.distance.tolist(), strict=True)]
        return {"radius": float(self.radius), "nodes": nodes, "links": links}


def disk_links(positions: FloatArray, radius: float) -> tuple[NDArray[np.int64], FloatArray]:
    """Index pairs ``a < b`` closer than ``radius`` and their true distances."""
    p = np.asarray(positions, dtype=np.float64)
    diff = p[:, None, :] - p[None, :, :]
    d = np.sqrt(np.sum(diff * diff, axis=2))
    a, b = np.nonzero(np.triu(d <= radius, k=1))
    return np.column_stack([a, b]).astype(np.int64), d[a, b]


def random_wsn(rng: np.random.Generator, *, n_nodes: int, region: BaseGeometry, radius: float,
               n_anchors: int = 3, anchor_mode: str = "corner", distance_sigma: float = 0.0,
               prefix: str = "n", z: float | None = None) -> WsnDeployment:
    """Nodes uniformly in ``region``; anchors nearest the lower-left corner or at random.

    ``distance_sigma`` is the 1-sigma noise of measured link distances; ``z`` adds a third
    coordinate when given.
    """
    if n_nodes < 1 or n_anchors < 0 or n_anchors > n_nodes or not radius > 0:
        raise InputError(f"n_nodes {n_nodes}, n_anchors {n_anchors}, radius {radius}",
                         where="random_wsn", expected="1 <= n_anchors <= n_nodes, radius > 0")
    minx, miny, maxx, maxy = region.bounds
    pts: list[FloatArray] = []
    while sum(len(p) for p in pts) < n_nodes:
        cand = np.column_stack([rng.uniform(minx, maxx, 4 * n_nodes),
                                rng.uniform(miny, maxy, 4 * n_nodes)])
        pts.append(cand[shapely.contains_xy(region, cand[:, 0], cand[:, 1])])
    xy = np.concatenate(pts)[:n_nodes]
    if anchor_mode == "corner":
        order = np.argsort(np.hypot(xy[:, 0] - minx, xy[:, 1] - miny))
    elif anchor_mode == "random":
        order = rng.permutation(n_nodes)
    else:
        raise InputError(f"anchor mode {anchor_mode!r}", where="anchor_mode",
                         expected="'corner' or 'random'")
    anchor = np.zeros(n_nodes, dtype=bool)
    anchor[order[:n_anchors]] = True
    positions = xy if z is None else np.column_stack([xy, np.full(n_nodes, z)])
    links, d = disk_links(xy, radius)
    if distance_sigma > 0:
        d = np.abs(d + rng.normal(0.0, distance_sigma, len(d)))
    ids = [f"{prefix}{i + 1}" for i in range(n_nodes)]
    return WsnDeployment(ids=ids, positions=positions, anchor=anchor, radius=radius,
                         links=links, distance=d)
