"""Activity features, decision tree and LDA (Inderst Sec. 4.1)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import FormatError, InputError
from hrtls.gait.activity_lda import LdaModel, default_loss, train_lda, transform_features
from hrtls.gait.activity_tree import (
    TreeThresholds,
    best_split,
    calibrate_tree,
    classify_tree,
)
from hrtls.gait.features import StreamingButterworth, window_features, window_labels


def test_window_features_hand_case() -> None:
    # one window of 4 samples: V = [8, 10, 12, 10] (mean 10), ML = [1, -1, 1, -1], AP = 0
    acc = np.array([[0, 1, 8], [0, -1, 10], [0, 1, 12], [0, -1, 10]], dtype=float)
    wf = window_features(np.arange(4.0), acc, window_samples=4)
    # variance of V: (4 + 0 + 4 + 0) / 4 = 2
    assert wf.tree[0, 0] == pytest.approx(2.0)
    # eq. 4.3-4.5 with n_r = 1: gamma = 10, above = {10, 12, 10} mean 32/3, below = {8}
    i_plus = 32 / 3 - 10
    i_minus = 8 - 10
    assert wf.tree[0, 1] == pytest.approx(np.hypot(i_plus, i_minus))
    assert wf.tree[0, 2] == pytest.approx(2.0)  # ML max - min
    np.testing.assert_allclose(wf.lda[0, :3], [1.0, np.sqrt(2.0), 0.0])
    # DFT peak of ML [1,-1,1,-1]: bin 2 magnitude 4, scaled by 2/4 -> 2
    assert wf.lda[0, 3] == pytest.approx(2.0)
    assert wf.lda[0, 6] == pytest.approx(2.0)
    with pytest.raises(InputError):
        window_features(np.arange(4.0), acc, window_samples=2)


def test_window_labels_purity() -> None:
    y = np.array([1, 1, 1, 1, 0, 0, 1, 1, 2])
    np.testing.assert_array_equal(window_labels(y, 4), [1, -1])
    np.testing.assert_array_equal(window_labels(y, 4, min_purity=0.5), [1, 1])


@settings(max_examples=30, deadline=None)
@given(split=st.integers(1, 499))
def test_streaming_butterworth_matches_scipy(split: int) -> None:
    from scipy.signal import sosfilt, sosfilt_zi

    rng = np.random.default_rng(0)
    x = rng.normal(size=(500, 3)) + 5.0
    f = StreamingButterworth(order=5, cutoff_hz=6.0, rate_hz=100.0)
    y = np.concatenate([f.update(x[:split]), f.update(x[split:])])
    zi = np.multiply.outer(sosfilt_zi(f.sos), x[0])
    ref, _ = sosfilt(f.sos, x, axis=0, zi=zi)
    np.testing.assert_allclose(y, ref, atol=1e-10)
    assert f.group_delay_s(1.0) > 0


def test_best_split_and_tree_calibration() -> None:
    v = np.array([0.1, 0.2, 0.3, 1.0, 1.2, 1.4])
    thr, above, bacc = best_split(v, np.array([0, 0, 0, 1, 1, 1], bool))
    assert 0.3 < thr < 1.0 and above and bacc == 1.0
    thr, above, _ = best_split(v, np.array([1, 1, 1, 0, 0, 0], bool))
    assert not above
    rng = np.random.default_rng(1)
    feats, labels = [], []
    centers = {Activity.STANDING: (0.01, 0.1, 0.5), Activity.WALKING: (3.0, 1.0, 2.0),
               Activity.UPSTAIRS: (3.0, 3.0, 2.0), Activity.DOWNSTAIRS: (3.0, 3.0, 5.0),
               Activity.RUNNING: (50.0, 5.0, 4.0)}
    for a, c in centers.items():
        feats.append(np.array(c) * rng.uniform(0.9, 1.1, (20, 3)))
        labels.append(np.full(20, int(a)))
    f = np.concatenate(feats)
    y = np.concatenate(labels)
    th = calibrate_tree(f, y)
    assert th.stairs_above_d2
    np.testing.assert_array_equal(classify_tree(f, th), y)
    assert TreeThresholds.from_dict(json.loads(json.dumps(th.to_dict()))) == th
    with pytest.raises(InputError):
        best_split(v, np.zeros(6, bool))


def separable_features(rng: np.random.Generator, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    means = {0: 0.05, 1: 1.0, 2: 6.0, 3: 0.6, 4: 2.0}
    f, y = [], []
    for c, m in means.items():
        base = np.full(7, m)
        base[6] *= 1.0 + c  # ML range differs
        f.append(base * np.exp(rng.normal(0, 0.08, (n, 7))))
        y.append(np.full(n, c))
    return np.concatenate(f), np.concatenate(y)


def test_lda_train_predict_roundtrip(tmp_path) -> None:
    rng = np.random.default_rng(2)
    f, y = separable_features(rng)
    model = train_lda(f, y, info="test")
    assert np.mean(model.predict(f) == y) > 0.97
    post = model.posteriors(f)
    np.testing.assert_allclose(post.sum(axis=1), 1.0)
    path = tmp_path / "m.json"
    model.save(path)
    again = LdaModel.load(path)
    np.testing.assert_array_equal(again.predict(f), model.predict(f))
    assert "pickle" not in path.read_text()
    # posteriors agree with scikit-learn's own LDA on the same transformed features
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    sk = LinearDiscriminantAnalysis(solver="lsqr", shrinkage="auto", priors=np.full(5, 0.2))
    sk.fit(transform_features(f, True), y)
    np.testing.assert_allclose(post, sk.predict_proba(transform_features(f, True)), atol=1e-6)


def test_loss_matrix_changes_decision() -> None:
    rng = np.random.default_rng(3)
    f, y = separable_features(rng)
    m = train_lda(f, y)
    post = m.posteriors(f[:1])
    # a loss that forbids every class but walking makes everything walking
    loss = np.full((5, 5), 100.0)
    loss[1, :] = 0.0
    m2 = LdaModel(m.classes, m.means, m.covariance, m.priors, loss)
    assert np.all(m2.predict(f) == 1)
    assert post.shape == (1, 5)
    d = default_loss(np.arange(5))
    assert d[3, 1] == 2.0 and d[1, 3] == 1.0 and np.all(np.diag(d) == 0)


def test_lda_errors(tmp_path) -> None:
    with pytest.raises(InputError):
        train_lda(np.ones((5, 7)), np.zeros(5))
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "other"}')
    with pytest.raises(FormatError):
        LdaModel.load(bad)
    bad.write_text("not json")
    with pytest.raises(FormatError):
        LdaModel.load(bad)


def test_default_model_ships_and_loads() -> None:
    m = LdaModel.default()
    assert set(m.classes.tolist()) == {0, 1, 2, 3, 4}
    assert m.log_features
    assert "simulated" in m.info
