"""Cut a session into time chunks, as the live service receives it.

:func:`session_window` keeps the samples and observations with ``t_start <= t < t_end``
(metadata, landmarks and ground truth stay whole); :func:`split_session` cuts a whole session
into consecutive windows of ``chunk_s`` seconds. Feeding the windows to
:meth:`hrtls.pipeline.Tracker.update` one after the other gives the offline result.

A gyroscope or magnetometer with its own timestamps is first resampled onto the accelerometer
times over the whole session (as :meth:`hrtls.data.ImuStream.aligned` does offline), the way a
live device delivers aligned samples; interpolating inside each window would differ at the
window edges.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from hrtls.data import Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.errors import InputError


def _mask(t: np.ndarray, t_start: float, t_end: float) -> np.ndarray:
    return np.asarray((t >= t_start) & (t < t_end))


def aligned_imu(imu: ImuStream) -> ImuStream:
    """The stream with gyroscope and magnetometer on the accelerometer's timestamps."""
    t, _, gyr, mag = imu.aligned()
    return ImuStream(imu.accel,
                     None if gyr is None else SensorSeries(t, gyr, "gyroscope"),
                     None if mag is None else SensorSeries(t, mag, "magnetometer"),
                     check_units=False)


def session_window(session: Session, t_start: float, t_end: float) -> Session | None:
    """The part of ``session`` with ``t_start <= t < t_end`` (None when nothing is in it)."""
    parts: dict[str, object] = {}
    imu = session.imu
    parts["imu"] = None
    if imu is not None:
        sub = imu.between(t_start, t_end)
        parts["imu"] = sub if len(sub.accel.t) else None
    o = session.orientation
    parts["orientation"] = None
    if o is not None:
        m = _mask(o.t, t_start, t_end)
        parts["orientation"] = OrientationSeries(o.t[m], o.q[m], o.name) if m.any() else None
    p = session.pressure
    parts["pressure"] = None if p is None else (p.between(t_start, t_end)
                                                if _mask(p.t, t_start, t_end).any() else None)
    f = session.fixes
    parts["fixes"] = None
    if f is not None and (m := _mask(f.t, t_start, t_end)).any():
        parts["fixes"] = PositionFixes(f.t[m], f.xyz[m], f.sigma_m[m], f.has_z)
    r = session.rss
    parts["rss"] = None
    if r is not None and (m := _mask(r.t, t_start, t_end)).any():
        parts["rss"] = RssReadings(r.t[m], r.anchor[m], r.rss_dbm[m])
    g = session.tags
    parts["tags"] = None
    if g is not None and (m := _mask(g.t, t_start, t_end)).any():
        parts["tags"] = TagDetections(g.t[m], g.tag[m])
    n = session.ranges
    parts["ranges"] = None
    if n is not None and (m := _mask(n.t, t_start, t_end)).any():
        parts["ranges"] = RangeMeasurements(n.t[m], n.node[m], n.range_m[m], n.sigma_m[m])
    if all(parts[k] is None for k in ("imu", "fixes", "rss", "tags", "ranges")):
        return None
    return session.with_parts(**parts)


def split_session(session: Session, chunk_s: float) -> Iterator[Session]:
    """Consecutive windows of ``chunk_s`` seconds covering the session (empty ones skipped)."""
    if not (math.isfinite(chunk_s) and chunk_s > 0):
        raise InputError(f"{chunk_s}", where="chunk_s", expected="a duration > 0 s")
    if session.imu is not None:
        session = session.with_parts(imu=aligned_imu(session.imu))
    t0, t1 = session.time_span()
    k = 0
    while t0 + k * chunk_s <= t1:
        part = session_window(session, t0 + k * chunk_s, t0 + (k + 1) * chunk_s)
        if part is not None:
            yield part
        k += 1
