"""Per-class covariances, per-source components and the zero-padded DFT feature (Sec. 4.1.2)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait.activity_lda import LdaModel, train_lda, transform_features
from hrtls.gait.features import window_features, window_labels


def two_source_features(rng: np.random.Generator, n: int = 40
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Five classes from two 'sources' whose class means differ (like two simulators)."""
    means = {0: 0.05, 1: 1.0, 2: 6.0, 3: 0.6, 4: 2.0}
    f, y, g = [], [], []
    for src, scale in ((0, 1.0), (1, 1.6)):
        for c, m in means.items():
            base = np.full(7, m * scale)
            base[6] *= 1.0 + c
            spread = 0.05 + 0.03 * c  # classes differ in spread: per-class covariance
            f.append(base * np.exp(rng.normal(0, spread, (n, 7))))
            y.append(np.full(n, c))
            g.append(np.full(n, src))
    return np.concatenate(f), np.concatenate(y), np.concatenate(g)


def slow_posteriors(model: LdaModel, features: np.ndarray) -> np.ndarray:
    """Eq. 4.7-4.8 one window and one component at a time with scipy's normal density."""
    assert model.component_class is not None and model.component_weights is not None
    x = transform_features(features, model.log_features)
    out = np.zeros((x.shape[0], model.classes.size))
    for w in range(x.shape[0]):
        logs = []
        for j in range(model.means.shape[0]):
            cov = model.covariance[j] if model.covariance.ndim == 3 else model.covariance
            c = int(model.component_class[j])
            logs.append(multivariate_normal(model.means[j], cov).logpdf(x[w])
                        + np.log(model.priors[c] * model.component_weights[j]))
        lg = np.array(logs)
        p = np.exp(lg - lg.max())
        for j in range(model.means.shape[0]):
            out[w, int(model.component_class[j])] += p[j]
        out[w] /= out[w].sum()
    return out


@pytest.mark.parametrize("covariance", ["per_class", "pooled"])
def test_components_match_scipy_reference(covariance: str) -> None:
    rng = np.random.default_rng(5)
    f, y, g = two_source_features(rng)
    model = train_lda(f, y, groups=g, covariance=covariance)  # type: ignore[arg-type]
    # one component per (class, source): 10 means, weights 1/2 within each class
    assert model.means.shape == (10, 7)
    assert model.component_class is not None and model.component_weights is not None
    np.testing.assert_allclose(np.bincount(model.component_class,
                                           weights=model.component_weights), 1.0)
    assert model.per_component_covariance == (covariance == "per_class")
    sub = f[::17]
    np.testing.assert_allclose(model.posteriors(sub), slow_posteriors(model, sub), atol=1e-9)
    assert np.mean(model.predict(f) == y) > 0.97


def test_per_class_without_groups_is_eq_4_8() -> None:
    rng = np.random.default_rng(6)
    f, y, _ = two_source_features(rng)
    model = train_lda(f, y, covariance="per_class", pooled_blend=0.0)
    assert model.means.shape == (5, 7) and model.covariance.shape == (5, 7, 7)
    # the class means are the plain means of the (log) features
    x = transform_features(f, True)
    for k, c in enumerate(model.classes):
        np.testing.assert_allclose(model.means[k], x[y == c].mean(axis=0))
    np.testing.assert_allclose(model.posteriors(f[::23]), slow_posteriors(model, f[::23]),
                               atol=1e-9)


def test_small_components_use_the_pooled_covariance() -> None:
    rng = np.random.default_rng(7)
    f, y, g = two_source_features(rng, n=10)
    model = train_lda(f, y, groups=g, covariance="per_class", min_component_windows=20)
    cov = model.covariance
    for j in range(1, cov.shape[0]):
        np.testing.assert_allclose(cov[j], cov[0])


def test_json_roundtrip_and_version_1(tmp_path) -> None:
    rng = np.random.default_rng(8)
    f, y, g = two_source_features(rng)
    model = train_lda(f, y, groups=g, covariance="per_class", info="two sources")
    path = tmp_path / "m.json"
    model.save(path)
    again = LdaModel.load(path)
    np.testing.assert_array_equal(again.predict(f), model.predict(f))
    np.testing.assert_allclose(again.posteriors(f), model.posteriors(f))
    assert again.dft_zero_pad == model.dft_zero_pad == 4
    # a version-1 file: one Gaussian per class, pooled covariance, unpadded DFT
    old = train_lda(f, y)
    d = old.to_dict()
    for key in ("component_class", "component_weights", "dft_zero_pad"):
        d.pop(key)
    d["version"] = 1
    v1 = LdaModel.from_dict(json.loads(json.dumps(d)))
    assert v1.dft_zero_pad == 1
    np.testing.assert_array_equal(v1.predict(f), old.predict(f))


def test_component_validation() -> None:
    rng = np.random.default_rng(9)
    f, y, g = two_source_features(rng)
    m = train_lda(f, y, groups=g, covariance="per_class")
    with pytest.raises(InputError, match="component_class"):
        LdaModel(m.classes, m.means, m.covariance, m.priors, m.loss,
                 component_class=np.zeros(10, dtype=np.int64))
    with pytest.raises(InputError, match="component_weights"):
        LdaModel(m.classes, m.means, m.covariance, m.priors, m.loss,
                 component_class=m.component_class, component_weights=np.full(10, 0.3))
    with pytest.raises(InputError, match="covariance"):
        LdaModel(m.classes, m.means, m.covariance[:3], m.priors, m.loss,
                 component_class=m.component_class)
    with pytest.raises(InputError, match="groups"):
        train_lda(f, y, groups=g[:-1])
    with pytest.raises(InputError, match="covariance"):
        train_lda(f, y, covariance="diagonal")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="pooled_blend"):
        train_lda(f, y, covariance="per_class", pooled_blend=1.5)


@settings(max_examples=60, deadline=None)
@given(scale=st.floats(1e-6, 1e3), seed=st.integers(0, 2**16))
def test_posteriors_are_probabilities_for_any_features(scale: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, scale, (6, 7))
    post = MODEL.posteriors(x)
    assert np.all(np.isfinite(post)) and np.all(post >= 0)
    np.testing.assert_allclose(post.sum(axis=1), 1.0)
    # windows are classified independently: order does not matter
    perm = rng.permutation(6)
    np.testing.assert_allclose(MODEL.posteriors(x[perm]), post[perm], atol=1e-12)


MODEL = train_lda(*two_source_features(np.random.default_rng(10))[:2], covariance="per_class")


def test_loss_matrix_with_components() -> None:
    rng = np.random.default_rng(11)
    f, y, g = two_source_features(rng)
    m = train_lda(f, y, groups=g, covariance="per_class")
    loss = np.full((5, 5), 100.0)
    loss[1, :] = 0.0
    m2 = LdaModel(m.classes, m.means, m.covariance, m.priors, loss,
                  component_class=m.component_class)
    assert np.all(m2.predict(f) == 1)


# ------------------------------------------------------------------ zero-padded DFT feature
@settings(max_examples=50, deadline=None)
@given(f_hz=st.floats(0.8, 4.0), amp=st.floats(0.1, 5.0))
def test_zero_padded_dft_peak_is_the_amplitude(f_hz: float, amp: float) -> None:
    rate = 100.0
    t = np.arange(200) / rate
    v = amp * np.cos(2 * np.pi * f_hz * t + 0.3)
    acc = np.column_stack([v, 0.5 * v, 9.81 + v])
    wf = window_features(t, acc, window_samples=200)
    # within 3 % of the amplitude wherever the frequency falls between the 0.5 Hz bins
    # (plus the leakage of the finite window, < 7 % above 0.8 Hz)
    np.testing.assert_allclose(wf.lda[0, 4], amp, rtol=0.1)
    plain = window_features(t, acc, window_samples=200, dft_zero_pad=1)
    assert wf.lda[0, 4] >= plain.lda[0, 4] - 1e-9


def test_dft_between_bins_hand_case() -> None:
    # 1.75 Hz sits half-way between the 1.5 and 2.0 Hz bins of a 2 s window
    t = np.arange(200) / 100.0
    v = np.cos(2 * np.pi * 1.75 * t)
    acc = np.column_stack([v, v, 9.81 + v])
    plain = window_features(t, acc, window_samples=200, dft_zero_pad=1).lda[0, 4]
    padded = window_features(t, acc, window_samples=200).lda[0, 4]
    assert plain < 0.7  # the scalloping loss of a rectangular window: 2 / pi = 0.64
    assert padded == pytest.approx(1.0, abs=0.05)
    with pytest.raises(InputError):
        window_features(t, acc, window_samples=200, dft_zero_pad=0)


# ------------------------------------------------------------------ default model regression
def test_default_model_on_held_out_synthetic_person() -> None:
    from hrtls.gait.session_analysis import activity_windows
    from hrtls.gait.synthetic import SimPerson, random_mounting, simulate

    rng = np.random.default_rng(4242)  # not one of the training persons (seeds 900-911)
    segs = [(0, 10), (1, 30), (0, 6), (3, 16), (4, 16), (2, 16), (0, 6)]
    w = simulate(segs, person=SimPerson.random(rng), q_bd=random_mounting(rng), seed=4242)
    wf = activity_windows(w.t, w.acc_d, rate_hz=100.0, q_nd=w.q_nd, mounting_q_bd=w.q_bd)
    y = window_labels(w.activity, 200)
    ok = y >= 0
    pred = LdaModel.default().predict(wf.lda[ok])
    assert np.mean(pred == y[ok]) > 0.9


def test_default_model_on_held_out_hrtls_sim_seed() -> None:
    sim = pytest.importorskip("hrtls.sim.scenarios")
    from hrtls.gait.session_analysis import activity_windows, session_inputs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = sim.run_scenario("inderst_ring", seed=3)  # training used seeds 10, 11, 20, 21
        t, acc, q_nd, mount, rate = session_inputs(r.session)
        wf = activity_windows(t, acc, rate_hz=rate, q_nd=q_nd, mounting_q_bd=mount)
    lab = np.interp(t, r.activity_t, r.activity).round().astype(np.int64)
    y = window_labels(lab, round(2.0 * rate))
    ok = y >= 0
    pred = LdaModel.default().predict(wf.lda[ok])
    # level walking at 0.9 m/s was labelled upstairs by the previous default model
    assert np.mean(pred == y[ok]) > 0.95
    assert np.mean(pred[y[ok] == int(Activity.WALKING)] == int(Activity.UPSTAIRS)) < 0.03


@settings(max_examples=40, deadline=None)
@given(hop=st.integers(1, 50), n=st.integers(0, 260), seed=st.integers(0, 1000))
def test_sliding_windows_match_shifted_consecutive_windows(hop: int, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    acc = rng.normal(size=(n, 3)) + np.array([0.0, 0.0, 9.81])
    j = 50
    slide = window_features(t, acc, window_samples=j, hop_samples=hop)
    assert len(slide) == (max(n - j, -1) // hop + 1 if n >= j else 0)
    for w in range(len(slide)):
        one = window_features(t[w * hop: w * hop + j], acc[w * hop: w * hop + j],
                              window_samples=j)
        np.testing.assert_allclose(slide.lda[w], one.lda[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(slide.tree[w], one.tree[0], rtol=1e-12, atol=1e-12)
        assert slide.t_start[w] == t[w * hop] and slide.t_end[w] == t[w * hop + j - 1]
    same = window_features(t, acc, window_samples=j, hop_samples=j)
    plain = window_features(t, acc, window_samples=j)
    np.testing.assert_array_equal(same.lda, plain.lda)
    with pytest.raises(InputError, match="hop"):
        window_features(t, acc, window_samples=j, hop_samples=j + 1)
