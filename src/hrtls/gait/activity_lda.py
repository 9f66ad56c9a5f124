"""Activity recognition by discriminant analysis (Inderst Sec. 4.1.2, eq. 4.6-4.8).

The seven features of Table 4.1 are classified by the minimum expected loss (eq. 4.6)

    c_hat = argmin_c sum_k P(k | theta) L(c | k)

with Bayes posteriors (eq. 4.7) from Gaussian likelihoods (eq. 4.8) and a uniform class prior
(Inderst Sec. 4.1.2). Two readings of eq. 4.8 are supported:

* ``covariance="pooled"``: one covariance shared by all classes (a *linear* discriminant, as
  the section's name says; fitted with scikit-learn ``LinearDiscriminantAnalysis``);
* ``covariance="per_class"``: the per-class ``Sigma_k`` printed in eq. 4.8 (Ledoit-Wolf
  estimates from scikit-learn, blended with the pooled one so that small classes stay well
  conditioned); the ``|Sigma_k|`` normalization of eq. 4.8 then matters and is kept.

Our extension: a class likelihood may be an equal-weight mixture of several Gaussians
("components"), one per training source (e.g. two simulators and real recordings), so that a
class whose windows come from differently shaped sources is not forced into one broad Gaussian.
With one component per class this is exactly eq. 4.7-4.8. Models are plain JSON parameters
(never pickle); prediction uses numpy only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data import Activity
from hrtls.errors import FormatError, InputError
from hrtls.gait._state import FloatArray, as_matrix
from hrtls.gait.features import DFT_ZERO_PAD, LDA_FEATURES

IntArray = NDArray[np.int64]
MODEL_FORMAT = "hrtls-activity-lda"
DEFAULT_MODEL_FILE = "activity_lda_default.json"


def default_loss(classes: ArrayLike) -> FloatArray:
    """Loss ``L[c, k]`` of predicting class ``c`` when the truth is ``k``.

    0 on the diagonal, 1 elsewhere, 2 for a false upstairs/downstairs prediction, so that
    stairs are rarely predicted by mistake (Inderst Sec. 6.2 comments on this choice).
    """
    cls = [int(c) for c in np.asarray(classes)]
    stairs = {int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS)}
    loss = np.ones((len(cls), len(cls)))
    for i, c in enumerate(cls):
        if c in stairs:
            loss[i, :] = 2.0
        loss[i, i] = 0.0
    return loss


@dataclass(frozen=True, slots=True, eq=False)
class LdaModel:
    """Parameters of a trained discriminant activity classifier.

    Attributes
    ----------
    classes: Activity codes of the classes (K,).
    means: means of the (transformed) features per component (M, 7); M = K unless the model
        has several components per class.
    covariance: pooled covariance (7, 7), or one covariance per component (M, 7, 7).
    priors: class priors (K,), uniform by default.
    loss: loss matrix ``L[c, k]`` (K, K) of eq. 4.6.
    window_s: window length the features were computed on, s.
    cutoff_hz: low-pass corner used before the features, Hz.
    feature_names: names of the features (Table 4.1 order).
    info: free-form description (training data, accuracy).
    log_features: classify ``log(theta + 1e-3)`` instead of ``theta``: the amplitude features
        spread proportionally to their size (standing vs running differ by 100x), and the
        logarithm makes the class covariances similar, as a pooled covariance assumes.
    component_class: index into ``classes`` of each component (M,); None: ``arange(K)``.
    component_weights: weight of each component within its class (M,), summing to 1 per class;
        None: equal weights.
    dft_zero_pad: zero-padding factor of the DFT features the model was trained on
        (:func:`hrtls.gait.features.window_features`; 1 for models written before padding).
    """

    classes: IntArray
    means: FloatArray
    covariance: FloatArray
    priors: FloatArray
    loss: FloatArray
    window_s: float = 2.0
    cutoff_hz: float = 6.0
    feature_names: tuple[str, ...] = LDA_FEATURES
    info: str = ""
    log_features: bool = True
    component_class: IntArray | None = None
    component_weights: FloatArray | None = None
    dft_zero_pad: int = DFT_ZERO_PAD

    def __post_init__(self) -> None:
        k = len(self.classes)
        d = len(self.feature_names)
        m = np.asarray(self.means).shape[0] if np.ndim(self.means) == 2 else -1
        comp = (np.arange(k) if self.component_class is None
                else np.asarray(self.component_class, dtype=np.int64))
        if comp.shape != (m,) or (m and (comp.min() < 0 or comp.max() >= k)) \
                or np.unique(comp).size != k:
            raise InputError(f"component classes {comp.tolist()} for {m} means, {k} classes",
                             where="LDA component_class",
                             expected="one class index per mean, every class present")
        weights = np.zeros(m)
        if self.component_weights is None:
            counts = np.bincount(comp, minlength=k)
            weights = 1.0 / counts[comp]
        else:
            weights = np.asarray(self.component_weights, dtype=np.float64)
        cov_shape = (d, d) if np.ndim(self.covariance) == 2 else (m, d, d)
        checks = (("means", self.means, (m, d)), ("covariance", self.covariance, cov_shape),
                  ("priors", self.priors, (k,)), ("loss", self.loss, (k, k)),
                  ("component_weights", weights, (m,)))
        for name, arr, shape in checks:
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise InputError(f"shape {a.shape} or non-finite values", where=f"LDA {name}",
                                 expected=f"finite array of shape {shape}")
            object.__setattr__(self, name, a)
        per_class = np.bincount(comp, weights=weights, minlength=k)
        if np.any(weights <= 0) or not np.allclose(per_class, 1.0):
            raise InputError(f"component weights {weights.tolist()}",
                             where="LDA component_weights",
                             expected="positive weights summing to 1 within each class")
        if np.any(self.priors <= 0):
            raise InputError(f"priors {self.priors.tolist()}", where="LDA priors",
                             expected="positive class priors")
        if int(self.dft_zero_pad) < 1:
            raise InputError(f"dft_zero_pad = {self.dft_zero_pad}", where="LDA dft_zero_pad",
                             expected="an integer >= 1")
        object.__setattr__(self, "classes", np.asarray(self.classes, dtype=np.int64))
        object.__setattr__(self, "component_class", comp)
        object.__setattr__(self, "component_weights", weights)
        object.__setattr__(self, "dft_zero_pad", int(self.dft_zero_pad))

    @property
    def per_component_covariance(self) -> bool:
        """True when each component has its own covariance (eq. 4.8's ``Sigma_k``)."""
        return bool(self.covariance.ndim == 3)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able parameters."""
        assert self.component_class is not None and self.component_weights is not None
        return {
            "format": MODEL_FORMAT, "version": 2,
            "classes": [Activity(int(c)).label for c in self.classes],
            "feature_names": list(self.feature_names),
            "means": self.means.tolist(), "covariance": self.covariance.tolist(),
            "priors": self.priors.tolist(), "loss": self.loss.tolist(),
            "window_s": self.window_s, "cutoff_hz": self.cutoff_hz, "info": self.info,
            "log_features": self.log_features,
            "component_class": self.component_class.tolist(),
            "component_weights": self.component_weights.tolist(),
            "dft_zero_pad": self.dft_zero_pad,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, where: str = "model") -> LdaModel:
        """Inverse of :meth:`to_dict`; raises :class:`FormatError` on a foreign file.

        Version-1 files (one Gaussian per class, pooled covariance, unpadded DFT) load too.
        """
        if data.get("format") != MODEL_FORMAT:
            raise FormatError(f"format {data.get('format')!r}", where=where,
                              expected=f"'format': '{MODEL_FORMAT}'")
        try:
            classes = np.array([int(Activity.parse(str(c))) for c in data["classes"]])
            comp = data.get("component_class")
            weights = data.get("component_weights")
            return cls(classes, np.asarray(data["means"]), np.asarray(data["covariance"]),
                       np.asarray(data["priors"]), np.asarray(data["loss"]),
                       float(data["window_s"]), float(data["cutoff_hz"]),
                       tuple(data["feature_names"]), str(data.get("info", "")),
                       bool(data.get("log_features", False)),
                       None if comp is None else np.asarray(comp, dtype=np.int64),
                       None if weights is None else np.asarray(weights, dtype=np.float64),
                       int(data.get("dft_zero_pad", 1)))
        except KeyError as exc:
            raise FormatError(f"missing key {exc}", where=where,
                              expected="an LDA model written by hrtls") from None

    def save(self, path: Path) -> None:
        """Write the model as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: Path) -> LdaModel:
        """Read a JSON model."""
        p = Path(path)
        try:
            data = json.loads(p.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise FormatError(str(exc), where=str(p), expected="a JSON LDA model") from None
        return cls.from_dict(data, where=str(p))

    @classmethod
    def default(cls) -> LdaModel:
        """The model shipped with hrtls (``hrtls/gait/models/activity_lda_default.json``)."""
        text = (resources.files("hrtls.gait") / "models" / DEFAULT_MODEL_FILE).read_text()
        return cls.from_dict(json.loads(text), where=DEFAULT_MODEL_FILE)

    def posteriors(self, features: FloatArray) -> FloatArray:
        """Posterior class probabilities (W, K) (eq. 4.7-4.8)."""
        assert self.component_class is not None and self.component_weights is not None
        f = transform_features(as_matrix(features, where="LDA features",
                                         columns=len(self.feature_names)), self.log_features)
        diff = f[:, None, :] - self.means[None, :, :]
        prec = np.linalg.pinv(self.covariance)
        if self.per_component_covariance:
            maha = np.einsum("wkd,kde,wke->wk", diff, prec, diff)
            _, logdet = np.linalg.slogdet(self.covariance)
        else:
            maha = np.einsum("wkd,de,wke->wk", diff, prec, diff)
            logdet = np.zeros(self.means.shape[0])
        logw = np.log(self.priors[self.component_class] * self.component_weights)
        logp = -0.5 * (maha + logdet[None, :]) + logw[None, :]
        logp -= logp.max(axis=1, keepdims=True)
        p = np.exp(logp)
        # class likelihood = mixture of its components (eq. 4.7 summed per class)
        post = np.zeros((f.shape[0], self.classes.size))
        for j, c in enumerate(self.component_class):
            post[:, c] += p[:, j]
        return np.asarray(post / post.sum(axis=1, keepdims=True), dtype=np.float64)

    def predict(self, features: FloatArray) -> IntArray:
        """Activity codes minimizing the expected loss (eq. 4.6)."""
        post = self.posteriors(features)
        risk = post @ self.loss.T  # risk[w, c] = sum_k P(k|theta_w) L[c, k]
        return np.asarray(self.classes[np.argmin(risk, axis=1)], dtype=np.int64)


def transform_features(features: FloatArray, log_features: bool) -> FloatArray:
    """The classifier's input: the features, or their logarithm (see :class:`LdaModel`)."""
    if not log_features:
        return features
    return np.asarray(np.log(np.clip(features, 0.0, None) + 1e-3), dtype=np.float64)


def _checked_training_data(features: FloatArray, labels: ArrayLike, *,
                          groups: ArrayLike | None, covariance: str, pooled_blend: float
                          ) -> tuple[FloatArray, IntArray, IntArray]:
    """``(features, labels, groups)`` as arrays of one row per window; bad options raise."""
    f = as_matrix(features, where="LDA features", columns=len(LDA_FEATURES))
    y = np.asarray(labels, dtype=np.int64)
    if y.shape != (f.shape[0],):
        raise InputError(f"{y.shape[0]} labels for {f.shape[0]} windows", where="labels",
                         expected="one label per window")
    g = np.zeros_like(y) if groups is None else np.asarray(groups, dtype=np.int64)
    if g.shape != y.shape:
        raise InputError(f"{g.shape[0]} groups for {y.shape[0]} windows", where="groups",
                         expected="one source group per window")
    if covariance not in ("pooled", "per_class"):
        raise InputError(f"covariance = {covariance!r}", where="covariance",
                         expected="'pooled' or 'per_class'")
    if not 0.0 <= pooled_blend <= 1.0:
        raise InputError(f"pooled_blend = {pooled_blend}", where="pooled_blend",
                         expected="a share in [0, 1]")
    return f, y, g


def _component_covariance(x: FloatArray, members: list[NDArray[np.bool_]], means: FloatArray, *,
                          resid: FloatArray, covariance: str, pooled_blend: float,
                          min_component_windows: int) -> FloatArray:
    """Pooled Ledoit-Wolf covariance, or one per component blended with it (``per_class``)."""
    from sklearn.covariance import ledoit_wolf

    pooled = np.asarray(ledoit_wolf(resid)[0], dtype=np.float64)
    if covariance == "pooled":
        return pooled
    covs = []
    for m, mu in zip(members, means, strict=True):
        if int(m.sum()) < min_component_windows:
            covs.append(pooled)
            continue
        own = np.asarray(ledoit_wolf(x[m] - mu)[0], dtype=np.float64)
        covs.append((1.0 - pooled_blend) * own + pooled_blend * pooled)
    return np.array(covs)


def train_lda(features: FloatArray, labels: ArrayLike, *, window_s: float = 2.0,
              cutoff_hz: float = 6.0, loss: FloatArray | None = None,
              shrinkage: float | str | None = "auto", info: str = "",
              log_features: bool = True, groups: ArrayLike | None = None,
              covariance: Literal["pooled", "per_class"] = "pooled",
              pooled_blend: float = 0.05, min_component_windows: int = 20,
              dft_zero_pad: int = DFT_ZERO_PAD) -> LdaModel:
    """Fit the discriminant parameters with scikit-learn (uniform class priors).

    Parameters
    ----------
    features: (W, 7) Table 4.1 features of labelled windows.
    labels: Activity codes of the windows (W,); UNKNOWN windows are ignored.
    window_s, cutoff_hz, dft_zero_pad: recorded in the model so that prediction uses the same
        features.
    loss: loss matrix over the sorted classes (default :func:`default_loss`).
    shrinkage: covariance shrinkage of the pooled linear discriminant (scikit-learn
        ``LinearDiscriminantAnalysis``; ``"auto"``: Ledoit-Wolf); used when ``covariance`` is
        ``"pooled"`` and ``groups`` is None.
    info: text stored in the model.
    log_features: fit on the logarithm of the features (see :class:`LdaModel`).
    groups: source of each window (W,) (any integers); each (class, source) pair becomes one
        equally weighted component of the class likelihood. None: one component per class.
    covariance: ``"pooled"`` (linear discriminant) or ``"per_class"`` (eq. 4.8's
        ``Sigma_k``, one Ledoit-Wolf covariance per component).
    pooled_blend: share of the pooled covariance mixed into each per-component covariance.
    min_component_windows: components with fewer windows use the pooled covariance.
    """
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    f, y, g = _checked_training_data(features, labels, groups=groups, covariance=covariance,
                                     pooled_blend=pooled_blend)
    keep = y != int(Activity.UNKNOWN)
    f, y, g = f[keep], y[keep], g[keep]
    classes = np.unique(y)
    if classes.size < 2:
        raise InputError(f"{classes.size} class(es) in the labels", where="labels",
                         expected="at least two activities")
    priors = np.full(classes.size, 1.0 / classes.size)
    loss_m = default_loss(classes) if loss is None else np.asarray(loss)
    x = transform_features(f, log_features)
    if groups is None and covariance == "pooled":
        lda = LinearDiscriminantAnalysis(solver="lsqr", shrinkage=shrinkage, priors=priors)
        lda.fit(x, y)
        return LdaModel(classes, lda.means_, lda.covariance_, priors, loss_m, window_s,
                        cutoff_hz, LDA_FEATURES, info, log_features,
                        dft_zero_pad=dft_zero_pad)
    # components: one per (class, group) pair present in the data
    pairs = np.unique(np.column_stack([y, g]), axis=0)
    comp_class = np.searchsorted(classes, pairs[:, 0])
    members = [(y == c) & (g == s) for c, s in pairs]
    means = np.array([x[m].mean(axis=0) for m in members])
    resid = np.concatenate([x[m] - mu for m, mu in zip(members, means, strict=True)])
    cov = _component_covariance(x, members, means, resid=resid, covariance=covariance,
                                pooled_blend=pooled_blend,
                                min_component_windows=min_component_windows)
    counts = np.bincount(comp_class, minlength=classes.size)
    return LdaModel(classes, means, cov, priors, loss_m, window_s, cutoff_hz, LDA_FEATURES,
                    info, log_features, comp_class, 1.0 / counts[comp_class], dft_zero_pad)
