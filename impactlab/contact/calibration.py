"""One stiffness calibrated: zeta for a target e over a speed range, and the predicted errors."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from impactlab.contact.closed_form import RESTITUTION_FLOOR, ContactModelError, contact_time_factor
from impactlab.contact.emulation import SOLIMP, scheme_of
from impactlab.contact.fast import gravity_shift
from impactlab.contact.params import ContactParams
from impactlab.contact.table import PHASE_BUDGET, calibrated_zeta, discrete, table


@dataclass(frozen=True)
class Request:
    """What a contact must deliver: e within the tolerance of `e` at every normal impact
    speed in `speed_range_mps` (m/s), at a timestep (s) and integrator, under gravity along
    the normal (m/s^2; 0 for two free bodies)."""

    e: float
    speed_range_mps: tuple[float, float]
    timestep_s: float
    integrator: str
    gravity_mps2: float

    @functools.cached_property
    def speeds(self) -> np.ndarray:
        """Where gravity's shift is evaluated (`shift_speeds`), m/s."""
        return shift_speeds(*self.speed_range_mps)

    @classmethod
    def of(cls, params: ContactParams, timestep_s: float | None = None) -> Request:
        """The request a contact was designed for (at another timestep when given)."""
        dt = params.timestep_s if timestep_s is None else timestep_s
        rng, g = params.speed_range_mps, params.gravity_mps2
        return cls(params.restitution, rng, dt, params.integrator, g)


def shift_speeds(lo: float, hi: float) -> np.ndarray:
    """Where gravity's shift is evaluated over a range: geometrically spaced, both ends
    included, four points per decade (at least three). The shift is not monotonic in the
    speed where the constraint grips again on the way out (g / (w0 v) above about 0.1), so
    the ends alone are not enough for wide ranges."""
    if lo == hi:
        return np.array([lo])
    n = max(3, min(13, 1 + math.ceil(4.0 * math.log10(hi / lo))))
    return np.geomspace(lo, hi, n)


def evaluate(request: Request, w0: float) -> ContactParams:
    """Calibrate zeta at stiffness w0**2 for the request: the contact and its predicted errors.

    zeta and gravity's shift depend on each other: a few fixed-point iterations. The shift is
    piecewise constant in zeta (the step in which the ball is back at the surface jumps by one
    for one phase: about h g / (w0 v) / 16), so the iteration stops at 1e-4.

    Raises:
        ContactModelError: gravity's shift cannot be calibrated out at this stiffness.
    """
    e, g, integrator = request.e, request.gravity_mps2, request.integrator
    speeds = request.speeds
    scheme = scheme_of(integrator)
    cap = w0dt_max(integrator)
    h = min(w0 * request.timestep_s, cap)
    ratios = g / (w0 * speeds) if g > 0.0 else np.zeros(speeds.size)
    shift, spread, step = 0.0, 0.0, 0.0
    for _ in range(12):
        zeta = calibrated_zeta(_shifted(e, shift, ratios), h, scheme)
        if g <= 0.0:
            break
        s = np.asarray(gravity_shift(zeta, h, ratios, integrator))
        new = 0.5 * (float(s.max()) + float(s.min()))
        spread = 0.5 * (float(s.max()) - float(s.min()))
        step, shift = abs(new - shift), new
        if step <= 1e-4:
            break
    if step > 1e-3:
        raise ContactModelError(
            f"cannot calibrate e = {e:g} under gravity {g:g} m/s^2 with stiffness {w0 * w0:.4g} "
            f"(g / (w0 v) up to {ratios.max():.3g}): use a stiffer contact or a higher v_lo"
        )
    zeta = calibrated_zeta(_shifted(e, shift, ratios), h, scheme)
    phase, pen = discrete(zeta, h, scheme)
    return ContactParams(
        solref=(-w0 * w0, -2.0 * zeta * w0),
        solimp=SOLIMP,
        stiffness=w0 * w0,
        damping=2.0 * zeta * w0,
        zeta=zeta,
        duration_s=contact_time_factor(zeta) / w0,
        max_penetration_m=request.speed_range_mps[1] * pen / w0,
        restitution=e,
        speed_range_mps=request.speed_range_mps,
        timestep_s=request.timestep_s,
        integrator=integrator,
        gravity_mps2=g,
        gravity_shift=shift,
        gravity_spread=spread,
        phase_error=phase,
    )


def try_evaluate(request: Request, w0: float) -> ContactParams | None:
    """:func:`evaluate`, or None where gravity's shift cannot be calibrated out."""
    try:
        return evaluate(request, w0)
    except ContactModelError:
        return None


def resolved(params: ContactParams | None) -> bool:
    """The timestep resolves this contact: the predicted worst case within PHASE_BUDGET (the
    tolerance minus 0.001 for the table's interpolation), inside the table."""
    if params is None:
        return False
    w0dt = math.sqrt(params.stiffness) * params.timestep_s
    return (
        w0dt <= w0dt_max(params.integrator) * (1.0 + 1e-9)
        and params.predicted_error <= PHASE_BUDGET + 1e-6
    )


def w0dt_max(integrator: str) -> float:
    """The coarsest step (w0 * dt) of the integrator's table."""
    return table(scheme_of(integrator)).w0dt_max


def _shifted(e: float, shift: float, ratios: np.ndarray) -> float:
    """The zero-gravity e to calibrate for so that gravity's shift brings it to e."""
    target = e - shift
    if not RESTITUTION_FLOOR <= target <= 1.0:
        raise ContactModelError(
            f"e = {e:g} cannot be reached under gravity with g / (w0 v) up to "
            f"{float(np.max(ratios)):.3g}: gravity changes e by {shift:+.3g}; use a stiffer "
            "contact"
        )
    return target
