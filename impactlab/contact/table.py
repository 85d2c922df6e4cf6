"""The discretisation tables: how MuJoCo's steps change e over (zeta, w0 * dt)."""

from __future__ import annotations

import argparse
import functools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from impactlab.contact.closed_form import (
    ZETA_MAX,
    bisect,
    max_penetration_factor,
    restitution_closed_form,
)
from impactlab.contact.emulation import IMPEDANCE, emulate_surface

RESTITUTION_TOLERANCE = 0.005
"""Accuracy promised for |e_measured - e_target| at every impact speed in the contact's range."""

PHASE_BUDGET = 0.004
"""Part of the tolerance given to the predicted worst case (phase error plus gravity's spread
over the speed range); the rest covers table interpolation and the residual of the gravity
calibration."""

TABLE_PATHS = {
    "euler": Path(__file__).with_name("restitution_table.json"),
    "rk4": Path(__file__).with_name("restitution_table_rk4.json"),
}


_TABLE_ZETA = np.linspace(0.0, 1.0, 41) ** 1.5


_TABLE_W0DT = np.geomspace(0.002, 0.3, 31)


_TABLE_PHASES = np.linspace(0.0, 1.0, 257)[1:]


def generate_table(scheme: str = "euler") -> dict[str, Any]:
    """Compute the discretisation table over (zeta, w0 * dt) with the mj_step emulation.

    For each node, over 256 contact-onset phases: ``delta`` = midrange of e minus the closed
    form, ``half`` = half the range of e (worst-case phase error once delta is calibrated out),
    ``pen`` = worst-case max penetration * w0 / v_in.

    Args:
        scheme: "euler" (Euler, implicit, implicitfast) or "rk4".

    Returns:
        A JSON-serialisable dict (arrays shaped len(zeta) x len(w0dt)).
    """
    nz, nw = len(_TABLE_ZETA), len(_TABLE_W0DT)
    delta, half, pen = (np.zeros((nz, nw)) for _ in range(3))
    closed = np.array([restitution_closed_form(z) for z in _TABLE_ZETA])
    integrator = "Euler" if scheme == "euler" else "RK4"
    for j, wh in enumerate(_TABLE_W0DT):
        _, e, p = emulate_surface(
            _TABLE_ZETA[:, None], float(wh), _TABLE_PHASES[None, :], integrator=integrator
        )
        delta[:, j] = 0.5 * (e.max(1) + e.min(1)) - closed
        half[:, j] = 0.5 * (e.max(1) - e.min(1))
        pen[:, j] = p.max(1)
    name = "semi-implicit Euler" if scheme == "euler" else "RK4 (four stages)"
    return {
        "generated_by": "python -m impactlab.contact.table",
        "description": (
            "MuJoCo linear spring-dashpot contact (direct solref, solimp d = "
            f"{IMPEDANCE}), zero gravity, {name}; over {len(_TABLE_PHASES)} "
            "contact-onset phases: delta = midrange(e) - closed form, half = range(e) / 2, "
            "pen = max penetration * w0 / v_in"
        ),
        "impedance": IMPEDANCE,
        "zeta": _TABLE_ZETA.tolist(),
        "w0dt": _TABLE_W0DT.tolist(),
        "delta": np.round(delta, 10).tolist(),
        "half": np.round(half, 10).tolist(),
        "pen": np.round(pen, 10).tolist(),
    }


@dataclass(frozen=True)
class Table:
    zeta: np.ndarray
    log_w0dt: np.ndarray
    delta: np.ndarray
    half: np.ndarray
    pen: np.ndarray

    def columns(self, w0dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Interpolate (delta, half, pen) over the zeta grid at w0dt (linear in log w0dt).

        Below the table, delta and half are scaled by w0dt / w0dt_min (both ~ w0dt).
        """
        lw = math.log(w0dt)
        if lw <= self.log_w0dt[0]:
            s = w0dt / math.exp(self.log_w0dt[0])
            p_cont = np.array([max_penetration_factor(z) for z in self.zeta])
            return (
                self.delta[:, 0] * s,
                self.half[:, 0] * s,
                p_cont + (self.pen[:, 0] - p_cont) * s,
            )
        j = int(np.searchsorted(self.log_w0dt, lw)) - 1
        j = min(max(j, 0), len(self.log_w0dt) - 2)
        t = (lw - self.log_w0dt[j]) / (self.log_w0dt[j + 1] - self.log_w0dt[j])
        t = min(t, 1.0)
        return tuple(
            (1.0 - t) * a[:, j] + t * a[:, j + 1] for a in (self.delta, self.half, self.pen)
        )

    @property
    def w0dt_max(self) -> float:
        return float(math.exp(self.log_w0dt[-1]))


@functools.cache
def table(scheme: str = "euler") -> Table:
    """The committed table of a stepping scheme ("euler" or "rk4")."""
    raw = json.loads(TABLE_PATHS[scheme].read_text())
    grids = {k: np.asarray(raw[k], float) for k in ("zeta", "w0dt", "delta", "half", "pen")}
    return Table(log_w0dt=np.log(grids.pop("w0dt")), **grids)


def discrete(zeta: float, w0dt: float, scheme: str = "euler") -> tuple[float, float]:
    """Return (worst phase error, worst penetration factor) at (zeta, w0dt)."""
    tab = table(scheme)
    _, half, pen = tab.columns(w0dt)
    return float(np.interp(zeta, tab.zeta, half)), float(np.interp(zeta, tab.zeta, pen))


def calibrated_zeta(e: float, w0dt: float, scheme: str = "euler") -> float:
    """zeta whose phase-midrange discrete e equals e at w0dt."""
    tab = table(scheme)
    delta, _, _ = tab.columns(w0dt)
    return bisect(
        lambda z: restitution_closed_form(z) + float(np.interp(z, tab.zeta, delta)) - e,
        0.0,
        ZETA_MAX,
    )


def main(argv: Sequence[str] | None = None) -> None:
    """Regenerate the committed calibration tables (`tests/contact/test_restitution.py`
    checks them)."""
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    for scheme, path in sorted(TABLE_PATHS.items()):
        path.write_text(json.dumps(generate_table(scheme), indent=1) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
