"""Rigid-body kinematics on arrays of contacts: rotations by the logged quaternions, rotation
at a constant angular velocity, and the first time a free flight reaches a surface.

Every function works on n rows at once: vectors are (n, 3), quaternions (n, 4) as logged
(qw, qx, qy, qz: the body's principal frame to the world), times (n,); NaN propagates
(a row without a state stays without a result).
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a . b, (n,)."""
    out: np.ndarray = np.einsum("ij,ij->i", a, b)
    return out


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b, (n, 3): np.cross's formula for 3-vectors without its per-call overhead
    (which dominates on the few rows of one run's contacts)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def rotate(q: np.ndarray, v: np.ndarray, *, inverse: bool = False) -> np.ndarray:
    """v rotated by q (body to world; world to body when `inverse`), (n, 3).

    t = 2 u x v, v' = v + qw t + u x t with u the quaternion's vector part (negated to invert).
    """
    u = -q[:, 1:] if inverse else q[:, 1:]
    t = 2 * cross(u, v)
    out: np.ndarray = v + q[:, :1] * t + cross(u, t)
    return out


def turn(r: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
    """r after s seconds of rotation at the constant angular velocity w (Rodrigues), (n, 3)."""
    size = np.linalg.norm(w, axis=1)
    axis = np.divide(w, size[:, None], out=np.zeros_like(w), where=size[:, None] > 0)
    angle = (size * s)[:, None]
    along = dot(axis, r)[:, None]
    out: np.ndarray = (
        r * np.cos(angle) + cross(axis, r) * np.sin(angle) + axis * along * (1 - np.cos(angle))
    )
    return out


def first_root(c: np.ndarray, b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Smallest s >= 0 with c + b s + a s^2 / 2 = 0 for c >= 0 (0 when c <= 0), NaN when none.

    The numerically stable form 2 c / (-b + sqrt(b^2 - 2 a c)).
    """
    disc = b * b - 2 * a * c
    denom = -b + np.sqrt(np.clip(disc, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where((disc >= 0) & (denom > 0), 2 * c / denom, np.nan)
    return np.where(c <= 0, 0.0, root)
