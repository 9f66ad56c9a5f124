"""Simulated vs real lower-back gait waveforms (Mobilise-D lab recordings).

Run ``python benchmarks/sim_vs_real.py`` (``--heading`` adds the Fourier tip-to-tail heading
error on the simulated Basso scenarios). For two walking-speed groups of the real strides it
simulates a straight walk at the group's mean speed and cadence (noiseless IMU at the waist,
identity mounting), measures both with the same code (:func:`levelled_gait_signals`,
:func:`stride_waveforms` between true / reference heel strikes) and prints, per axis, the
correlation and RMS difference of the mean stride waveforms, the amplitude ratio and phase
difference of the main harmonic, and the AP extremes relative to the heel strikes.

The simulated person's vertical amplitude (``--k``): ``step`` (default) is the median per-step
peak-to-peak of the raw levelled vertical acceleration of the group's real strides, ``wave`` the
peak-to-peak of the mean real waveform (amplitudes then agree by construction and the RMS
difference is the shape error), ``default`` the model's own law. The amplitude-vs-speed table
compares that law (``GaitParams.vertical_pp`` and the spread of :meth:`GaitParams.drawn`) with
the real per-stride peak-to-peak binned by stride speed, per participant. ``--model FILE``
compares another version of ``gait_model.py`` instead, e.g. the model before the waveforms
were measured: ``git show cf9c77b:src/hrtls/sim/gait_model.py > /tmp/old.py``.

The recordings (and the ``--heading`` scenario-seeds) run through ``--engine``
(``benchmarks/_engine.py``); the simulated walks of the groups run in this process.
"""

from __future__ import annotations

import argparse
import itertools
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from _engine import Batch, add_engine_options
from hrtls.frames import quat_rotate
from hrtls.sim.gait_model import GaitParams, simulate_gait
from hrtls.sim.gait_waveforms import (
    GAIT_SIGNAL_COLUMNS,
    levelled_gait_signals,
    stride_waveforms,
    waveform_harmonics,
)
from hrtls.sim.imu_model import body_kinematics, ideal_imu
from hrtls.sim.motion_truth import Waypoint, simulate_motion

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
POINTS = 100
SPEED_EDGES_M_S = (0.6, 0.9)  # speed groups by reference bout speed


@dataclass
class Group:
    """Real strides of one speed group."""

    name: str
    waves: list[np.ndarray]
    duration_s: list[float]
    speed_m_s: list[float]
    k: list[float]
    pp: list[float]

    def mean(self) -> np.ndarray:
        return np.mean(self.waves, axis=0)


@dataclass(frozen=True)
class TrialItem:
    """One mobgap lab trial."""

    root: Path
    participant: str
    test: str
    trial: str


def trial_items(root: Path) -> list[TrialItem]:
    """The mobgap lab trials under ``root``."""
    from hrtls.datasets.mobgap import list_trials

    return [TrialItem(root, t.participant, t.test, t.trial) for t in list_trials(root)]


def _trial_label(item: TrialItem) -> str:
    return f"{item.participant}/{item.test}/{item.trial}"


Stride = tuple[int, np.ndarray, float, float, float, float]
"""Speed group index, waveform, duration s, speed m/s, Weinberg K, vertical peak-to-peak."""


def _trial_with_reference(item: TrialItem) -> tuple[Any, Any]:
    """A mobgap trial and its reference (INDIP, else stereophotogrammetry; None when empty)."""
    from hrtls.datasets.mobgap import load_trial

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trial = load_trial(item.root, item.participant, item.test, item.trial)
    ref = trial.reference.indip
    if ref is None or ref.is_empty:
        ref = trial.reference.stereophoto
    return trial, None if ref is None or ref.is_empty else ref


def trial_strides(item: TrialItem) -> list[Stride]:
    """The stride waveforms of one trial with a reference (none without one)."""
    trial, ref = _trial_with_reference(item)
    if ref is None:
        return []
    t, acc, gyr, _ = trial.session.imu.aligned()
    if gyr is None:
        return []
    q_bd = np.asarray(trial.session.meta.mounting_q_bd, dtype=np.float64)
    sig = levelled_gait_signals(t, quat_rotate(q_bd, acc), quat_rotate(q_bd, gyr))
    sw = stride_waveforms(t, sig, ref.initial_contacts_s, ref.initial_contact_left,
                          bout=ref.initial_contact_bout, points=POINTS)
    ic = ref.initial_contacts_s
    out: list[Stride] = []
    for s in range(len(sw.start_s)):
        i = int(np.flatnonzero(ic == sw.start_s[s])[0])
        bout = int(ref.initial_contact_bout[i])
        v = float(ref.bout_walking_speed_m_s[bout])
        if not np.isfinite(v):
            continue
        # Weinberg K of this stride: reference stride length / 2 over the step pp^(1/4)
        k_stride = pp_stride = np.nan
        near = np.flatnonzero((ref.stride_bout == bout)
                              & (np.abs(ref.stride_start_s - sw.start_s[s]) < 0.03))
        if len(near) and np.isfinite(ref.stride_length_m[near[0]]):
            pp = []
            for a, b in ((ic[i], ic[i + 1]), (ic[i + 1], ic[i + 2])):
                seg = sig[(t >= a) & (t <= b), 2]
                pp.append(np.ptp(seg))
            k_stride = 0.5 * ref.stride_length_m[near[0]] / np.mean(pp) ** 0.25
            pp_stride = float(np.mean(pp))
        out.append((int(np.searchsorted(SPEED_EDGES_M_S, v, side="right")), sw.waveforms[s],
                    float(sw.duration_s[s]), v, float(k_stride), pp_stride))
    return out


def real_groups(batch: Batch, root: Path) -> list[Group]:
    """Stride waveforms of the mobgap lab trials, split by reference bout speed."""
    lo, hi = SPEED_EDGES_M_S
    groups = [Group(name, [], [], [], [], [])
              for name in (f"v < {lo}", f"{lo} <= v < {hi}", f"v >= {hi}")]
    for strides in batch.values(trial_strides, trial_items(root), label=_trial_label):
        for k, wave, duration_s, v, k_stride, pp in strides:
            g = groups[k]
            g.waves.append(wave)
            g.duration_s.append(duration_s)
            g.speed_m_s.append(v)
            g.k.append(k_stride)
            g.pp.append(pp)
    return [g for g in groups if g.waves]


def simulated_mean(speed_m_s: float, stride_s: float, pp: float | None,
                   simulate: Callable[..., Any] = simulate_gait, base: Any = None,
                   seed: int = 0) -> tuple[np.ndarray, int]:
    """Mean stride waveform of a simulated straight walk at ``speed_m_s`` and cadence.

    ``pp``: the vertical peak-to-peak (m/s^2) to give the simulated person at this speed (None:
    the model's own); a model file with a Weinberg ``K`` gets the ``K`` that produces it.
    """
    step_len = speed_m_s * stride_s / 2.0
    base = base if base is not None else GaitParams()
    amp: dict[str, float] = {}
    if pp is not None and hasattr(base, "vertical_pp_1ms_m_s2"):
        amp = {"vertical_pp_1ms_m_s2": pp / max(speed_m_s, base.envelope_speed_m_s)
               ** base.vertical_pp_exponent}
    elif pp is not None:
        amp = {"weinberg_k_walk": step_len / pp ** 0.25}
    p = replace(base, step_a_m=step_len - base.step_b_s * speed_m_s, **amp)
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=max(40.0, 60.0 * speed_m_s), y=0.0,
                                            speed_m_s=speed_m_s)]
    motion = simulate_motion(wps, rate_hz=100.0)
    gait = simulate(motion, p, np.random.default_rng(seed))
    imu = ideal_imu(body_kinematics(motion, gait))
    sig = levelled_gait_signals(motion.t, imu.specific_force, imu.angular_rate)
    st = gait.steps
    # heel strikes (left on even steps); only strides at cruise speed
    ic = np.concatenate([st.t_start, st.t_end[-1:]])
    left = np.arange(len(ic)) % 2 == 0
    sw = stride_waveforms(motion.t, sig, ic, left, points=POINTS, min_stride_s=0.5,
                          max_stride_s=2.5)
    v_at = np.interp(sw.start_s, motion.t, motion.speed)
    v_end = np.interp(sw.start_s + sw.duration_s, motion.t, motion.speed)
    ok = (v_at > 0.97 * speed_m_s) & (v_end > 0.97 * speed_m_s)
    return sw.waveforms[ok].mean(axis=0), int(ok.sum())


def extremes_s(wave: np.ndarray, stride_s: float) -> tuple[float, float]:
    """Times of the minimum and the maximum of a stride waveform relative to the nearest heel
    strike, s (negative: before it), on the mean of its two steps."""
    half = len(wave) // 2
    step = 0.5 * (wave[:half] + wave[half: 2 * half])
    def rel(i: int) -> float:
        p = i / half
        return float((p - 1.0 if p > 0.5 else p) * 0.5 * stride_s)
    return rel(int(np.argmin(step))), rel(int(np.argmax(step)))


def compare(real: np.ndarray, sim: np.ndarray) -> list[tuple[str, float, float, float, int,
                                                              float, float]]:
    """Per column: correlation, RMS diff, real RMS, the real waveform's largest stride harmonic
    ``n`` and the sim / real amplitude ratio and phase difference (deg) of that harmonic."""
    out = []
    hr = waveform_harmonics(real)
    hs = waveform_harmonics(sim)
    for j, name in enumerate(GAIT_SIGNAL_COLUMNS):
        r = real[:, j] - real[:, j].mean()
        s = sim[:, j] - sim[:, j].mean()
        corr = float(np.corrcoef(r, s)[0, 1])
        rms = float(np.sqrt(np.mean((r - s) ** 2)))
        n = int(np.argmax(np.abs(hr[:, j])))
        ratio = float(abs(hs[n, j]) / abs(hr[n, j]))
        dphi = float(np.degrees(np.angle(hs[n, j] / hr[n, j])))
        out.append((name, corr, rms, float(np.sqrt(np.mean(r**2))), n + 1, ratio, dphi))
    return out


def run(groups: list[Group], simulate: Callable[..., Any] = simulate_gait,
        k_mode: str = "step", base: Any = None) -> list[dict[str, float | str]]:
    """Print the comparison table of the real ``groups``; return its rows."""
    rows: list[dict[str, float | str]] = []
    for g in groups:
        v = float(np.mean(g.speed_m_s))
        stride = float(np.mean(g.duration_s))
        real = g.mean()
        pp_real = {"step": float(np.nanmedian(g.pp)),
                   "wave": float(np.ptp(real[:, 2]))}.get(k_mode)
        sim, n_sim = simulated_mean(v, stride, pp_real, simulate, base)
        print(f"\nreal strides with {g.name} m/s: {len(g.waves)} strides, v {v:.2f} m/s, cadence "
              f"{120.0 / stride:.1f} steps/min, real Weinberg K (median) "
              f"{float(np.nanmedian(g.k)):.3f}, sim vertical pp "
              f"{'model' if pp_real is None else f'{pp_real:.2f} m/s^2'} ({k_mode}), "
              f"{n_sim} simulated strides")
        print(f"  {'column':<18}{'corr':>7}{'rms diff':>10}{'real rms':>10}{'harm n':>8}"
              f"{'amp ratio':>11}{'dphase deg':>12}")
        for name, corr, rms, rr, n, ratio, dphi in compare(real, sim):
            print(f"  {name:<18}{corr:7.2f}{rms:10.2f}{rr:10.2f}{n:8d}{ratio:11.2f}{dphi:12.0f}")
            rows.append({"group": g.name, "column": name, "corr": corr, "rms": rms,
                         "ratio": ratio, "dphase_deg": dphi})
        (ra, rb), (sa, sb) = extremes_s(real[:, 0], stride), extremes_s(sim[:, 0], stride)
        rv, sv = extremes_s(real[:, 2], stride)[1], extremes_s(sim[:, 2], stride)[1]
        print(f"  from the nearest heel strike (s): AP min real {ra:+.2f} sim {sa:+.2f}; "
              f"AP max real {rb:+.2f} sim {sb:+.2f}; vertical max real {rv:+.2f} sim {sv:+.2f}")
    return rows


def measured_table(groups: list[Group], split_m_s: float = 0.75) -> None:
    """Print the harmonic tables of ``hrtls.sim.gait_model`` as measured on the real strides."""
    waves = [w for g in groups for w in g.waves]
    dur = np.array([d for g in groups for d in g.duration_s])
    speed = np.array([v for g in groups for v in g.speed_m_s])
    print(f"\nmeasured stride harmonics (amplitude, phase deg), groups split at {split_m_s} m/s")
    for name, sel in (("slow", speed < split_m_s), ("fast", speed >= split_m_s)):
        mean = np.mean(np.asarray(waves)[sel], axis=0)
        stride = float(dur[sel].mean())
        w_s = 2.0 * np.pi / stride
        h = waveform_harmonics(mean, 8)
        ref = abs(h[1, 2])
        n = np.arange(1, 9)
        print(f"{name}: {sel.sum()} strides, {speed[sel].mean():.2f} m/s, "
              f"{120.0 / stride:.1f} steps/min, vertical n=2 amplitude {ref:.2f} m/s^2")
        rows = {"vertical / |V2|": h[:, 2] / ref, "AP / |V2|": h[:, 0] / ref,
                "ML m/s^2": h[:, 1], "roll rad": h[:, 3] / (1j * n * w_s),
                "pitch rad": h[:, 4] / (1j * n * w_s), "yaw rad": h[:, 5] / (1j * n * w_s)}
        for label, c in rows.items():
            cells = " ".join(f"{k}:({abs(z):.3f},{np.degrees(np.angle(z)):+.0f})"
                             for k, z in zip(n, c, strict=True))
            print(f"  {label:<16}{cells}")
        print(f"  ML n=1 displacement {abs(h[0, 1]) / w_s**2:.4f} m")


@dataclass(frozen=True)
class HeadingItem:
    """One simulated scenario and seed."""

    name: str
    seed: int


def heading_error(item: HeadingItem) -> tuple[int, float, float]:
    """Steps with a heading, median and 90th percentile |error| (deg) of one scenario-seed."""
    from hrtls.frames import wrap_angle
    from hrtls.gait.session_analysis import analyze_session
    from hrtls.sim.scenarios import run_scenario

    res = run_scenario(item.name, item.seed)
    st = analyze_session(res.session, heading="fourier").steps
    truth = res.session.truth
    assert truth is not None and truth.heading_rad is not None
    tm = 0.5 * (st.t_start + st.t_end)
    true_h = np.interp(tm, truth.t, np.unwrap(truth.heading_rad))
    ok = np.isfinite(st.heading_rad)
    err = np.degrees(np.abs(wrap_angle(st.heading_rad[ok] - true_h[ok])))
    return int(ok.sum()), float(np.median(err)), float(np.percentile(err, 90))


def heading_errors(batch: Batch, names: tuple[str, ...] = ("basso_test1", "basso_test2"),
                   seeds: tuple[int, ...] = (0, 1)) -> None:
    """Median |error| of the Fourier tip-to-tail step heading on simulated Basso walks."""
    print("\nFourier tip-to-tail heading (GaitAnalyzer heading='fourier') vs truth")
    items = [HeadingItem(name, seed) for name in names for seed in seeds]
    for it, (n, median, p90) in batch.map(heading_error, items,
                                          label=lambda it: f"{it.name} seed {it.seed}"):
        print(f"  {it.name} seed {it.seed}: {n} steps, median {median:.1f} deg, "
              f"90th pct {p90:.1f} deg")


def trial_amplitudes(item: TrialItem) -> list[tuple[float, float]]:
    """(stride speed m/s, vertical peak-to-peak m/s^2) of one trial's reference strides."""
    trial, ref = _trial_with_reference(item)
    t, acc, gyr, _ = trial.session.imu.aligned()
    if ref is None or gyr is None:
        return []
    q_bd = np.asarray(trial.session.meta.mounting_q_bd, dtype=np.float64)
    up = levelled_gait_signals(t, quat_rotate(q_bd, acc), quat_rotate(q_bd, gyr))[:, 2]
    out = []
    for a, b, _, v in ref.strides:
        if np.isfinite(v) and 0.7 <= b - a <= 2.0:
            m = 0.5 * (a + b)
            pp = 0.5 * (np.ptp(up[(t >= a) & (t <= m)]) + np.ptp(up[(t >= m) & (t <= b)]))
            out.append((float(v), float(pp)))
    return out


def amplitude_vs_speed(batch: Batch, root: Path = DATA / "mobgap_lab") -> None:
    """Real per-stride vertical peak-to-peak by speed bin (median, per participant) vs model."""
    from hrtls.sim.motion_truth import GAIT_WALK

    edges = np.array([0.3, 0.6, 0.8, 1.0, 1.2, 1.5])
    real: dict[str, list[tuple[float, float]]] = {}
    for it, strides in batch.map(trial_amplitudes, trial_items(root), label=_trial_label):
        if strides:
            real.setdefault(it.participant, []).extend(strides)
    base = GaitParams()
    lo, hi = replace(base, vertical_pp_1ms_m_s2=base.vertical_pp_1ms_m_s2 * 0.87,
                     vertical_pp_exponent=base.vertical_pp_exponent + 0.12), \
        replace(base, vertical_pp_1ms_m_s2=base.vertical_pp_1ms_m_s2 * 1.13,
                vertical_pp_exponent=base.vertical_pp_exponent - 0.12)
    print("\nvertical peak-to-peak (m/s^2) vs stride speed: real median per participant (n) / "
          "model default [spread of drawn persons]")
    print(f"  {'speed m/s':<12}" + "".join(f"{p:>16}" for p in real) + f"{'model':>22}")
    for a, b in itertools.pairwise(edges):
        mid = np.array([0.5 * (a + b)])
        walk = np.array([GAIT_WALK])
        cells = []
        for rows in real.values():
            x = np.array([pp for v, pp in rows if a <= v < b])
            cells.append(f"{np.median(x):.2f} ({x.size})" if x.size else "-")
        vals = sorted(float(g.vertical_pp(mid, walk)[0]) for g in (lo, hi))
        model = f"{float(base.vertical_pp(mid, walk)[0]):.2f} [{vals[0]:.2f}-{vals[1]:.2f}]"
        print(f"  {f'{a:.1f}-{b:.1f}':<12}" + "".join(f"{c:>16}" for c in cells) + f"{model:>22}")


def main() -> None:
    """Command line entry."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", choices=("step", "wave", "default"), default="step",
                    help="vertical amplitude of the simulated person (see the module notes)")
    ap.add_argument("--model", type=Path, default=None,
                    help="another gait_model.py to compare instead of the installed one")
    ap.add_argument("--heading", action="store_true", help="also score the Fourier heading")
    ap.add_argument("--table", action="store_true",
                    help="also print the measured harmonic tables (the model's constants)")
    add_engine_options(ap)
    args = ap.parse_args()
    batch = Batch.of(args)
    if not (DATA / "mobgap_lab").is_dir():
        print(f"no real data at {DATA / 'mobgap_lab'}; nothing to compare")
    else:
        simulate: Callable[..., Any] = simulate_gait
        base = None
        if args.model is not None:
            import importlib.util
            import sys

            spec = importlib.util.spec_from_file_location("gait_model_under_test", args.model)
            assert spec is not None and spec.loader is not None
            module = importlib.util.module_from_spec(spec)
            sys.modules[spec.name] = module
            spec.loader.exec_module(module)
            simulate, base = module.simulate_gait, module.GaitParams()
            print(f"model: {args.model}")
        groups = real_groups(batch, DATA / "mobgap_lab")
        run(groups, simulate=simulate, k_mode=args.k, base=base)
        if args.model is None:
            amplitude_vs_speed(batch)
        if args.table:
            measured_table(groups)
    if args.heading:
        heading_errors(batch)
    batch.finish()


if __name__ == "__main__":
    main()
