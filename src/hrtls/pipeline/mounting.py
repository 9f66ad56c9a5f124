"""Device->body mounting of a phone held in front of the body, from the accelerometer alone.

A phone held in front of the walker in portrait points its top edge (device +y) in the walking
direction; its mean tilt is seen in the mean specific force over the walk (the accelerations of
the steps average out, the gravity reaction stays). :func:`handheld_mounting_q_bd` turns these
two facts into the fixed rotation ``q_bd`` of ``SessionMeta.mounting_q_bd``
(``q_nd = q_nb * q_bd``). No ground truth or magnetometer is involved.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.errors import InputError
from hrtls.frames import quat_from_rotation

FloatArray = NDArray[np.float64]

HANDHELD_FORWARD_D = (0.0, 1.0, 0.0)
"""Device axis along the walking direction of a phone held in portrait (its top edge)."""
HANDHELD_PLACEMENTS = frozenset({"hand", "handheld", "hand-held"})
"""``SessionMeta.placement`` values of a device held in the hand (case-insensitive)."""


def declared_handheld(placement: str | None) -> bool:
    """Whether ``SessionMeta.placement`` says the device is held in the hand."""
    return (placement or "").strip().lower() in HANDHELD_PLACEMENTS


def uses_handheld_mounting(mounting: str, placement: str | None) -> bool:
    """Whether ``[attitude] mounting`` holds the first samples for a hand-held mounting.

    ``handheld`` always; ``auto`` when the session says the device is held in the hand, or
    says nothing of where it is (then the samples decide, :func:`looks_handheld`);
    ``session`` never.
    """
    return mounting == "handheld" or (
        mounting == "auto" and (declared_handheld(placement) or not (placement or "").strip()))


def looks_handheld(acc_d_m_s2: ArrayLike, *, screen_tilt_deg: tuple[float, float]
                   ) -> tuple[bool, str]:
    """Whether the mean specific force is that of a phone held in front in portrait.

    Such a phone is read while walking: its screen normal (device +z) points up, tilted from
    the vertical by ``screen_tilt_deg`` (min, max), and its top edge (+y) is the higher one
    (the long axis more vertical than the short one). Flat (a table, a bag) or upright (a
    pocket, a belt clip, a lower-back wearable) devices fall outside. Returns the verdict and
    the tilt in words.
    """
    acc = np.asarray(acc_d_m_s2, dtype=np.float64)
    up = acc.mean(axis=0) if acc.ndim == 2 and len(acc) else np.full(3, np.nan)
    norm = float(np.linalg.norm(up))
    if not (np.isfinite(norm) and norm > 1.0):
        return False, "no usable mean specific force"
    ux, uy, uz = up / norm
    tilt = float(np.degrees(np.arccos(np.clip(uz, -1.0, 1.0))))
    portrait = bool(uy > abs(ux))
    ok = bool(screen_tilt_deg[0] <= tilt <= screen_tilt_deg[1] and portrait)
    return ok, (f"screen {tilt:.0f} deg from the vertical, "
                f"{'top edge up' if portrait else 'not portrait with the top edge up'}")


def handheld_mounting_q_bd(acc_d_m_s2: ArrayLike, *,
                           forward_d: Sequence[float] = HANDHELD_FORWARD_D) -> FloatArray:
    """Device->body rotation of a phone held in front of the body.

    Body z (up) is the mean specific-force direction in the device frame (gravity reaction,
    the mean tilt of the hand-held phone); body x (forward) is ``forward_d`` (device +y, the top
    edge in portrait) with its component along body z removed; body y = z x x (left).

    Parameters
    ----------
    acc_d_m_s2:
        Device-frame accelerometer samples (N, 3), m/s^2, over the walk.
    forward_d:
        Device axis that points in the walking direction.

    Returns
    -------
    ``q_bd`` [w, x, y, z]: rotates device-frame vectors into the body frame
    (``q_nd = q_nb * q_bd``, the convention of ``SessionMeta.mounting_q_bd``).
    """
    acc = np.asarray(acc_d_m_s2, dtype=np.float64)
    if acc.ndim != 2 or acc.shape[1] != 3 or acc.shape[0] == 0:
        raise InputError(f"shape {acc.shape}", where="acc_d_m_s2", expected="(N, 3), N >= 1")
    if not np.all(np.isfinite(acc)):
        i = int(np.flatnonzero(~np.all(np.isfinite(acc), axis=1))[0])
        raise InputError("non-finite sample", where=f"acc_d_m_s2 row {i}",
                         expected="finite m/s^2")
    up = acc.mean(axis=0)
    norm = float(np.linalg.norm(up))
    if norm < 1.0:
        raise InputError(f"mean specific force {norm:.3g} m/s^2", where="acc_d_m_s2",
                         expected="about 9.8 m/s^2 (a device carried by a walker)")
    z_b = up / norm
    fwd = np.asarray(forward_d, dtype=np.float64)
    if fwd.shape != (3,) or not np.all(np.isfinite(fwd)) or np.linalg.norm(fwd) == 0:
        raise InputError(f"{forward_d}", where="forward_d", expected="a non-zero 3-vector")
    fwd = fwd / np.linalg.norm(fwd)
    x_raw = fwd - float(fwd @ z_b) * z_b
    if np.linalg.norm(x_raw) < 0.2:  # forward axis within ~11 deg of vertical
        raise InputError("forward axis is almost vertical", where="forward_d",
                         expected="a device axis that is roughly horizontal while walking")
    x_b = x_raw / np.linalg.norm(x_raw)
    y_b = np.cross(z_b, x_b)
    r_bd = np.vstack([x_b, y_b, z_b])  # rows: body axes in device coordinates
    from scipy.spatial.transform import Rotation  # slow to import: only when used

    return np.asarray(quat_from_rotation(Rotation.from_matrix(r_bd)), dtype=np.float64)
