"""IPIN 2023 track 3 benchmark: landmark errors of a hand-held phone, several configurations.

Run ``python benchmarks/ipin.py`` (data in ``../shared/data/ipin2023``, or ``--data DIR``).
Prints one table: file | configuration | landmarks | mean | median | p75 | max error (m) |
floor hits | Weinberg k used, with the IPIN 2021 reference (best smartphone entry,
p75 = 4.43 m). Rows "both" pool the landmarks of the two files (the competition's way).

Protocol (what a competitor knows): the start position (first POSI, heading unknown), the
beacon positions, that the phone is held in front of the body (hand-held mounting from the mean
gravity direction, :mod:`hrtls.pipeline.mounting`; the row of ``configs/ipin.toml`` lets the
tracker estimate it and average the RSS itself), and a Weinberg step-length constant calibrated
on the *other* logfile with the same configuration (two-fold cross-validation).
``--default-k`` uses the library's default constant (0.45) instead.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from hrtls.data import Session
from hrtls.datasets.ipin2023 import list_logfiles, load_logfile
from hrtls.errors import DegradedInputWarning
from hrtls.evaluate.metrics import error_stats
from hrtls.frames import quat_from_euler, quat_multiply
from hrtls.jobs.ipin_eval import (
    REFERENCE_P75_M,
    TARGET_P75_M,
    CaseResult,
    IpinCase,
    calibrate_channel,
    landmark_errors,
    prepare_session,
    run_case,
    run_cross_validated,
    standard_cases,
    with_weinberg_k,
)
from hrtls.pipeline.config import load_config
from hrtls.pipeline.tracker import Tracker

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "ipin2023"
CONFIG = REPO / "benchmarks" / "configs" / "ipin.toml"


def _short(name: str) -> str:
    return name.removesuffix(".txt").replace("IPIN2023_T3_TrainingTrial", "T").replace(
        "_repetition", "r")


def _line(file: str, case: str, st_n: int, mean: float, median: float, p75: float, mx: float,
          floors: str, k: str) -> str:
    return (f"{file:7s} | {case:50s} | {st_n:3d} | {mean:6.2f} | {median:6.2f} | {p75:6.2f} | "
            f"{mx:6.2f} | {floors:>6s} | {k}")


def _pooled(results: list[CaseResult], sessions: dict[str, Session]) -> np.ndarray:
    """Landmark errors of all files; a failed file counts each of its landmarks as inf."""
    out = []
    for cr in results:
        if cr.errors is not None:
            out.append(cr.errors.horizontal_m)
        else:
            cps = sessions[cr.file].checkpoints
            out.append(np.full(0 if cps is None else len(cps), np.inf))
    return np.concatenate(out) if out else np.zeros(0)


def _p75(cr: CaseResult | None) -> float:
    return math.inf if cr is None or cr.errors is None else float(cr.errors.stats.p75)


def leave_one_file_out(by_case: dict[str, dict[str, CaseResult]],
                       sessions: dict[str, Session]) -> None:
    """Configuration chosen on the other files (lowest mean p75), scored on the held file.

    The headline figure: no file scores the configuration that was chosen on it.
    """
    print("\nleave one file out: configuration chosen on the other file(s), scored on this one")
    held: list[CaseResult] = []
    for name in sessions:
        def score(case: str, held_name: str = name) -> float:
            return float(np.mean([_p75(r) for f, r in by_case[case].items() if f != held_name]))

        choice = min(by_case, key=score)
        cr = by_case[choice][name]
        held.append(cr)
        text = "failed" if cr.errors is None else f"p75 {cr.errors.stats.p75:.2f} m"
        print(f"  {_short(name):7s}: {choice} (p75 on the other file(s) {score(choice):.2f} m) "
              f"-> {text}")
    all_e = _pooled(held, sessions)
    st = error_stats(np.where(np.isfinite(all_e), all_e, 1e9)) if all_e.size else None
    if st is not None:
        n_failed = sum(cr.errors is None for cr in held)
        p75 = "inf" if not np.isfinite(np.percentile(all_e, 75)) else f"{st.p75:.2f}"
        print(f"  pooled {st.n} landmarks: mean {st.mean:.2f}, median {st.median:.2f}, "
              f"p75 {p75} m; {n_failed} failed file(s), counted with infinite errors")


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA, help="the ipin2023 folder")
    ap.add_argument("--default-k", action="store_true",
                    help="library default Weinberg constant instead of cross-calibration")
    ap.add_argument("--sensitivity", action="store_true",
                    help="also: p75 spread under small perturbations (k, mounting yaw)")
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        print(f"no data at {args.data}")
        return 1
    warnings.simplefilter("ignore", DegradedInputWarning)
    sessions = {n: load_logfile(args.data, n, trim_to_start=True)
                for n in list_logfiles(args.data)}
    cases = standard_cases()
    if CONFIG.is_file():
        best = load_config(CONFIG)
        cases.append(IpinCase(f"configs/ipin.toml ({best.name})", best,
                              channel_from_other=best.rss.mode != "off", rss_window_s=4.0))

    head = (f"{'file':7s} | {'configuration':50s} | {'lm':>3s} | {'mean':>6s} | {'median':>6s} | "
            f"{'p75':>6s} | {'max':>6s} | {'floors':>6s} | k")
    print(head)
    print("-" * len(head))
    by_case: dict[str, dict[str, CaseResult]] = {}
    for case in cases:
        results: list[CaseResult] = (
            [run_case(s, case, file=n) for n, s in sessions.items()] if args.default_k
            else run_cross_validated(sessions, case))
        by_case[case.name] = {cr.file: cr for cr in results}
        hits = 0
        for cr in results:
            if cr.errors is None:
                print(f"{_short(cr.file):7s} | {case.name:50s} | failed: {cr.error}")
                continue
            e, st = cr.errors, cr.errors.stats
            hits += e.floor_hits
            k = "-" if cr.weinberg_k is None else f"{cr.weinberg_k:.3f}"
            print(_line(_short(cr.file), case.name, st.n, st.mean, st.median, st.p75, st.max,
                        f"{e.floor_hits}/{st.n}", k))
        if len(results) > 1:
            st = error_stats(_pooled(results, sessions))
            n_failed = sum(cr.errors is None for cr in results)
            print(_line("both", case.name, st.n, st.mean, st.median, st.p75, st.max,
                        f"{hits}/{st.n}", f"{n_failed} failed file(s) counted as inf"
                        if n_failed else ""))
        print("-" * len(head))
    if len(sessions) > 1:
        leave_one_file_out(by_case, sessions)
    print(f"{'IPIN21':7s} | {'best smartphone entry (reference)':50s} | {'':3s} | {'':6s} | "
          f"{'':6s} | {REFERENCE_P75_M:6.2f} |")
    print(f"target: p75 < {TARGET_P75_M:.2f} m; k = Weinberg constant used "
          f"({'library default' if args.default_k else 'calibrated on the other file'})")
    if args.sensitivity:
        sensitivity(sessions, [c for c in cases if c.mounting == "handheld"
                               and "fixed" not in c.name and "floors" not in c.name
                               and c.declination_rad == 0.0
                               and not (c.channel_from_other and c.rss_window_s == 0)])
    return 0


def sensitivity(sessions: dict[str, Session], cases: list[IpinCase]) -> None:
    """Spread of p75 when k is 0.43/0.45/0.47 and the mounting yaw is off by -6..6 deg."""
    print()
    print("sensitivity: p75 (m) over k in {0.43, 0.45, 0.47} x mounting yaw in {-6,-3,0,3,6} deg")
    for case in cases:
        spread: dict[str, list[float]] = {n: [] for n in sessions}
        pooled: list[float] = []
        chans = ({n: calibrate_channel(s, rss_window_s=case.rss_window_s)
                  for n, s in sessions.items()} if case.channel_from_other else {})
        other = {n: next((c for m, c in chans.items() if m != n), None) for n in sessions}
        for k in (0.43, 0.45, 0.47):
            cfg = with_weinberg_k(case.config, k)
            for dpsi in (-6.0, -3.0, 0.0, 3.0, 6.0):
                per = []
                for n, s in sessions.items():
                    p = prepare_session(s, mounting="handheld", rss_floors=case.rss_floors,
                                        rss_window_s=case.rss_window_s, channel=other[n])
                    q = quat_multiply(quat_from_euler(np.zeros(1), np.zeros(1),
                                                      np.radians([dpsi]))[0],
                                      np.asarray(p.meta.mounting_q_bd))
                    p = replace(p, meta=p.meta.model_copy(
                        update={"mounting_q_bd": tuple(float(v) for v in q)}))
                    res = Tracker(cfg).run(p)
                    assert s.checkpoints is not None
                    e = landmark_errors(res.trajectory, s.checkpoints,
                                        floor_height_m=s.meta.floor_height_m).horizontal_m
                    spread[n].append(float(np.percentile(e, 75)))
                    per.append(e)
                pooled.append(float(np.percentile(np.concatenate(per), 75)))
        parts = [f"{_short(n)} {min(v):.2f}-{max(v):.2f} (median {np.median(v):.2f})"
                 for n, v in spread.items()]
        print(f"  {case.name:50s} | " + " | ".join(parts)
              + f" | both {min(pooled):.2f}-{max(pooled):.2f} (median {np.median(pooled):.2f},"
              f" > {TARGET_P75_M:g} m in {sum(x > TARGET_P75_M for x in pooled)}/{len(pooled)})")


if __name__ == "__main__":
    sys.exit(main())
