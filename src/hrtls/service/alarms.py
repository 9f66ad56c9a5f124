"""Alarms and events of one agent: PASS no-motion, fall, silence, uncertainty, floor, zones, SOS.

Motion is judged from the IMU (not from the position): a batch window moves when the spread
of the accelerometer norm or the gyroscope rate exceeds a threshold. The PASS pre-alarm and
alarm follow the mission's ``alarm_profile`` (20 s / 30 s by default, as PASS devices); a fall is
an impact above ``impact_ms2`` followed by ``fall_still_s`` without motion.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.service.batches import Batch


@dataclass(frozen=True)
class MotionParams:
    """Thresholds of the IMU motion test."""

    acc_std_ms2: float = 0.25
    gyro_rad_s: float = 0.35
    window_s: float = 1.0
    impact_ms2: float = 29.4
    fall_still_s: float = 5.0


@dataclass(frozen=True)
class AlarmProfile:
    """The mission's thresholds (``alarm_profile`` of the contract)."""

    prealarm_s: float = 20.0
    alarm_s: float = 30.0
    silent_s: float = 15.0
    sigma_alarm_m: float = 5.0


@dataclass
class Raised:
    """An event to store and push: kind, severity, time, detail; ``clears`` ends an open one."""

    kind: str
    severity: str
    t: float
    detail: dict[str, Any] = field(default_factory=dict)
    clears: str | None = None


def moving_windows(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
                   params: MotionParams) -> tuple[np.ndarray, np.ndarray]:
    """End times of the ``window_s`` windows of a batch and whether each one moves."""
    edges = np.arange(t[0], t[-1] + params.window_s, params.window_s)
    idx = np.searchsorted(t, edges)
    norm = np.linalg.norm(acc, axis=1)
    ends, moving = [], []
    for i0, i1 in itertools.pairwise(idx):
        if i1 - i0 < 2:
            continue
        m = float(np.std(norm[i0:i1])) > params.acc_std_ms2
        if gyr is not None:
            m = m or float(np.max(np.linalg.norm(gyr[i0:i1], axis=1))) > params.gyro_rad_s
        ends.append(float(t[i1 - 1]))
        moving.append(m)
    return np.asarray(ends), np.asarray(moving, dtype=bool)


@dataclass
class AgentAlarms:
    """Alarm state of one agent (fed in time order; back-filled data are not re-judged)."""

    profile: AlarmProfile
    motion: MotionParams = field(default_factory=MotionParams)
    t_judged: float = -math.inf
    last_motion_t: float | None = None
    impact_t: float | None = None
    open: set[str] = field(default_factory=set)
    floor: int | None = None
    zone: str | None = None

    def _open(self, kind: str, severity: str, t: float, detail: dict[str, Any]) -> list[Raised]:
        if kind in self.open:
            return []
        self.open.add(kind)
        return [Raised(kind, severity, t, detail)]

    def _close(self, kind: str, t: float) -> list[Raised]:
        if kind not in self.open:
            return []
        self.open.discard(kind)
        return [Raised(kind, "info", t, clears=kind)]

    def on_batch(self, batch: Batch) -> list[Raised]:
        """Judge the IMU of a new batch (and its SOS flag)."""
        out: list[Raised] = []
        span = batch.time_span()
        if batch.sos:
            out.append(Raised("sos", "alarm", span[1] if span else self.t_judged, {}))
        imu = batch.imu
        if imu is None or imu.t[0] <= self.t_judged:
            return out
        t = np.asarray(imu.t)
        acc = np.asarray(imu.acc)
        gyr = None if imu.gyr is None else np.asarray(imu.gyr)
        peak = np.linalg.norm(acc, axis=1)
        if float(peak.max()) > self.motion.impact_ms2:
            self.impact_t = float(t[int(np.argmax(peak))])
        ends, moving = moving_windows(t, acc, gyr, self.motion)
        for t_end, m in zip(ends, moving, strict=False):
            if self.last_motion_t is None:
                self.last_motion_t = t_end
            after_impact = self.impact_t is not None and t_end > self.impact_t + 1.0
            if m:
                self.last_motion_t = t_end
                if after_impact:   # moving again after the impact: no fall (or it ended)
                    self.impact_t = None
                    out += self._close("fall", t_end)
                out += self._close("pass_alarm", t_end) + self._close("pass_prealarm", t_end)
                continue
            still = t_end - self.last_motion_t
            if still >= self.profile.alarm_s:
                out += self._close("pass_prealarm", t_end)
                out += self._open("pass_alarm", "alarm", t_end, {"still_s": still})
            elif still >= self.profile.prealarm_s:
                out += self._open("pass_prealarm", "warning", t_end, {"still_s": still})
            if self.impact_t is not None and t_end - self.impact_t >= self.motion.fall_still_s:
                out += self._open("fall", "alarm", t_end, {"impact_t": self.impact_t})
        self.t_judged = float(t[-1])
        return out

    def on_estimate(self, est: dict[str, Any], zones: list[tuple[str, int, Any]]) -> list[Raised]:
        """Judge a new estimate: uncertainty, floor change, zone enter/leave."""
        out: list[Raised] = []
        t = float(est["t"])
        c = est["cov_xy"]
        tr, det = c[0][0] + c[1][1], c[0][0] * c[1][1] - c[0][1] * c[1][0]
        radius = 2.0 * math.sqrt(max(0.0, 0.5 * tr + math.sqrt(max(0.0, 0.25 * tr * tr - det))))
        if radius > self.profile.sigma_alarm_m:
            out += self._open("uncertainty", "warning", t, {"radius_2sigma_m": radius})
        else:
            out += self._close("uncertainty", t)
        floor = int(est["floor"])
        if self.floor is not None and floor != self.floor:
            out.append(Raised("floor_change", "info", t, {"from": self.floor, "to": floor}))
        self.floor = floor
        zone = zone_of(est["x"], est["y"], floor, zones)
        if zone != self.zone:
            if self.zone is not None:
                out.append(Raised("zone_leave", "info", t, {"zone": self.zone}))
            if zone is not None:
                out.append(Raised("zone_enter", "info", t, {"zone": zone}))
            self.zone = zone
        return out

    def on_silence(self, t_now: float, silent_for_s: float | None) -> list[Raised]:
        """The agent sent nothing for ``silent_for_s`` (None: it is sending)."""
        if silent_for_s is not None and silent_for_s >= self.profile.silent_s:
            return self._open("silent", "alarm", t_now, {"silent_s": silent_for_s})
        if silent_for_s is None:
            return self._close("silent", t_now)
        return []


def zones_of(floors: list[tuple[int, dict[str, Any] | None]]) -> list[tuple[str, int, Any]]:
    """Named polygons (room, corridor, stairs, zone) of the plans: ``(name, floor, shape)``."""
    from shapely.geometry import shape
    from shapely.prepared import prep

    out = []
    for index, plan in floors:
        if not plan:
            continue
        for i, f in enumerate(plan.get("features", [])):
            props = f.get("properties") or {}
            if props.get("kind") not in ("room", "corridor", "stairs", "zone"):
                continue
            geom = shape(f["geometry"])
            if geom.geom_type not in ("Polygon", "MultiPolygon"):
                continue
            out.append((str(props.get("name") or f"{props['kind']} {i}"), index, prep(geom)))
    return out


def zone_of(x: float, y: float, floor: int, zones: list[tuple[str, int, Any]]) -> str | None:
    """The first zone of ``floor`` containing the point (None outside all)."""
    from shapely.geometry import Point

    p = Point(x, y)
    for name, index, geom in zones:
        if index == floor and geom.contains(p):
            return name
    return None
