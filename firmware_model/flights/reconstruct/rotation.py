"""Quaternions (scalar first, body -> site) and rotation vectors, vectorised over leading axes."""

from __future__ import annotations

import numpy as np


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a (x) b over the last axis."""
    w1, x1, y1, z1 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    w2, x2, y2, z2 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def exp_rv(v: np.ndarray) -> np.ndarray:
    """Rotation vector(s) (..., 3) -> unit quaternion(s) (..., 4)."""
    ang = np.linalg.norm(v, axis=-1)
    half = 0.5 * ang
    small = ang < 1e-8
    k = np.where(small, 0.5 - ang * ang / 48.0, np.sin(half) / np.where(small, 1.0, ang))
    return np.concatenate([np.cos(half)[..., None], v * k[..., None]], axis=-1)


def log_q(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) -> rotation vector(s), angle in [0, pi] (the shorter way)."""
    q = np.where(q[..., :1] < 0, -q, q)
    s = np.linalg.norm(q[..., 1:], axis=-1)
    ang = 2.0 * np.arctan2(s, q[..., 0])
    small = s < 1e-8
    k = np.where(small, 2.0 / np.where(small, q[..., 0], 1.0), ang / np.where(small, 1.0, s))
    return q[..., 1:] * k[..., None]


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R(q) v over the last axis (body -> site)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def tilt_deg(q: np.ndarray) -> np.ndarray:
    """Angle (deg) between the body z axis (the rocket's axis) and the site's vertical."""
    axis_z = 1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2)
    return np.degrees(np.arccos(np.clip(axis_z, -1.0, 1.0)))


def attitude_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Site-frame rotation vector e with q_true = exp(e) (x) q_est (the filter's error convention)."""
    return log_q(qmul(q_true, qconj(q_est)))
