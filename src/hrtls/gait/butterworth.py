"""Digital Butterworth low-pass as second-order sections, and the kernel that runs them.

Written here rather than taken from ``scipy.signal``, whose import is slow (it pulls in
``scipy.stats``): ``hrtls track`` does not import it. ``tests/gait/test_butterworth.py`` checks
the design, the steady state, the response and the filtered output against ``scipy.signal``
(the reference), to the bit.

Design (bilinear transform with pre-warping, Oppenheim & Schafer Sec. 7.2): the analog
prototype of order ``N`` with unit cutoff has the poles ``s_m = -exp(i pi m / (2 N))``,
``m = -N+1, -N+3, ..., N-1``; scaled to the pre-warped cutoff ``W = 4 tan(pi f_c / f_s)``
(sampling period 1/2, so ``K = 2 / T = 4``) and mapped by ``z = (K + s) / (K - s)``; the
``N`` zeros are at ``z = -1`` and the gain ``k = W^N / prod(K - W s_m)`` gives unit gain at DC.
Conjugate pole pairs make sections ``[1, 2, 1] / [1, -2 Re p, |p|^2]``, the real pole of an odd
order ``[1, 2, 1] / [1, -p, 0]`` (its second pole at 0); sections are ordered by their poles'
distance to the unit circle, farthest first. An odd order has one zero at 0 (``[1, 1, 0]``):
in the section nearest the circle whose poles are nearer 0 than -1, else in the real pole's.
The gain multiplies the first numerator (the layout of ``scipy.signal.butter(...,
output="sos")``, whose sections pair each pole with its nearest zeros).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrtls.kernels import njit

FloatArray = NDArray[np.float64]


def butter_lowpass_sos(order: int, cutoff_hz: float, rate_hz: float) -> FloatArray:
    """Second-order sections ``(ceil(order / 2), 6)`` of the Butterworth low-pass.

    Rows are ``[b0, b1, b2, 1, a1, a2]``; ``0 < cutoff_hz < rate_hz / 2`` (checked by callers).
    """
    m = np.arange(-order + 1, order, 2)
    s = -np.exp(1j * np.pi * m / (2 * order))              # analog prototype poles
    warped = 4.0 * np.tan(np.pi * (2.0 * cutoff_hz / rate_hz) / 2.0)  # pre-warped, K = 4
    s = warped * s
    p = (4.0 + s) / (4.0 - s)                              # bilinear transform
    gain = warped ** order * np.real((1.0 + 0j) / np.prod(4.0 - s))
    pairs = p[p.imag > 0]
    pairs = pairs[np.argsort(-np.abs(1.0 - np.abs(pairs)), kind="stable")]
    rows = [[1.0, 2.0, 1.0, 1.0, -float(np.real(r)), 0.0] for r in p[p.imag == 0]]
    rows += [[1.0, 2.0, 1.0, 1.0, -2.0 * c.real, c.real * c.real + c.imag * c.imag]
             for c in pairs]
    sos = np.array(rows, dtype=np.float64)
    if order % 2:  # N + 1 poles with the one at 0, so one zero at 0 too
        nearer = [k + 1 for k, c in enumerate(pairs) if abs(c) < abs(c + 1.0)]
        sos[nearer[-1] if nearer else 0, :3] = (1.0, 1.0, 0.0)
    sos[0, :3] *= gain
    return sos


def sos_steady_state(sos: FloatArray) -> FloatArray:
    """Section memory ``(S, 2)`` of the transposed direct form II at rest under a unit input.

    A section ``b / a`` fed a constant ``u`` holds ``z`` with ``z0 = b1 u - a1 y + z1``,
    ``z1 = b2 u - a2 y`` and ``y = b0 u + z0``: ``[[1 + a1, -1], [a2, 1]] z / u = b[1:] - b0
    a[1:]``; the next section is fed ``y = u sum(b) / sum(a)``.
    """
    zi = np.empty((len(sos), 2))
    u = 1.0
    for k, (b0, b1, b2, _, a1, a2) in enumerate(sos):
        system = np.array([[1.0 + a1, -1.0], [a2, 1.0]])
        zi[k] = u * np.linalg.solve(system, np.array([b1 - a1 * b0, b2 - a2 * b0]))
        u *= (b0 + b1 + b2) / (1.0 + a1 + a2)
    return zi


def sos_response(sos: FloatArray, frequency_hz: FloatArray,
                 rate_hz: float) -> NDArray[np.complex128]:
    """Complex frequency response of the sections at ``frequency_hz``."""
    w = 2.0 * np.pi * np.asarray(frequency_hz, dtype=np.float64) / rate_hz  # rad/sample
    z1 = np.exp(-1j * w)
    h = np.ones(z1.shape, dtype=np.complex128)
    for b0, b1, b2, a0, a1, a2 in sos:
        h *= (b0 + (b1 + b2 * z1) * z1) / (a0 + (a1 + a2 * z1) * z1)
    return h


@njit(cache=True)
def sos_kernel(sos: FloatArray, x: FloatArray, zi: FloatArray,
               y: FloatArray) -> None:  # pragma: no cover
    """Filter the columns of ``x`` (N, K) into ``y``; ``zi`` (S, 2, K) is updated in place.

    Transposed direct form II per section: ``y = b0 u + z0``, ``z0 = b1 u - a1 y + z1``,
    ``z1 = b2 u - a2 y``.
    """
    n, k_cols = x.shape
    for c in range(k_cols):
        for i in range(n):
            u = x[i, c]
            for s in range(sos.shape[0]):
                v = sos[s, 0] * u + zi[s, 0, c]
                zi[s, 0, c] = sos[s, 1] * u - sos[s, 4] * v + zi[s, 1, c]
                zi[s, 1, c] = sos[s, 2] * u - sos[s, 5] * v
                u = v
            y[i, c] = u
