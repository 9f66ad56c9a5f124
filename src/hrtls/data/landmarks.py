"""Landmarks: the HRTLS location message (Inderst thesis Sec. 3.2).

A landmark (passive RFID tag, BLE beacon, radio node, camera, ...) tells a passing agent where it
is and how it can be passed: its position in the navigation frame or in WGS-84, its floor, the
bearings (directions of travel) that lead through it, the accuracy radius and the orientation of
its antenna lobe, its classification and when its information was last updated: a new version
during the mission (moved, destroyed, a hazard nearby) holds from that time on
(:mod:`hrtls.pipeline.landmark_updates`).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from hrtls.errors import InputError
from hrtls.frames import Georeference, wrap_angle

LandmarkKind = Literal["rfid", "beacon", "node", "anchor", "camera", "checkpoint", "other"]


class Wgs84(BaseModel):
    """WGS-84 coordinates: degrees and ellipsoidal height in m."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    lat: float = Field(ge=-90.0, le=90.0)
    lon: float = Field(ge=-180.0, le=360.0)
    alt: float = 0.0


class Landmark(BaseModel):
    """One location message.

    ``position`` is ``[x, y, z]`` in the navigation frame (m); ``wgs84`` is used when only
    geographic coordinates are known and becomes a position through the session's georeference
    (:meth:`resolved`). Angles are radians in the navigation frame (CCW from east).
    """

    model_config = ConfigDict(extra="allow", frozen=True)

    id: str = Field(min_length=1)
    kind: LandmarkKind = "other"
    position: tuple[float, float, float] | None = None
    wgs84: Wgs84 | None = None
    floor: int | None = None
    bearings_rad: tuple[float, ...] = ()
    accuracy_m: float | None = Field(default=None, gt=0.0)
    lobe_orientation_rad: float | None = None
    lobe_half_angle_rad: float | None = Field(default=None, gt=0.0, le=math.pi)
    classification: str | None = None
    updated: float | None = None
    """Time (s, session clock) from which this version holds; None: from the start."""
    status: Literal["active", "destroyed"] = "active"
    """A destroyed landmark corrects nothing from ``updated`` on."""
    hazard: str | None = Field(default=None, max_length=200)
    """A hazard reported near the landmark (for the people; the filter ignores it)."""

    @field_validator("position")
    @classmethod
    def _finite_position(cls, value: tuple[float, float, float] | None
                         ) -> tuple[float, float, float] | None:
        if value is not None and not all(math.isfinite(v) for v in value):
            raise ValueError("position must be finite [x, y, z] in m")
        return value

    @field_validator("bearings_rad")
    @classmethod
    def _wrap_bearings(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if not all(math.isfinite(v) for v in value):
            raise ValueError("bearings must be finite angles in rad")
        return tuple(float(v) for v in wrap_angle(np.asarray(value, dtype=float)))

    @model_validator(mode="after")
    def _has_location(self) -> Landmark:
        if self.position is None and self.wgs84 is None:
            raise ValueError("a landmark needs 'position' [x, y, z] or 'wgs84' {lat, lon, alt}")
        return self

    def resolved(self, georeference: Georeference | None) -> Landmark:
        """This landmark with ``position`` filled from ``wgs84`` through the georeference."""
        if self.position is not None:
            return self
        if georeference is None or self.wgs84 is None:
            raise InputError("landmark has only WGS-84 coordinates", where=f"landmark {self.id!r}",
                             expected="a georeference in session.json to place it")
        xyz = georeference.from_wgs84(self.wgs84.lat, self.wgs84.lon, self.wgs84.alt)[0]
        return self.model_copy(update={"position": (float(xyz[0]), float(xyz[1]),
                                                    float(xyz[2]))})

    def xyz(self) -> np.ndarray:
        """Position as a float array [x, y, z] (call :meth:`resolved` first if only WGS-84)."""
        if self.position is None:
            raise InputError("landmark has no local position", where=f"landmark {self.id!r}",
                             expected="position [x, y, z], or resolve it with a georeference")
        return np.asarray(self.position, dtype=np.float64)
