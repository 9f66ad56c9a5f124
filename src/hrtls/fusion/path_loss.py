"""Log-normal path loss of beacon RSS (Tarrio, Besada, Casar, eq. 1).

``rss = A - 10 eta log10(d/d0) + N(0, sigma)``; inverted to a distance
``d = d0 10^((A - rss)/(10 eta))`` whose log is Gaussian with standard deviation
``sigma ln(10) / (10 eta)`` (so ``sigma_d ~ d sigma ln10/(10 eta)``). :data:`PATH_LOSS_DTYPE` is
the model as a record for compiled code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.session import ChannelModel
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion._records import to_record
from hrtls.kernels import njit

LN10 = math.log(10.0)

PATH_LOSS_DTYPE = np.dtype([("a_dbm", np.float64), ("eta", np.float64),
                            ("sigma_db", np.float64), ("d0_m", np.float64)])
"""Record of :class:`PathLossModel` for compiled code (same field names)."""


@njit(cache=True, error_model="numpy")
def mean_rss_dbm(a_dbm: float, eta: float, d0_m: float, distance_m: FloatArray | float
                 ) -> FloatArray | float:   # pragma: no cover - compiled
    """Mean RSS at ``distance_m`` (m; a scalar or an array), dBm: ``A - 10 eta log10(d/d0)``.

    The one definition of the law for Python and compiled callers.
    """
    return a_dbm - 10.0 * eta * np.log10(distance_m / d0_m)


@dataclass(frozen=True, kw_only=True)
class PathLossModel:
    """Log-normal path loss (Tarrio eq. 1).

    Attributes
    ----------
    a_dbm: RSS at the reference distance ``d0``, dBm (``A``).
    eta: path-loss exponent.
    sigma_db: shadowing standard deviation, dB.
    d0_m: reference distance, m.
    """

    a_dbm: float = -59.0
    eta: float = 2.0
    sigma_db: float = 4.0
    d0_m: float = 1.0

    def __post_init__(self) -> None:
        finite_scalar(self.a_dbm, where="PathLossModel.a_dbm")
        finite_scalar(self.eta, where="PathLossModel.eta", positive=True)
        finite_scalar(self.sigma_db, where="PathLossModel.sigma_db", positive=True)
        finite_scalar(self.d0_m, where="PathLossModel.d0_m", positive=True)

    def record(self) -> np.ndarray:
        """The model as a one-element :data:`PATH_LOSS_DTYPE` array."""
        return to_record(PATH_LOSS_DTYPE, self)

    @classmethod
    def from_channel(cls, channel: ChannelModel) -> PathLossModel:
        """From a session's ``channel`` block."""
        return cls(a_dbm=channel.a_dbm, eta=channel.eta, sigma_db=channel.sigma_db)

    @property
    def sigma_ln(self) -> float:
        """Standard deviation of ``ln d`` implied by the shadowing."""
        return self.sigma_db * LN10 / (10.0 * self.eta)

    def expected_rss(self, distance_m: ArrayLike) -> FloatArray:
        """Mean RSS at a distance, dBm."""
        d = np.asarray(distance_m, dtype=np.float64)
        return np.asarray(mean_rss_dbm(self.a_dbm, self.eta, self.d0_m, d))

    def distance(self, rss_dbm: ArrayLike) -> FloatArray:
        """Distance estimate (the median of the log-normal distance), m."""
        r = np.asarray(rss_dbm, dtype=np.float64)
        return np.asarray(self.d0_m * 10.0 ** ((self.a_dbm - r) / (10.0 * self.eta)))

    def distance_sigma(self, rss_dbm: ArrayLike) -> FloatArray:
        """First-order 1-sigma of :meth:`distance`, m."""
        return np.asarray(self.distance(rss_dbm) * self.sigma_ln)
