"""Activity recognition by linear discriminant analysis (Inderst Sec. 4.1.2, eq. 4.6-4.8).

The seven features of Table 4.1 are classified by the minimum expected loss (eq. 4.6)

    c_hat = argmin_c sum_k P(k | theta) L(c | k)

with Bayes posteriors (eq. 4.7) from Gaussian likelihoods (eq. 4.8). Eq. 4.8 is printed with a
per-class covariance ``Sigma_k``; a *linear* discriminant shares one pooled covariance among the
classes, which is what we fit (scikit-learn ``LinearDiscriminantAnalysis``). The prior is uniform
(Inderst Sec. 4.1.2). Models are plain JSON parameters (never pickle); prediction uses numpy
only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data import Activity
from hrtls.errors import FormatError, InputError
from hrtls.gait._state import FloatArray, as_matrix
from hrtls.gait.features import LDA_FEATURES

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
    """Parameters of a trained LDA activity classifier.

    Attributes
    ----------
    classes: Activity codes of the classes (K,).
    means: class means of the features (K, 7).
    covariance: pooled within-class covariance (7, 7).
    priors: class priors (K,), uniform by default.
    loss: loss matrix ``L[c, k]`` (K, K) of eq. 4.6.
    window_s: window length the features were computed on, s.
    cutoff_hz: low-pass corner used before the features, Hz.
    feature_names: names of the features (Table 4.1 order).
    info: free-form description (training data, accuracy).
    log_features: classify ``log(theta + 1e-3)`` instead of ``theta``: the amplitude features
        spread proportionally to their size (standing vs running differ by 100x), and the
        logarithm makes the class covariances similar, as the pooled covariance assumes.
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

    def __post_init__(self) -> None:
        k = len(self.classes)
        d = len(self.feature_names)
        checks = (("means", self.means, (k, d)), ("covariance", self.covariance, (d, d)),
                  ("priors", self.priors, (k,)), ("loss", self.loss, (k, k)))
        for name, arr, shape in checks:
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise InputError(f"shape {a.shape} or non-finite values", where=f"LDA {name}",
                                 expected=f"finite array of shape {shape}")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "classes", np.asarray(self.classes, dtype=np.int64))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able parameters."""
        return {
            "format": MODEL_FORMAT, "version": 1,
            "classes": [Activity(int(c)).label for c in self.classes],
            "feature_names": list(self.feature_names),
            "means": self.means.tolist(), "covariance": self.covariance.tolist(),
            "priors": self.priors.tolist(), "loss": self.loss.tolist(),
            "window_s": self.window_s, "cutoff_hz": self.cutoff_hz, "info": self.info,
            "log_features": self.log_features,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, where: str = "model") -> LdaModel:
        """Inverse of :meth:`to_dict`; raises :class:`FormatError` on a foreign file."""
        if data.get("format") != MODEL_FORMAT:
            raise FormatError(f"format {data.get('format')!r}", where=where,
                              expected=f"'format': '{MODEL_FORMAT}'")
        try:
            classes = np.array([int(Activity.parse(str(c))) for c in data["classes"]])
            return cls(classes, np.asarray(data["means"]), np.asarray(data["covariance"]),
                       np.asarray(data["priors"]), np.asarray(data["loss"]),
                       float(data["window_s"]), float(data["cutoff_hz"]),
                       tuple(data["feature_names"]), str(data.get("info", "")),
                       bool(data.get("log_features", False)))
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
        """Posterior class probabilities (W, K) (eq. 4.7-4.8 with a pooled covariance)."""
        f = transform_features(as_matrix(features, where="LDA features",
                                         columns=len(self.feature_names)), self.log_features)
        prec = np.linalg.pinv(self.covariance)
        diff = f[:, None, :] - self.means[None, :, :]
        maha = np.einsum("wkd,de,wke->wk", diff, prec, diff)
        logp = -0.5 * maha + np.log(self.priors)[None, :]
        logp -= logp.max(axis=1, keepdims=True)
        p = np.exp(logp)
        return np.asarray(p / p.sum(axis=1, keepdims=True), dtype=np.float64)

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


def train_lda(features: FloatArray, labels: ArrayLike, *, window_s: float = 2.0,
              cutoff_hz: float = 6.0, loss: FloatArray | None = None,
              shrinkage: float | str | None = "auto", info: str = "",
              log_features: bool = True) -> LdaModel:
    """Fit the LDA parameters with scikit-learn (uniform priors, pooled covariance).

    Parameters
    ----------
    features: (W, 7) Table 4.1 features of labelled windows.
    labels: Activity codes of the windows (W,); UNKNOWN windows are ignored.
    window_s, cutoff_hz: recorded in the model so that prediction uses the same features.
    loss: loss matrix over the sorted classes (default :func:`default_loss`).
    shrinkage: covariance shrinkage passed to scikit-learn (``"auto"``: Ledoit-Wolf).
    info: text stored in the model.
    log_features: fit on the logarithm of the features (see :class:`LdaModel`).
    """
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    f = as_matrix(features, where="LDA features", columns=len(LDA_FEATURES))
    y = np.asarray(labels, dtype=np.int64)
    if y.shape != (f.shape[0],):
        raise InputError(f"{y.shape[0]} labels for {f.shape[0]} windows", where="labels",
                         expected="one label per window")
    keep = y != int(Activity.UNKNOWN)
    f, y = f[keep], y[keep]
    classes = np.unique(y)
    if classes.size < 2:
        raise InputError(f"{classes.size} class(es) in the labels", where="labels",
                         expected="at least two activities")
    lda = LinearDiscriminantAnalysis(solver="lsqr", shrinkage=shrinkage,
                                     priors=np.full(classes.size, 1.0 / classes.size))
    lda.fit(transform_features(f, log_features), y)
    return LdaModel(classes, lda.means_, lda.covariance_,
                    np.full(classes.size, 1.0 / classes.size),
                    default_loss(classes) if loss is None else np.asarray(loss),
                    window_s, cutoff_hz, LDA_FEATURES, info, log_features)
