"""Batched rotations: exponential maps, fixed-axis rotations, Euler angles, yaw-pitch-roll.

Convention: column vectors, ``v_rotated = R @ v``; angles in radians; every
function keeps any leading batch shape (``x.shape[:-1]`` for vectors,
``R.shape[:-2]`` for matrices). float64 throughout.
"""
from __future__ import annotations

import numpy as np
from numba import njit

_SMALL = 1e-6


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]_x`` of vectors ``(..., 3)`` -> ``(..., 3, 3)``."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


@njit(cache=True, nogil=True)
def exp_map_into(x: float, y: float, z: float, out: np.ndarray) -> None:
    """The rotation matrix of one exponential map ``(x, y, z)`` written into ``out`` 3 x 3 (compiled; the one
    implementation behind :func:`exp_map_to_matrix` and the forward-kinematics kernel)."""
    t2 = x * x + y * y + z * z
    t = np.sqrt(t2)
    if t < _SMALL:
        a = 1.0 - t2 / 6.0
        b = 0.5 - t2 / 24.0
    else:
        a = np.sin(t) / t
        b = (1.0 - np.cos(t)) / (t * t)
    # [v]_x^2 = v v^T - t^2 I, written out.
    out[0, 0] = 1.0 - b * (y * y + z * z)
    out[1, 1] = 1.0 - b * (x * x + z * z)
    out[2, 2] = 1.0 - b * (x * x + y * y)
    out[0, 1] = b * x * y - a * z
    out[1, 0] = b * x * y + a * z
    out[0, 2] = b * x * z + a * y
    out[2, 0] = b * x * z - a * y
    out[1, 2] = b * y * z - a * x
    out[2, 1] = b * y * z + a * x


@njit(cache=True, nogil=True)
def _exp_maps(v: np.ndarray, out: np.ndarray) -> None:
    for i in range(v.shape[0]):
        exp_map_into(v[i, 0], v[i, 1], v[i, 2], out[i])


def exp_map_to_matrix(v: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` from exponential maps (axis * angle) ``(..., 3)``.

    Rodrigues' formula ``R = I + a [v]_x + b [v]_x^2`` with ``a = sin t / t`` and
    ``b = (1 - cos t) / t^2``, ``t = |v|``. Below ``t = 1e-6`` both coefficients use
    their Taylor series, so the map is smooth (and exact to float precision) at zero.
    """
    v = np.asarray(v, dtype=float)
    flat = np.ascontiguousarray(v.reshape(-1, 3))
    out = np.empty((len(flat), 3, 3))
    _exp_maps(flat, out)
    return out.reshape(v.shape[:-1] + (3, 3))


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` as ``(w, x, y, z)`` with ``w >= 0`` from rotations ``(..., 3, 3)``.

    Shepperd's method: of the four candidate formulas the one with the largest
    denominator is used per element, which keeps it accurate near 180 degrees.
    """
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    trace = m00 + m11 + m22
    cand = np.stack([trace, m00, m11, m22], axis=-1)
    choice = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # Case 0: w largest.
    s = np.sqrt(np.maximum(1.0 + trace, 1e-300)) * 2.0
    q0 = np.stack([0.25 * s, (R[..., 2, 1] - R[..., 1, 2]) / s, (R[..., 0, 2] - R[..., 2, 0]) / s,
                   (R[..., 1, 0] - R[..., 0, 1]) / s], axis=-1)
    s = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 1e-300)) * 2.0
    q1 = np.stack([(R[..., 2, 1] - R[..., 1, 2]) / s, 0.25 * s, (R[..., 0, 1] + R[..., 1, 0]) / s,
                   (R[..., 0, 2] + R[..., 2, 0]) / s], axis=-1)
    s = np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 1e-300)) * 2.0
    q2 = np.stack([(R[..., 0, 2] - R[..., 2, 0]) / s, (R[..., 0, 1] + R[..., 1, 0]) / s, 0.25 * s,
                   (R[..., 1, 2] + R[..., 2, 1]) / s], axis=-1)
    s = np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 1e-300)) * 2.0
    q3 = np.stack([(R[..., 1, 0] - R[..., 0, 1]) / s, (R[..., 0, 2] + R[..., 2, 0]) / s,
                   (R[..., 1, 2] + R[..., 2, 1]) / s, 0.25 * s], axis=-1)
    q = np.choose(choice[..., None], [q0, q1, q2, q3])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def matrix_to_exp_map(R: np.ndarray) -> np.ndarray:
    """Exponential maps ``(..., 3)`` with angle in ``[0, pi]`` from rotations ``(..., 3, 3)``.

    At angle zero the result is zero; at exactly pi the axis sign is the one the
    quaternion gives (both signs are the same rotation).
    """
    q = matrix_to_quaternion(R)
    w, xyz = q[..., 0], q[..., 1:]
    n = np.linalg.norm(xyz, axis=-1)
    angle = 2.0 * np.arctan2(n, w)
    small = n < _SMALL
    # angle / n -> 2 / w as n -> 0 (w -> 1).
    scale = np.where(small, 2.0 / np.maximum(w, _SMALL), angle / np.where(small, 1.0, n))
    return xyz * scale[..., None]


def continuous_exp_maps(v: np.ndarray, time_axis: int = -2) -> np.ndarray:
    """Make a sequence of exponential maps continuous along ``time_axis``.

    Each rotation has the equivalent exp maps ``(t + 2 pi k) n``; frame 0 keeps
    its principal value (angle in [0, pi]) and each later frame takes the
    equivalent closest to the frame before it. ``v`` has shape ``(..., T, 3)``
    when ``time_axis = -2``. Used wherever a sequence of orientations is turned
    into exp maps, so the same rotations always give the same vectors.
    """
    v = np.moveaxis(np.array(v, dtype=float), time_axis, 0)
    out = v.copy()
    for i in range(1, v.shape[0]):
        cur, prev = v[i], out[i - 1]
        angle = np.linalg.norm(cur, axis=-1, keepdims=True)
        prev_norm = np.linalg.norm(prev, axis=-1, keepdims=True)
        # The identity has no axis of its own: its equivalents lie along any
        # axis, so take the previous frame's.
        axis = np.where(angle < _SMALL, prev / np.where(prev_norm < _SMALL, 1.0, prev_norm),
                        cur / np.where(angle < _SMALL, 1.0, angle))
        best = cur
        best_d = np.linalg.norm(cur - prev, axis=-1)
        for k in (-2, -1, 1, 2):
            cand = axis * (angle + 2.0 * np.pi * k)
            d = np.linalg.norm(cand - prev, axis=-1)
            better = d < best_d
            best = np.where(better[..., None], cand, best)
            best_d = np.where(better, d, best_d)
        out[i] = best
    return np.moveaxis(out, 0, time_axis)


_AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


def elementary_rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """Rotation about the coordinate axis ``'x'``, ``'y'`` or ``'z'`` by ``angle`` ``(...)``."""
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    i = "xyz".index(axis.lower())
    j, k = (i + 1) % 3, (i + 2) % 3
    out[..., i, i] = 1.0
    out[..., j, j] = c
    out[..., k, k] = c
    out[..., j, k] = -s
    out[..., k, j] = s
    return out


def euler_to_matrix(angles: np.ndarray, axes: str) -> np.ndarray:
    """Product of elementary rotations, left to right: ``R = R_a0(t0) @ R_a1(t1) @ ...``.

    ``angles`` is ``(..., len(axes))``. This is the BVH reading of a channel list
    ("Zrotation Xrotation Yrotation" gives ``Rz @ Rx @ Ry``), i.e. intrinsic
    rotations in the listed order. For the Acclaim (ASF/AMC) reading, where the
    first listed axis is applied first to the vector, pass the reversed order.
    """
    angles = np.asarray(angles, dtype=float)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for n, a in enumerate(axes):
        R = R @ elementary_rotation(a, angles[..., n])
    return R


def yaw_pitch_roll_to_matrix(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` for arrays of equal shape ``(...)``."""
    return elementary_rotation("z", yaw) @ elementary_rotation("y", pitch) @ elementary_rotation("x", roll)


def matrix_to_yaw_pitch_roll(R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`yaw_pitch_roll_to_matrix`; ``pitch`` in ``[-pi/2, pi/2]``.

    ``yaw`` is the heading of the body's forward axis ``R @ e_x`` in the ground
    plane (``atan2``), ``pitch`` its angle below the horizontal, ``roll`` the
    rotation about it. Singular (gimbal lock) only when the forward axis is
    vertical, i.e. the body lies face down or face up.
    """
    R = np.asarray(R, dtype=float)
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    pitch = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    return yaw, pitch, roll
