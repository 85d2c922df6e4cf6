"""Rigid-body kinematics as polars expressions: rotations by the logged quaternions, the
velocity of a point of a body, and where a ballistic flight meets a surface.

Vectors are lists of three expressions (x, y, z). The logged quaternion (qw, qx, qy, qz)
rotates the body's (principal, centre-of-mass) frame into the world frame.
"""

from __future__ import annotations

import polars as pl

Vec = list[pl.Expr]


def vec(prefix: str, suffix: str = "") -> Vec:
    """The columns `<prefix>x<suffix>`, `<prefix>y<suffix>`, `<prefix>z<suffix>`."""
    return [pl.col(f"{prefix}{c}{suffix}") for c in "xyz"]


def dot(a: Vec, b: Vec) -> pl.Expr:
    """a . b"""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec, b: Vec) -> Vec:
    """a x b"""
    return [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]


def add(a: Vec, b: Vec) -> Vec:
    """a + b"""
    return [a[i] + b[i] for i in range(3)]


def sub(a: Vec, b: Vec) -> Vec:
    """a - b"""
    return [a[i] - b[i] for i in range(3)]


def norm(a: Vec) -> pl.Expr:
    """|a|"""
    return dot(a, a).sqrt()


def rotate(suffix: str, v: Vec, *, inverse: bool = False) -> Vec:
    """v rotated by the quaternion (qw, qx, qy, qz)<suffix>: body to world (world to body when
    `inverse`): t = 2 u x v, v' = v + qw t + u x t with u the quaternion's vector part."""
    sign = -1.0 if inverse else 1.0
    u = [sign * pl.col(f"q{c}{suffix}") for c in "xyz"]
    t = [2 * c for c in cross(u, v)]
    ut = cross(u, t)
    return [v[i] + pl.col(f"qw{suffix}") * t[i] + ut[i] for i in range(3)]


def named(v: Vec, prefix: str, suffix: str = "") -> list[pl.Expr]:
    """The vector as columns `<prefix>x<suffix>` ..."""
    return [v[i].alias(f"{prefix}{c}{suffix}") for i, c in enumerate("xyz")]


def first_root(c: pl.Expr, b: pl.Expr, a: pl.Expr) -> pl.Expr:
    """Smallest s >= 0 with c + b s + a s^2 / 2 = 0, for c >= 0; null when there is none.

    The numerically stable form 2 c / (-b + sqrt(b^2 - 2 a c)); c <= 0 gives 0.
    """
    disc = b * b - 2 * a * c
    denom = -b + disc.clip(0.0).sqrt()
    return (
        pl.when(c <= 0)
        .then(pl.lit(0.0))
        .when((disc >= 0) & (denom > 0))
        .then(2 * c / denom)
        .otherwise(pl.lit(None, dtype=pl.Float64))
    )
