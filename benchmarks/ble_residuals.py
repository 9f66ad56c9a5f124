"""Diagnosis of the BLE RSSI set: RSS residuals against the channel at the TRUE distance.

Scoring / analysis only (reads the truth; nothing here feeds the estimator). For each track,
the residual ``r = rss - (A - 10 eta log10(d))`` of every reading (``d``: true horizontal
distance, at least 1 m; channel: the session's default) is split into

* a per-beacon (receiver) constant: the mean residual of each receiver on each track, and how
  much of the residual variance it explains; its consistency across tracks;
* a body-shadowing term: the mean residual against the angle between the walking direction
  (from the truth, over 1 s) and the direction from the walker to the receiver, in 45 degree
  bins (0: walking towards the receiver; 180: the receiver behind the walker's back);
* a time lag: the lag (0 ... 3 s) that maximises the correlation of the RSS with the model
  at the true distance;
* the residual autocorrelation time of each receiver (readings within 0.5 s vs 2 s).

Run: ``python benchmarks/ble_residuals.py``.
"""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np

from hrtls.data.session import ChannelModel
from hrtls.datasets.ble_rssi import BleRssiTrajectory, load_trajectory

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "ble_rssi"
TRACKS = ("rectangular_with_rotation", "rectangular_without_rotation", "straight_01",
          "straight_02", "straight_03")
BINS_DEG = np.arange(0, 181, 45)


def model_rss(tr: BleRssiTrajectory, ch: ChannelModel, t_shift_s: float = 0.0) -> np.ndarray:
    """Channel mean at the true horizontal distance at ``t - t_shift_s``, dBm."""
    pos = np.array([tr.receivers[a].xyz[:2] for a in tr.anchor.tolist()])
    t = tr.t - t_shift_s
    xy = np.column_stack([np.interp(t, tr.t, tr.beacon_xyz[:, k]) for k in (0, 1)])
    d = np.maximum(np.linalg.norm(xy - pos, axis=1), 1.0)
    return np.asarray(ch.a_dbm - 10.0 * ch.eta * np.log10(d))


def relative_bearing_deg(tr: BleRssiTrajectory) -> tuple[np.ndarray, np.ndarray]:
    """Angle between walking direction and the direction to the receiver, deg; speed m/s."""
    t, xy = tr.t, tr.beacon_xyz[:, :2]
    ahead = np.column_stack([np.interp(t + 0.5, t, xy[:, k]) for k in (0, 1)])
    behind = np.column_stack([np.interp(t - 0.5, t, xy[:, k]) for k in (0, 1)])
    v = ahead - behind
    speed = np.linalg.norm(v, axis=1)
    pos = np.array([tr.receivers[a].xyz[:2] for a in tr.anchor.tolist()])
    to_rx = pos - xy
    cos = np.sum(v * to_rx, axis=1) / np.maximum(speed * np.linalg.norm(to_rx, axis=1), 1e-9)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), speed


def report(tr: BleRssiTrajectory, ch: ChannelModel) -> dict[str, float]:
    """Print the split of one track's residuals; per-receiver means returned."""
    r = tr.rss_dbm - model_rss(tr, ch)
    print(f"\n== {tr.name}: {len(r)} readings, {tr.t[-1]:.0f} s; residual mean {r.mean():+.1f}"
          f" dB, std {r.std():.1f} dB")
    means = {}
    fitted = np.zeros_like(r)
    for a in sorted(set(tr.anchor.tolist())):
        sel = tr.anchor == a
        means[a] = float(r[sel].mean())
        fitted[sel] = means[a]
    print(f"  per-receiver constant: std of the means {np.std(list(means.values())):.1f} dB;"
          f" residual std {r.std():.1f} -> {(r - fitted).std():.1f} dB")
    ang, speed = relative_bearing_deg(tr)
    moving = speed > 0.3
    rr = r - fitted
    cells = []
    for lo, hi in itertools.pairwise(BINS_DEG):
        sel = moving & (ang >= lo) & (ang < hi + (hi == 180))
        cells.append(f"{lo}-{hi}: {rr[sel].mean():+.1f} ({sel.sum()})")
    print("  body shadowing (residual minus receiver mean, by relative bearing deg): "
          + ", ".join(cells))
    corr = []
    for lag in np.arange(0.0, 3.01, 0.5):
        m = model_rss(tr, ch, lag)
        corr.append((float(np.corrcoef(tr.rss_dbm - fitted, m)[0, 1]), lag))
    print("  corr(rss, model at t - lag): " + ", ".join(f"{lag:.1f}s {c:.3f}" for c, lag in corr))
    lagged = []
    for a in sorted(set(tr.anchor.tolist())):
        sel = np.flatnonzero(tr.anchor == a)
        ta, ra = tr.t[sel], rr[sel]
        for gap in (0.5, 2.0, 5.0):
            j = np.searchsorted(ta, ta + gap)
            ok = j < len(ta)
            if ok.sum() > 10:
                lagged.append((gap, float(np.corrcoef(ra[ok], ra[j[ok]])[0, 1])))
    for gap in (0.5, 2.0, 5.0):
        v = [c for g, c in lagged if g == gap]
        print(f"  residual autocorrelation at +{gap} s (mean over receivers): {np.mean(v):.2f}")
    return means


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = {n: load_trajectory(DATA, n) for n in TRACKS}
    ch = loaded[TRACKS[0]].session.meta.channel or ChannelModel()
    print(f"channel: A={ch.a_dbm} eta={ch.eta} sigma={ch.sigma_db}")
    table = {n: report(loaded[n], ch) for n in TRACKS}
    rx = sorted({a for m in table.values() for a in m})
    print("\nper-receiver mean residual (dB) by track:")
    print("receiver  " + "  ".join(f"{n[:12]:>12}" for n in TRACKS))
    for a in rx:
        print(f"{a:9} " + "  ".join(f"{table[n].get(a, np.nan):+12.1f}" for n in TRACKS))
    m = np.array([[table[n].get(a, np.nan) for n in TRACKS] for a in rx])
    centred = m - np.nanmean(m, axis=0)
    print(f"receiver means centred per track: std across tracks (mean over receivers) "
          f"{np.nanmean(np.nanstd(centred, axis=1)):.1f} dB; std across receivers of the "
          f"across-track mean {np.nanstd(np.nanmean(centred, axis=1)):.1f} dB")


if __name__ == "__main__":
    main()
