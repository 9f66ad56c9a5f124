"""The last step of a walk and the closing movement after it (issue 19): real and simulated.

Run ``PYTHONPATH=src python benchmarks/closing_steps.py [--seeds dev|held-out]`` (about 3 min
on a quiet machine). Everything is in the tracker's own measure, the quantity the walk
filter's ``closing_ratio`` is compared against: a detected step's peak (``acc_max``) over
the median of the 4 detected peaks before the last step, from the default tracker (or gait
analyzer) without the closing-step rule.

* Real: for each INDIP bout of the mobgap lab recordings (lower back; HA/001 development,
  HA/002 and MS/001 held out, for reporting only) the detected step on the bout's last INDIP
  contact (within 0.2 s) and the first detected step after it that is on no INDIP contact,
  within 1.5 s (the closing movement). Per event: ``peak`` (the ratio above), ``dt`` (time
  since the previous detected step over the walk's step period), ``vpp``, ``appp`` (vertical
  and antero-posterior peak-to-peak within 0.3 s of the peak, 5 Hz low-pass, over the walk's
  median), ``after`` (standard deviation of the vertical acceleration 0.4-1.4 s after the
  peak, m/s^2) and ``sp`` (Stereophoto has a contact within 0.2 s). A walk *ends standing*
  when ``after`` of its last event (the closing movement, else the last step) is under
  ``STANDING_STD_M_S2``; only those enter the summary.
* Scenario simulator (:mod:`hrtls.sim.scenarios`, ``SCENARIOS`` below): each run of true steps
  with more than 4 steps whose last step is walking and that is followed by at least
  ``STAND_S`` of standing: the detected step on its last true step (within 0.2 s) and the
  first detected step after it on no true step (within 1.5 s). Also the last true steps the
  default tracker (closing rule on) drops although the tracker without the rule finds them.
* Short walks (:func:`hrtls.gait.synthetic.short_walk_u_turn`): the same for the walk's end.

``--seeds dev`` (default) is seeds 0-29 for both simulators (the seeds the simulator's stop
constants were set on), ``--seeds held-out`` 100-129 (reporting only).
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Sequence
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
SCENARIOS = ("colombo_natural", "tarrio_office", "inderst_ring", "office_random_walk")
SEEDS = {"dev": range(0, 30), "held-out": range(100, 130)}
STANDING_STD_M_S2 = 1.0
"""A real walk ends standing when the vertical acceleration after its last event varies less."""
STAND_S = 3.0
"""A simulated run ends standing when no true step follows within this time, s."""
MATCH_S = 0.2
CLOSING_WITHIN_S = 1.5
Row = tuple[str, str, str, dict[str, float]]


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


def _ratios(k: int, te: np.ndarray, peak: np.ndarray, ref_k: int) -> dict[str, float]:
    """``peak`` and ``dt`` of step ``k`` against the 4 steps before ``ref_k`` (no signals)."""
    prev = np.arange(ref_k - 4, ref_k)
    per = float(np.median(np.diff(te[ref_k - 5:ref_k])))
    return {"peak": float(peak[k] / np.median(peak[prev])), "dt": (te[k] - te[k - 1]) / per,
            **dict.fromkeys(COLS[2:], np.nan)}


def _end_events(te: np.ndarray, t_last: float, on_contact: np.ndarray) -> tuple[int, int]:
    """Detected step on the last contact (-1: none, or fewer than 5 before it) and the first
    detected step after it within ``CLOSING_WITHIN_S`` on no contact (-1: none)."""
    if te.size == 0:
        return -1, -1
    k = int(np.argmin(np.abs(te - t_last)))
    if k < 5 or abs(te[k] - t_last) > MATCH_S:
        return -1, -1
    n = k + 1
    ok = n < te.size and te[n] - te[k] <= CLOSING_WITHIN_S and not on_contact[n]
    return k, n if ok else -1


def _on_contact(te: np.ndarray, contacts: np.ndarray) -> np.ndarray:
    c = np.sort(contacts[np.isfinite(contacts)])
    if c.size == 0:
        return np.zeros(te.size, dtype=bool)
    i = np.clip(np.searchsorted(c, te), 1, c.size - 1)
    return np.minimum(np.abs(c[i] - te), np.abs(c[i - 1] - te)) <= MATCH_S


def real_rows() -> list[Row]:
    """``(walk, role, kind, features)`` for the last INDIP step and the closing movement."""
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
        on_ic, on_sp = _on_contact(te, ic), _on_contact(te, sp_ic)
        role = "dev" if tid.participant in DEV else "held out"
        for b in range(ref.n_bouts):
            icb = np.sort(ic[(ref.initial_contact_bout == b) & np.isfinite(ic)])
            k, n = _end_events(te, float(icb[-1]), on_ic)
            if k < 0:
                continue
            name = f"{tid.participant} {tid.test} {tid.trial} bout {b}"
            last = _features(k, te, res.steps.acc_max, v, ap, fs, k)
            close = _features(n, te, res.steps.acc_max, v, ap, fs, k) if n >= 0 else None
            stands = (close or last)["after"] < STANDING_STD_M_S2
            suffix = "" if stands else " (walk goes on)"
            out.append((name, role, "last" + suffix, last))
            if close is not None:
                kind = "closing (Stereophoto)" if on_sp[n] else "closing"
                out.append((name, role, kind + suffix, close))
    return out


def short_walk_rows(seeds: Sequence[int]) -> list[Row]:
    """The last true step and the closing movement of the simulated short walks."""
    out: list[Row] = []
    for seed in seeds:
        w = short_walk_u_turn(seed)
        found = {}
        for rule in (NO_CLOSING, WalkStepParams()):
            ga = GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns",
                              window_features=False, walk_steps=rule)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                found[rule.closing_ratio] = ga.process(w.t, w.acc_d).steps
        st = found[0.0]
        _end_rows(out, f"seed {seed}", "short walks", st.t_end, st.acc_max,
                  found[WalkStepParams().closing_ratio].t_end, float(w.step_t[-1]),
                  _on_contact(st.t_end, w.step_t))
    return out


def _end_rows(out: list[Row], where: str, role: str, te: np.ndarray, peak: np.ndarray,
              te_rule: np.ndarray, t_last: float, on_true: np.ndarray) -> None:
    """Rows of one simulated walk end: without the rule (``te``) and with it (``te_rule``)."""
    k, n = _end_events(te, t_last, on_true)
    if k < 0:
        out.append((where, role, "last not detected", {}))
        return
    out.append((where, role, "last", _ratios(k, te, peak, k)))
    if n >= 0:
        out.append((where, role, "closing", _ratios(n, te, peak, k)))
    if not np.any(np.abs(te_rule - te[k]) < 1e-9):
        out.append((where, role, "last dropped by the closing rule", {}))


def _stand_ends(steps: object, t_stop_s: float) -> list[float]:
    """End times of the runs of true steps (more than 4, last walking) followed by standing."""
    from hrtls.data import Activity, StepEvents

    assert isinstance(steps, StepEvents)
    n = len(steps)
    new_run = np.concatenate([[True], np.abs(steps.t_start[1:] - steps.t_end[:-1]) > 1e-9])
    first = np.flatnonzero(new_run)
    last = np.concatenate([first[1:] - 1, [n - 1]])
    nxt = np.concatenate([steps.t_start[first[1:]], [t_stop_s]])
    ok = ((last - first >= 4) & (steps.activity[last] == int(Activity.WALKING))
          & (nxt - steps.t_end[last] >= STAND_S))
    return [float(x) for x in steps.t_end[last[ok]]]


def scenario_rows(names: Sequence[str], seeds: Sequence[int]) -> list[Row]:
    """The last true step and the closing movement of each stop of the scenario simulator;
    ``dropped`` rows: last steps found without the closing rule and lost with it."""
    import steps_stops
    from hrtls.pipeline.config import preset
    from hrtls.pipeline.tracker import Tracker
    from hrtls.sim.scenarios import run_scenario

    out: list[Row] = []
    for name in names:
        for seed in seeds:
            r = run_scenario(name, seed)
            t0 = float(r.session.imu.accel.t[0])
            found = {}
            for rule in (NO_CLOSING, WalkStepParams()):
                with steps_stops.tracker_rule(None, rule), warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    found[rule.closing_ratio] = Tracker(preset("default")).run(r.session).steps
            st = found[0.0]
            te = st.t_end - t0
            te_rule = found[WalkStepParams().closing_ratio].t_end - t0
            on_true = _on_contact(te, r.true_steps.t_end - t0)
            for t_last in _stand_ends(r.true_steps, float(r.session.imu.accel.t[-1])):
                _end_rows(out, f"{name} {seed} t={t_last - t0:.1f}", "scenarios", te,
                          st.acc_max, te_rule, t_last - t0, on_true)
    return out


def _summary(rows: list[Row]) -> None:
    print("\npeak / level in the tracker's measure: n, p10 / median / p90 (min - max)")
    for role in ("dev", "held out", "scenarios", "short walks"):
        for kind in ("last", "closing", "closing (Stereophoto)"):
            a = np.array([f["peak"] for _, r, k, f in rows if r == role and k == kind])
            if a.size:
                p10, med, p90 = np.percentile(a, [10, 50, 90])
                print(f"{role:<12} {kind:<22} n={a.size:<4} {p10:.2f} / {med:.2f} / {p90:.2f} "
                      f"({a.min():.2f} - {a.max():.2f})")
        ends = sum(1 for _, r, k, _ in rows if r == role and k in ("last", "last not detected"))
        if ends and role in ("scenarios", "short walks"):
            for kind in ("last not detected", "last dropped by the closing rule"):
                n = sum(1 for _, r, k, _ in rows if r == role and k == kind)
                print(f"{role:<12} {kind}: {n} of {ends} walk ends")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", choices=tuple(SEEDS), default="dev")
    ap.add_argument("--no-real", action="store_true", help="skip the mobgap recordings")
    ap.add_argument("--scenario", action="append", default=None,
                    help=f"scenario (repeatable; default {', '.join(SCENARIOS)})")
    args = ap.parse_args()
    rows = real_rows() if DATA.is_dir() and not args.no_real else []
    print(f"{'walk end':<34} {'role':<9} {'event':<38}" + "".join(f"{c:>7}" for c in COLS))
    for name, role, kind, f in rows:
        print(f"{name:<34} {role:<9} {kind:<38}" + "".join(f"{f[c]:7.2f}" for c in COLS))
    rows += scenario_rows(args.scenario or SCENARIOS, SEEDS[args.seeds])
    rows += short_walk_rows(SEEDS[args.seeds])
    print(f"\nsimulated seeds: {args.seeds} ({SEEDS[args.seeds].start}-"
          f"{SEEDS[args.seeds].stop - 1})")
    _summary(rows)


if __name__ == "__main__":
    main()
