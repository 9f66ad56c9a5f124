"""Scheduling of the tracker's events: buffers, grouping of RSS scans and tag reads, horizon.

Two queues hold the events not yet applied, in the order (time, kind, arrival):

- a heap of *slow* events handled one at a time in Python (tag groups, bearings, fixes the
  loop cannot apply, and with the velocity-driven prediction every observation);
- sorted columns of *fast* rows for the compiled loop (:mod:`hrtls.pipeline._events`): steps,
  tight RSS readings or scans, ranges, position fixes.

Tag reads and RSS readings wait until their grouping window has closed (windows run from the
session start, so a chunked run closes the same windows as an offline run); events wait until
the gait stage can no longer release a step before them (the horizon).
"""

from __future__ import annotations

import heapq
import math
from typing import Any

import numpy as np

from hrtls.data import Landmark, Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.fusion.rss_scans import average_rss_per_anchor, scan_table
from hrtls.fusion.shadowing import ShadowingMemory
from hrtls.fusion.tags import group_detections
from hrtls.pipeline import _events as ev
from hrtls.pipeline._fix_events import fixes_in_loop
from hrtls.pipeline.build import Notes
from hrtls.pipeline.config import TrackerConfig

# event kinds in the order they are applied when they share a time
STEP, FIX, RSS, TAGS, RANGE, BEARING, MAGNETIC = 0, 1, 2, 3, 4, 5, 6
SCAN_ROWS_TRIM = 4096
"""Stored anchors of queued RSS scans are trimmed once there are this many (rows)."""


class PoseGate:
    """Position starts at the start pose's time: what came before is counted, not used."""

    def __init__(self, t_pose: float) -> None:
        self.t_pose = t_pose
        self.ignored: dict[str, int] = {}

    def keep(self, what: str, t: np.ndarray) -> np.ndarray:
        """Mask of the times at or after the start pose's time; counts the others."""
        keep = np.asarray(t, dtype=np.float64) >= self.t_pose
        n = int(len(keep) - np.count_nonzero(keep))
        if n:
            self.ignored[what] = self.ignored.get(what, 0) + n
        return keep

    def observations(self, chunk: Session) -> Session:
        """The chunk's observations at or after the start pose's time."""
        parts: dict[str, Any] = {}
        f = chunk.fixes
        if f is not None and not (m := self.keep("fixes", f.t)).all():
            parts["fixes"] = PositionFixes(f.t[m], f.xyz[m], f.sigma_m[m], f.has_z) \
                if m.any() else None
        r = chunk.rss
        if r is not None and not (m := self.keep("rss", r.t)).all():
            parts["rss"] = RssReadings(r.t[m], r.anchor[m], r.rss_dbm[m]) if m.any() else None
        g = chunk.tags
        if g is not None and not (m := self.keep("tags", g.t)).all():
            parts["tags"] = TagDetections(g.t[m], g.tag[m]) if m.any() else None
        n = chunk.ranges
        if n is not None and not (m := self.keep("ranges", n.t)).all():
            parts["ranges"] = RangeMeasurements(n.t[m], n.node[m], n.range_m[m],
                                                n.sigma_m[m]) if m.any() else None
        return chunk.with_parts(**parts) if parts else chunk


def chunk_end(chunk: Session) -> float:
    """Latest time of the chunk's sensor streams and observations (not its ground truth)."""
    ends = [float(part.t[-1]) for part in (chunk.fixes, chunk.rss, chunk.tags, chunk.ranges)
            if part is not None and len(part.t)]
    if chunk.imu is not None and len(chunk.imu.accel.t):
        ends.append(float(chunk.imu.accel.t[-1]))
    return max(ends) if ends else -math.inf


class EventSchedule:
    """Queued events of one tracker, released in time order up to a horizon.

    Parameters
    ----------
    config: the tracker's configuration (which observations, grouping windows).
    landmarks: resolved landmarks (positions of anchors and nodes).
    t0: session start (origin of the grouping windows), s.
    slow_only: queue every observation as a slow event (the velocity-driven prediction).
    tag_window_s: grouping window of tag reads, s.
    """

    STATE = ("pending", "seq", "horizon", "bulk_count", "labels", "tag_t", "tag_id",
             "scan_t", "scan_a", "scan_v", "scan_rows", "scan_base", "avg_t", "avg_a",
             "avg_v", "seen_obs", "rss_note", "rss_last_t")
    """Plain attributes of the schedule's state (snapshot); plus the buffer from ``i``."""
    fixes_in_loop = True
    """Position fixes as rows of the compiled loop where it can apply them
    (:func:`hrtls.pipeline._fix_events.fixes_in_loop`); False: every fix through Python."""
    BULK = ("bulk_t", "bulk_k", "bulk_seq", "bulk_ev", "bulk_data", "bulk_src", "bulk_label")

    def __init__(self, config: TrackerConfig, landmarks: dict[str, Landmark], *, t0: float,
                 slow_only: bool, tag_window_s: float) -> None:
        self.config = config
        self.landmarks = landmarks
        self.t0 = t0
        self.slow_only = slow_only
        self.tag_window_s = tag_window_s
        self.pending: list[tuple[float, int, int, Any]] = []
        self.seq = 0
        self.horizon = -math.inf
        self.bulk_t = np.zeros(0)
        self.bulk_k = np.zeros(0, dtype=np.int64)
        self.bulk_seq = np.zeros(0, dtype=np.int64)
        self.bulk_ev = np.zeros(0, dtype=np.int64)
        self.bulk_data = np.zeros((0, 5))
        self.bulk_src = np.zeros(0, dtype=str)
        # diagnostics (kind, reason) of each buffer row, as codes into label_kind/reason
        self.bulk_label = np.zeros(0, dtype=np.int64)
        self.labels: dict[tuple[str, str], int] = {}
        self.label_kind = np.zeros(0, dtype=object)
        self.label_reason = np.zeros(0, dtype=object)
        self.i = 0
        self.bulk_count = 0
        self.tag_t = np.zeros(0)
        self.tag_id = np.zeros(0, dtype=str)
        self.scan_t = np.zeros(0)
        self.scan_a = np.zeros(0, dtype=str)
        self.scan_v = np.zeros(0)
        self.scan_rows = np.zeros((0, 4))     # anchors of queued scans (kernel SC_* columns)
        self.scan_base = 0                    # absolute index of scan_rows[0]
        self.avg_t = np.zeros(0)
        self.avg_a = np.zeros(0, dtype=str)
        self.avg_v = np.zeros(0)
        self.seen_obs = False
        self.rss_note = False
        self.rss_last_t: dict[str, float] = {}   # ShadowingMemory.last_t of tight readings

    # ------------------------------------------------------------------ queueing
    def push(self, t: float, kind: int, payload: Any) -> None:
        """A slow event."""
        self.seq += 1
        heapq.heappush(self.pending, (t, kind, self.seq, payload))

    def observations(self, chunk: Session, notes: Notes, *, channel_estimated: bool,
                     has_channel: bool) -> None:
        """Queue the chunk's observations (already from the start pose on)."""
        cfg = self.config
        self.seen_obs = self.seen_obs or any(
            part is not None for part in (chunk.fixes, chunk.rss, chunk.tags, chunk.ranges))
        if chunk.fixes is not None and cfg.fixes.enabled:
            f = chunk.fixes
            if self.fixes_in_loop and fixes_in_loop(cfg, slow_only=self.slow_only):
                n = len(f)
                data = np.full((n, 5), np.nan)
                data[:, :3] = f.xyz
                data[:, 3] = f.sigma_m
                self.add_rows(FIX, np.asarray(f.t, dtype=np.float64),
                              np.full(n, ev.EV_FIX, dtype=np.int64), data,
                              np.full(n, "", dtype=str))
            else:
                for i in range(len(f)):
                    self.push(float(f.t[i]), FIX, (f.xyz[i], float(f.sigma_m[i]), f.has_z))
        if chunk.rss is not None and cfg.rss.mode != "off":
            if not has_channel and not self.rss_note:
                self.rss_note = True
                notes.add("no channel model in session.json: RSS starts from A = -59 dBm, eta "
                          "= 2" + (" and re-estimates them online" if channel_estimated
                                   else ""))
            r = chunk.rss
            if cfg.rss.mode == "tight":
                keep = r.rss_dbm >= cfg.rss.sensitivity_dbm
                if cfg.rss.average_s > 0:
                    self.avg_t = np.concatenate([self.avg_t, r.t[keep]])
                    self.avg_a = np.concatenate([self.avg_a, r.anchor[keep].astype(str)])
                    self.avg_v = np.concatenate([self.avg_v, r.rss_dbm[keep]])
                else:
                    self._queue_tight(r.t[keep], r.anchor[keep].astype(str), r.rss_dbm[keep])
            else:
                self.scan_t = np.concatenate([self.scan_t, r.t])
                self.scan_a = np.concatenate([self.scan_a, r.anchor.astype(str)])
                self.scan_v = np.concatenate([self.scan_v, r.rss_dbm])
        end = chunk_end(chunk)
        if cfg.rss.mode in ("wls", "kalman"):
            self.flush_scans(end)
        self.flush_averages(end)
        if chunk.tags is not None and cfg.tags.enabled:
            g = chunk.tags
            self.tag_t = np.concatenate([self.tag_t, g.t])
            self.tag_id = np.concatenate([self.tag_id, g.tag.astype(str)])
        self.flush_tag_groups(end)
        if chunk.ranges is not None and cfg.ranges.enabled:
            rm = chunk.ranges
            if self.slow_only:
                for i in range(len(rm)):
                    self.push(float(rm.t[i]), RANGE, (str(rm.node[i]), float(rm.range_m[i]),
                                                      float(rm.sigma_m[i])))
            else:
                self._add_bulk(RANGE, rm.t, rm.node.astype(str), rm.range_m, rm.sigma_m)

    def steps(self, t_end: np.ndarray, rows: np.ndarray) -> None:
        """Steps for the compiled loop: rows (length, heading, dz, activity, nan)."""
        n = len(t_end)
        self.add_rows(STEP, np.asarray(t_end, dtype=np.float64),
                      np.full(n, ev.EV_STEP, dtype=np.int64), rows, np.full(n, "", dtype=str))

    def _queue_tight(self, t: np.ndarray, anchor: np.ndarray, rss_dbm: np.ndarray) -> None:
        """Queue RSS readings for tight (per-reading) updates with their information fraction.

        The fraction (:mod:`hrtls.fusion.shadowing`) depends on the time since the previous
        reading of the same beacon, remembered across chunks in ``rss_last_t``.
        """
        memory = ShadowingMemory(self.rss_last_t)
        w = memory.fractions(t, anchor, tau_s=self.config.rss.shadowing_time_s)
        if self.slow_only:
            for k in range(len(t)):
                self.push(float(t[k]), RSS, ("reading", str(anchor[k]), float(rss_dbm[k]),
                                             float(w[k])))
        else:
            self._add_bulk(RSS, t, anchor, rss_dbm, w)

    def flush_averages(self, t_seen: float) -> None:
        """Queue the per-beacon RSS means of the ``average_s`` windows that have closed."""
        if len(self.avg_t) == 0:
            return
        w = self.config.rss.average_s
        if math.isfinite(t_seen):
            end_bin = math.floor((t_seen - self.t0) / w)
            done = np.floor((self.avg_t - self.t0) / w) < end_bin
        else:
            done = np.ones(len(self.avg_t), dtype=bool)
        if not done.any():
            return
        avg = average_rss_per_anchor(
            RssReadings(self.avg_t[done], self.avg_a[done], self.avg_v[done]), w,
            t_origin=self.t0)
        self._queue_tight(avg.t, avg.anchor.astype(str), avg.rss_dbm)
        self.avg_t = self.avg_t[~done]
        self.avg_a = self.avg_a[~done]
        self.avg_v = self.avg_v[~done]

    def _add_bulk(self, kind: int, t: np.ndarray, src: np.ndarray, value: np.ndarray,
                  sigma: np.ndarray) -> None:
        """Queue tight RSS readings or ranges as sorted columns (no per-reading Python)."""
        n = len(t)
        if n == 0:
            return
        ev_kind = np.full(n, ev.EV_RSS if kind == RSS else ev.EV_RANGE, dtype=np.int64)
        data = np.full((n, 5), np.nan)
        data[:, 3] = value
        data[:, 4] = sigma
        names, inv = np.unique(src, return_inverse=True)
        for j, name in enumerate(names.tolist()):
            lm = self.landmarks.get(name)
            rows = inv == j
            if lm is None or lm.position is None:
                ev_kind[rows] = ev.EV_SKIP
            else:
                data[rows, :3] = lm.xyz()
        self.add_rows(kind, np.asarray(t, dtype=np.float64), ev_kind, data, src)

    def add_rows(self, kind: int, t: np.ndarray, ev_kind: np.ndarray, data: np.ndarray,
                 src: np.ndarray, reason: np.ndarray | None = None) -> None:
        """Merge rows of the compiled loop into the sorted buffer (order: t, kind, arrival).

        ``reason``: text of the rows' diagnostics when skipped (default: the unknown
        anchor/node text on ``EV_SKIP`` rows).
        """
        n = len(t)
        i0 = self.i
        name = {RSS: "rss", RANGE: "range", FIX: "fix"}.get(kind, "")
        label = np.full(n, self._label(name, ""), dtype=np.int64)
        if reason is None:
            skip = ev_kind == ev.EV_SKIP
            if skip.any():
                label[skip] = self._label(name, "anchor without a known position"
                                          if kind == RSS else "node without a known position")
        else:
            reason = np.asarray(reason, dtype=object)
            for text in set(reason.tolist()) - {""}:
                label[reason == text] = self._label(name, str(text))
        seq = self.bulk_count + np.arange(n)
        self.bulk_count += n
        bt = np.concatenate([self.bulk_t[i0:], t])
        bk = np.concatenate([self.bulk_k[i0:], np.full(n, kind, dtype=np.int64)])
        bs = np.concatenate([self.bulk_seq[i0:], seq])
        order = np.lexsort((bs, bk, bt))
        self.bulk_t = bt[order]
        self.bulk_k = bk[order]
        self.bulk_seq = bs[order]
        self.bulk_ev = np.concatenate([self.bulk_ev[i0:], ev_kind])[order]
        self.bulk_data = np.concatenate([self.bulk_data[i0:], data])[order]
        self.bulk_src = np.concatenate([self.bulk_src[i0:], src])[order]
        self.bulk_label = np.concatenate([self.bulk_label[i0:], label])[order]
        self.i = 0

    def _label(self, kind: str, reason: str) -> int:
        """Code of a (diagnostics kind, reason) pair of buffer rows."""
        code = self.labels.get((kind, reason))
        if code is None:
            code = len(self.labels)
            self.labels[(kind, reason)] = code
            self.label_kind = np.array([*self.label_kind.tolist(), kind], dtype=object)
            self.label_reason = np.array([*self.label_reason.tolist(), reason], dtype=object)
        return code

    # ------------------------------------------------------------------ grouping
    def flush_tag_groups(self, t_seen: float) -> None:
        """Group tag reads whose grouping window has closed (the same in chunked runs)."""
        if len(self.tag_t) == 0:
            return
        w = self.tag_window_s
        groups = group_detections(TagDetections(self.tag_t, self.tag_id), w)
        used = 0
        for t, ids in groups:
            first = float(self.tag_t[used])
            if first + w >= t_seen:
                break
            self.push(t, TAGS, ids)
            used = int(np.searchsorted(self.tag_t, first + w, side="right"))
        self.tag_t = self.tag_t[used:]
        self.tag_id = self.tag_id[used:]

    def _take_closed_scans(self, t_seen: float) -> RssReadings | None:
        """Remove and return the buffered RSS readings whose window closed before ``t_seen``."""
        if len(self.scan_t) == 0:
            return None
        n = len(self.scan_t)
        if math.isfinite(t_seen):
            w = self.config.rss.window_s
            end_bin = math.floor((t_seen - self.t0) / w)
            n = int(np.count_nonzero(np.floor((self.scan_t - self.t0) / w) < end_bin))
        if n == 0:
            return None
        readings = RssReadings(self.scan_t[:n], self.scan_a[:n], self.scan_v[:n])
        self.scan_t = self.scan_t[n:]
        self.scan_a = self.scan_a[n:]
        self.scan_v = self.scan_v[n:]
        return readings

    def flush_scans(self, t_seen: float) -> None:
        """Average RSS over windows of ``window_s`` from the session start once they closed."""
        readings = self._take_closed_scans(t_seen)
        if readings is None:
            return
        table = scan_table(readings, self.landmarks, window_s=self.config.rss.window_s,
                           sensitivity_dbm=self.config.rss.sensitivity_dbm, t_origin=self.t0)
        if self.slow_only:
            for scan in table.scans():
                self.push(scan.t, RSS, ("scan", scan))
        elif len(table):
            # compiled loop: rows [first anchor row (absolute), number of anchors]
            start = self.scan_base + len(self.scan_rows)
            self.scan_rows = np.concatenate([self.scan_rows, np.column_stack(
                [table.anchor_xyz[:, :2], table.rss_dbm, table.n_readings])])
            data = np.full((len(table), 5), np.nan)
            data[:, 0] = start + table.first
            data[:, 1] = table.count
            src = np.array([",".join(table.anchor[a:a + c].tolist())
                            for a, c in zip(table.first.tolist(), table.count.tolist(),
                                            strict=True)], dtype=str)
            reason = np.full(len(table), "", dtype=object)
            few = np.flatnonzero(table.count < 3)
            reason[few] = [f"{c} anchors heard (WLS needs 3)" for c in table.count[few].tolist()]
            self.add_rows(RSS, table.t, np.full(len(table), ev.EV_SCAN, dtype=np.int64),
                          data, src, reason)

    def flush_all(self) -> None:
        """End of the recording: every window is closed."""
        self.flush_tag_groups(math.inf)
        self.flush_scans(math.inf)
        self.flush_averages(math.inf)

    def release_limit(self) -> float:
        """Events up to this time may be applied: the horizon, before any open group."""
        limit = self.horizon
        for buf in (self.tag_t, self.scan_t, self.avg_t):
            if len(buf):
                limit = min(limit, float(np.nextafter(buf[0], -np.inf)))
        return limit

    # ------------------------------------------------------------------ release
    def next_slow(self, horizon: float) -> tuple[float, int, int, Any] | None:
        """The next event if it is slow and due before the next fast row (removed), else None.

        Call :meth:`fast_run` when this gives None and :meth:`has_fast` holds.
        """
        pending = self.pending
        head = pending[0] if pending and pending[0][0] <= horizon else None
        if head is None:
            return None
        bi = self.i
        if not self.has_fast(horizon) or (head[0], head[1]) < (float(self.bulk_t[bi]),
                                                               int(self.bulk_k[bi])):
            return heapq.heappop(pending)
        return None

    def has_fast(self, horizon: float) -> bool:
        """A fast row is due up to ``horizon``."""
        return self.i < len(self.bulk_t) and self.bulk_t[self.i] <= horizon

    def fast_run(self, horizon: float) -> tuple[int, int]:
        """Buffer rows ``[b0, b1)`` up to the next slow event (or the horizon); consumed."""
        bi = self.i
        pending = self.pending
        if pending and pending[0][0] <= horizon:
            lim_t, lim_k = pending[0][0], pending[0][1]
            j = int(np.searchsorted(self.bulk_t, lim_t, side="left"))
            j2 = int(np.searchsorted(self.bulk_t, lim_t, side="right"))
            j += int(np.count_nonzero(self.bulk_k[j:j2] < lim_k))
        else:
            j = int(np.searchsorted(self.bulk_t, horizon, side="right"))
        j = max(j, bi + 1)
        self.i = j
        return bi, j

    def trim_scan_rows(self) -> None:
        """Drop the stored scan anchors that no queued scan (rows from ``i``) needs."""
        if len(self.scan_rows) < SCAN_ROWS_TRIM:
            return
        b1 = self.i
        pending = np.flatnonzero(self.bulk_ev[b1:] == ev.EV_SCAN)
        keep_from = (int(self.bulk_data[b1:][pending, 0].min()) if len(pending)
                     else self.scan_base + len(self.scan_rows))
        drop = keep_from - self.scan_base
        if drop > 0:
            self.scan_rows = self.scan_rows[drop:]
            self.scan_base = keep_from

    # ------------------------------------------------------------------ snapshot
    def state(self) -> dict[str, Any]:
        """Plain state (the buffer from the first row not yet applied)."""
        out = {name: getattr(self, name) for name in self.STATE}
        out.update({name: getattr(self, name)[self.i:] for name in self.BULK})
        out["label_kind"] = self.label_kind
        out["label_reason"] = self.label_reason
        return out

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state`."""
        for name in (*self.STATE, *self.BULK):
            # rss_last_t: absent from snapshots made before the shadowing discount
            setattr(self, name, state.get(name, {}) if name == "rss_last_t" else state[name])
        self.i = 0
        self.label_kind = np.asarray(state["label_kind"], dtype=object)
        self.label_reason = np.asarray(state["label_reason"], dtype=object)
