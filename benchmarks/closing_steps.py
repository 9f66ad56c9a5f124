"""The last step of a walk and the closing movement after it (issue 19): real and simulated.

Run ``PYTHONPATH=src python benchmarks/closing_steps.py`` (about 1 min). For each INDIP bout
of the mobgap lab recordings (lower back; HA/001 development, HA/002 and MS/001 held out) it
takes the detected step on the bout's last INDIP contact (within 0.2 s) and the first detected
step after it that is on no INDIP contact, within 1.5 s (the closing movement), both from the
default tracker without the closing-step rule, and prints for each:

* ``peak``: its vertical peak over the walk's level (median of the 4 detected peaks before
  the last INDIP step, as the walk filter measures it);
* ``dt``: time since the previous detected step over the walk's step period;
* ``vpp``, ``appp``: vertical and antero-posterior peak-to-peak within 0.3 s of the peak (5 Hz
  low-pass) over the same walk's median;
* ``after``: standard deviation of the vertical acceleration 0.4-1.4 s after the peak, m/s^2;
* ``sp``: whether Stereophoto has a contact within 0.2 s.

Then the same two ratios (``peak``, ``dt``) on the simulated short walks
(:func:`hrtls.gait.synthetic.short_walk_u_turn`, seeds 0-19) for the last true step and a
detected step after it.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt

from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.synthetic import short_walk_u_turn
from hrtls.gait.walk_steps import WalkStepParams

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
NO_CLOSING = WalkStepParams(closing_ratio=0.0)
DEV = ("HA/001",)
COLS = ("peak", "dt", "vpp", "appp", "after")


def _lp(x: np.ndarray, fs: float) -> np.ndarray:
    b, a = butter(2, 5.0 / (fs / 2.0))
    return np.asarray(filtfilt(b, a, x - np.median(x)))


def _features(k: int, te: np.ndarray, peak: np.ndarray, v: np.ndarray, ap: np.ndarray,
              fs: float, ref_k: int) -> dict[str, float]:
    """Features of step ``k`` against the 4 steps before step ``ref_k``."""
    prev = np.arange(max(0, ref_k - 4), ref_k)

    def pp(x: np.ndarray, tc: float) -> float:
        i = round(tc * fs)
        return float(np.ptp(x[max(0, i - round(0.3 * fs)):i + round(0.3 * fs)]))

    i = round(te[k] * fs)
    return {"peak": peak[k] / np.median(peak[prev]),
            "dt": (te[k] - te[k - 1]) / np.median(np.diff(te[max(0, ref_k - 5):ref_k])),
            "vpp": pp(v, te[k]) / np.median([pp(v, te[j]) for j in prev]),
            "appp": pp(ap, te[k]) / np.median([pp(ap, te[j]) for j in prev]),
            "after": float(np.std(v[i + round(0.4 * fs):i + round(1.4 * fs)]))}


def real_rows() -> list[tuple[str, str, str, dict[str, float]]]:
    """``(trial, role, kind, features)`` for the last INDIP step and the closing movement."""
    import steps_stops
    from hrtls.datasets import mobgap
    from hrtls.pipeline.config import preset
    from hrtls.pipeline.tracker import Tracker

    out = []
    root = DATA / "mobgap_lab"
    for tid in mobgap.list_trials(root):
        trial = mobgap.load_trial(root, tid.participant, tid.test, tid.trial)
        ref, sp = trial.reference.indip, trial.reference.stereophoto
        if ref is None:
            continue
        with steps_stops.tracker_rule(None, NO_CLOSING), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = Tracker(preset("default")).run(trial.session)
        te = res.steps.t_end - trial.session.imu.accel.t[0]
        acc = trial.session.imu.accel.values   # sensor frame: x up, z forward
        fs = trial.sampling_rate_hz
        v, ap = _lp(acc[:, 0], fs), _lp(acc[:, 2], fs)
        ic = ref.initial_contacts_s
        sp_ic = sp.initial_contacts_s if sp is not None else np.zeros(0)
        role = "dev" if tid.participant in DEV else "held out"
        for b in range(ref.n_bouts):
            icb = np.sort(ic[(ref.initial_contact_bout == b) & np.isfinite(ic)])
            k = int(np.argmin(np.abs(te - icb[-1]))) if te.size else -1
            if k < 5 or abs(te[k] - icb[-1]) > 0.2:
                continue
            name = f"{tid.participant} {tid.test} {tid.trial} bout {b}"
            out.append((name, role, "last", _features(k, te, res.steps.acc_max, v, ap, fs, k)))
            nxt = k + 1
            if (nxt < te.size and te[nxt] - te[k] <= 1.5
                    and np.min(np.abs(ic[np.isfinite(ic)] - te[nxt])) > 0.2):
                f = _features(nxt, te, res.steps.acc_max, v, ap, fs, k)
                sp_hit = bool(sp_ic.size) and np.nanmin(np.abs(sp_ic - te[nxt])) <= 0.2
                out.append((name, role, "closing (Stereophoto)" if sp_hit else "closing", f))
    return out


def sim_rows(seeds: range) -> list[tuple[str, str, str, dict[str, float]]]:
    """The last true step and a detected step after it on the simulated short walks."""
    out = []
    for seed in seeds:
        w = short_walk_u_turn(seed)
        ga = GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns",
                          window_features=False, walk_steps=NO_CLOSING)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            st = ga.process(w.t, w.acc_d).steps
        te, peak = st.t_end, st.acc_max
        k = int(np.argmin(np.abs(te - w.step_t[-1])))
        if k < 5 or abs(te[k] - w.step_t[-1]) > 0.2:
            continue
        nan = {"vpp": np.nan, "appp": np.nan, "after": np.nan}
        prev = np.arange(k - 4, k)
        per = np.median(np.diff(te[k - 5:k]))
        out.append((f"seed {seed}", "sim", "last", {
            "peak": peak[k] / np.median(peak[prev]), "dt": (te[k] - te[k - 1]) / per, **nan}))
        if k + 1 < te.size and te[k + 1] - te[k] <= 1.5:
            out.append((f"seed {seed}", "sim", "closing", {
                "peak": peak[k + 1] / np.median(peak[prev]),
                "dt": (te[k + 1] - te[k]) / per, **nan}))
    return out


def main() -> None:
    rows = real_rows() if DATA.is_dir() else []
    rows += sim_rows(range(0, 20))
    print(f"{'walk end':<34} {'role':<9} {'event':<22}" + "".join(f"{c:>7}" for c in COLS))
    for name, role, kind, f in rows:
        if role != "sim":
            print(f"{name:<34} {role:<9} {kind:<22}" + "".join(f"{f[c]:7.2f}" for c in COLS))
    print("\nranges (min / median / max):")
    for role in ("dev", "held out", "sim"):
        for kind in ("last", "closing", "closing (Stereophoto)"):
            sel = [f for _, r, k, f in rows if r == role and k == kind]
            if sel:
                txt = "  ".join(
                    f"{c} {np.nanmin(a):.2f} / {np.nanmedian(a):.2f} / {np.nanmax(a):.2f}"
                    for c in COLS if np.isfinite(a := np.array([f[c] for f in sel])).any())
                print(f"{role:<9} {kind:<22} n={len(sel):<3} {txt}")


if __name__ == "__main__":
    main()
