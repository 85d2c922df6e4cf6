"""The designer of a target e(v): solref and a rising impedance fitted by the step emulation."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from impactlab.contact.closed_form import ContactModelError, bisect, contact_time_factor
from impactlab.contact.closed_form import zeta_for_restitution as _zeta
from impactlab.contact.curve import RestitutionCurve
from impactlab.contact.params import ContactParams
from impactlab.contact.shaped import MAX_IMPEDANCE, emulate, impedance

CURVE_TOLERANCE = 0.01
"""Accuracy promised for |e - e_target(v)| of every impact whose normal speed lies in a
curve's promised range, between its points too (issue 39); a constant keeps
RESTITUTION_TOLERANCE."""

CURVE_PENETRATION_FRACTION = 0.1
"""The default penetration bound at the top speed of a curve, as a fraction of the smaller
radius (a rising impedance lets the ball sink into a soft layer first)."""

MIN_EMULATED_W0DT = 0.004
"""Finer steps than w0 dt = 0.004 (some 800 per contact) are fitted and checked at it: the
step error there is about 2e-4 and shrinks with the step (and the emulation's time with it
would grow without bound)."""

MAX_W0DT = 1.0
"""The coarsest step a curve is fitted at (about three steps per contact; beyond, Euler's
step of a stiff contact diverges)."""

MAX_GRAVITY_RATIO = 0.3
"""The largest g / (w0 v) at the lowest speed of a curve: above, the ball hardly leaves."""

MAX_SPAN = 100.0
"""The widest curve: its top speed at most this many times its lowest."""

CHECK_SPEEDS, CHECK_PHASES = 41, 16
"""The check of a fit: speeds spaced geometrically over the range (the curve's points
added) and contact-onset phases at each."""

_FIT_SPEEDS, _FIT_PHASES = 9, 4
_BATCH_TIME = 100.0
"""A candidate of the first batch still in contact after this many 1 / w0 is a bad one."""
_STARTS, _NFEV, _NFEV_WARM = 3, 25, 10
_GOOD_FIT = 0.3 * CURVE_TOLERANCE
"""A start whose fit is within this at every fit speed ends the search (the next of the
batch's best _STARTS is tried otherwise)."""
_LOWER = np.array([0.01, -5.0, -4.0, 0.02, 1.0])
_UPPER = np.array([0.9, 4.0, math.log10(0.9), 0.98, 60.0])
"""Bounds of the fitted parameters: zeta, log(w0 width / v_mid), log10 dmin, midpoint,
power (dmax is MuJoCo's largest impedance)."""


@dataclass(frozen=True)
class Fit:
    """A fitted contact at one stiffness and timestep."""

    theta: np.ndarray
    w0: float
    v_mid: float

    @property
    def solref(self) -> tuple[float, float]:
        return (-self.w0 * self.w0, -2.0 * float(self.theta[0]) * self.w0)

    @property
    def solimp(self) -> tuple[float, float, float, float, float]:
        _, log_width, log_dmin, mid, power = (float(x) for x in self.theta)
        width = math.exp(log_width) * self.v_mid / self.w0
        return (10.0**log_dmin, MAX_IMPEDANCE, width, mid, power)


@dataclass(frozen=True)
class Setting:
    """Where a fit holds: range (m/s), timestep (s), integrator, gravity along the normal."""

    speed_range_mps: tuple[float, float]
    timestep_s: float
    integrator: str
    gravity_mps2: float

    @property
    def v_mid(self) -> float:
        return math.sqrt(self.speed_range_mps[0] * self.speed_range_mps[1])

    def impacts(
        self,
        theta: np.ndarray,
        w0: float,
        speeds: np.ndarray,
        phases: int,
        max_time_s: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(e, penetration, contact time) of candidates `theta` (n, 5) at stiffness w0**2,
        shape (n, speeds, phases); an impact not over after `max_time_s` (default: 40 / w0
        plus four times the widest soft layer's crossing at the lowest speed) gets e = 0."""
        theta = np.atleast_2d(theta)
        zeta, log_width, log_dmin, mid, power = theta.T
        n = len(theta)
        solref = np.stack([np.full(n, -w0 * w0), -2.0 * zeta * w0], -1)
        width = np.exp(log_width) * self.v_mid / w0
        solimp = np.stack([10.0**log_dmin, np.full(n, MAX_IMPEDANCE), width, mid, power], -1)
        lo = self.speed_range_mps[0]
        found = emulate(
            solref[:, None, None, :],
            solimp[:, None, None, :],
            np.asarray(speeds, float)[None, :, None],
            ((np.arange(phases) + 0.5) / phases)[None, None, :],
            timestep_s=self.timestep_s,
            gravity_mps2=self.gravity_mps2,
            integrator=self.integrator,
            max_time_s=max_time_s or 40.0 / w0 + 4.0 * float(width.max()) / lo,
        )
        return found.e, found.penetration_m, found.contact_s


def fit_speeds(curve: RestitutionCurve, lo: float, hi: float, n: int) -> np.ndarray:
    """n speeds spaced geometrically over lo..hi, and the curve's points inside it."""
    inside = [v for v in curve.speed_mps if lo <= v <= hi]
    grid = np.geomspace(lo, hi, n) if hi > lo else np.array([lo])
    return np.unique(np.concatenate([grid, inside]))


def fit_shape(
    curve: RestitutionCurve, setting: Setting, w0: float, start: np.ndarray | None = None
) -> np.ndarray:
    """The parameters whose mean e over step phases is nearest the curve (least squares at
    the fit speeds), from `start` or from the best of a seeded random batch."""
    from scipy import optimize  # not at the top: 0.9 s to import, needed only here

    speeds = fit_speeds(curve, *setting.speed_range_mps, _FIT_SPEEDS)
    target = curve.at(speeds)

    def mean_e(theta: np.ndarray, max_time_s: float | None = None) -> np.ndarray:
        e, _, _ = setting.impacts(theta, w0, speeds, _FIT_PHASES, max_time_s)
        mean: np.ndarray = e.mean(-1)
        return mean

    if start is None:
        batch = _LOWER + (_UPPER - _LOWER) * np.random.default_rng(39).random((128, 5))
        worst = np.abs(mean_e(batch, _BATCH_TIME / w0) - target).max(-1)
        starts = batch[np.argsort(worst)[:_STARTS]]
    else:
        starts = np.atleast_2d(start)
    steps = 1e-3 * (_UPPER - _LOWER)

    def jacobian(theta: np.ndarray) -> np.ndarray:
        moved = np.minimum(theta + np.diag(steps), _UPPER)
        moved = np.where(moved == theta, theta - np.diag(steps), moved)
        e = mean_e(np.vstack([theta, moved]))
        jac: np.ndarray = ((e[1:] - e[0]) / (moved - theta).sum(-1)[:, None]).T
        return jac

    best, best_cost = starts[0], math.inf
    for theta0 in starts:
        sol = optimize.least_squares(
            lambda th: mean_e(th)[0] - target,
            np.clip(theta0, _LOWER, _UPPER),
            jac=jacobian,
            bounds=(_LOWER, _UPPER),
            x_scale=_UPPER - _LOWER,
            max_nfev=_NFEV if start is None else _NFEV_WARM,
        )
        if sol.cost < best_cost:
            best, best_cost = sol.x, sol.cost
        if np.max(np.abs(sol.fun)) <= _GOOD_FIT:
            break
    return np.asarray(best, float)


@dataclass(frozen=True)
class Checked:
    """A fit checked on the dense grid: the worst |e - target| over speeds and phases, the
    mean e at the curve's points, the worst penetration at the top speed and the mean
    contact time at the reference speed."""

    fit: Fit
    worst_error: float
    achieved: tuple[float, ...]
    penetration_m: float
    contact_s: float


def check(curve: RestitutionCurve, setting: Setting, fit: Fit, reference_mps: float) -> Checked:
    """The fit's worst error on CHECK_SPEEDS x CHECK_PHASES, and its figures."""
    lo, hi = setting.speed_range_mps
    dense = fit_speeds(curve, lo, hi, CHECK_SPEEDS)
    points = np.array(curve.speed_mps)
    speeds = np.concatenate([dense, points, [hi, reference_mps]])
    e, pen, time = setting.impacts(fit.theta, fit.w0, speeds, CHECK_PHASES)
    e, pen, time = e[0], pen[0], time[0]
    n, m = dense.size, points.size
    worst = float(np.abs(e[:n] - curve.at(dense)[:, None]).max())
    return Checked(
        fit,
        worst,
        tuple(float(x) for x in e[n : n + m].mean(-1)),
        float(pen[n + m].max()),
        float(np.mean(time[n + m + 1])),  # NaN when a ball does not leave
    )


def design_curve(
    curve: RestitutionCurve,
    setting: Setting,
    *,
    bound_m: float | None,
    duration_s: float | None,
    reference_mps: float,
    start: Fit | None = None,
) -> Checked:
    """Fit at a stiffness (from `start` when given), rescale the stiffness to meet the
    penetration bound at the top speed (or the contact time at the reference speed), fit
    again from there, rescale again: at a fixed shape (width in units of v_mid / w0) both
    scale as 1 / w0, and e changes only through w0 dt and g / (w0 v)."""
    e_ref = float(curve.at(reference_mps))
    if duration_s is not None:
        w0 = contact_time_factor(_zeta(min(max(e_ref, 0.14), 1.0))) / duration_s
    else:
        assert bound_m is not None
        w0 = 1.2 * setting.speed_range_mps[1] / bound_m
    within_reach(setting, w0)
    dt = emulated_timestep(setting.timestep_s, w0)
    setting = Setting(setting.speed_range_mps, dt, setting.integrator, setting.gravity_mps2)

    def rescaled(theta: np.ndarray, w0: float) -> Checked:
        for _ in range(8):
            found = check(curve, setting, Fit(theta, w0, setting.v_mid), reference_mps)
            if duration_s is not None:
                ratio = found.contact_s / duration_s
                if not math.isfinite(ratio) or abs(ratio - 1.0) <= 0.01:
                    break
            else:
                assert bound_m is not None
                ratio = found.penetration_m / (0.995 * bound_m)
                if 0.99 <= ratio <= 1.0:
                    break
            w0 *= ratio
        return found

    if start is None:
        found = rescaled(fit_shape(curve, setting, w0), w0)
    else:
        found = rescaled(fit_shape(curve, setting, start.w0, start.theta), start.w0)
    refit = fit_shape(curve, setting, found.fit.w0, found.fit.theta)
    return rescaled(refit, found.fit.w0)


def within_reach(setting: Setting, w0: float) -> None:
    """Refuse before fitting what no fit can do: a step of more than MAX_W0DT / w0, or
    gravity above MAX_GRAVITY_RATIO w0 v at the lowest speed (w0 from the penetration bound
    or the contact time).

    Raises:
        ContactModelError: naming the timestep, or the speeds and penetration, that would do.
    """
    dt, g, lo = setting.timestep_s, setting.gravity_mps2, setting.speed_range_mps[0]
    if w0 * dt > MAX_W0DT:
        raise ContactModelError(
            f"timestep {dt:g} s is too coarse for this contact (stiffness about {w0 * w0:.3g} "
            f"1/s^2 from its penetration bound or contact time: w0 dt = {w0 * dt:.3g}): a "
            f"curve needs timestep <= {MAX_W0DT / w0:.3g} s, or a softer contact"
        )
    if g / (w0 * lo) > MAX_GRAVITY_RATIO:
        raise ContactModelError(
            f"gravity dominates this contact at {lo:g} m/s (g / (w0 v) = {g / (w0 * lo):.3g}, "
            f"stiffness about {w0 * w0:.3g} 1/s^2): a curve needs its lowest speed >= "
            f"{g / (MAX_GRAVITY_RATIO * w0):.3g} m/s, or a stiffer contact (a smaller "
            "penetration bound or a shorter contact time)"
        )


def emulated_timestep(timestep_s: float, w0: float) -> float:
    """The timestep a contact of stiffness w0**2 is emulated at (MIN_EMULATED_W0DT)."""
    return max(timestep_s, MIN_EMULATED_W0DT / w0)


def rest_sink_m(params: ContactParams) -> float:
    """How deep a ball at rest sinks into the contact (m): where K d(p)^2 p = (1 - d(p)) g,
    K = k / dmax^2 (0 without gravity)."""
    g = params.gravity_mps2
    if g <= 0.0:
        return 0.0
    solimp = np.array(params.solimp)
    stiff = params.stiffness / min(max(params.solimp[1], 1e-4), MAX_IMPEDANCE) ** 2

    def excess(p: float) -> float:
        d = float(impedance(solimp, np.array(p)))
        return stiff * d * d * p - (1.0 - d) * g

    hi = 1e-9
    while excess(hi) < 0.0 and hi < 1e3:
        hi *= 2.0
    return bisect(excess, 0.0, hi, tol=1e-12 * hi) if hi < 1e3 else math.inf


@functools.lru_cache(maxsize=64)
def cached_design(
    curve: RestitutionCurve,
    setting: Setting,
    bound_m: float | None,
    duration_s: float | None,
    reference_mps: float,
) -> Checked:
    """:func:`design_curve`, once per process for the same arguments."""
    return design_curve(
        curve, setting, bound_m=bound_m, duration_s=duration_s, reference_mps=reference_mps
    )


def better_timestep(
    curve: RestitutionCurve,
    setting: Setting,
    found: Checked,
    *,
    bound_m: float | None,
    duration_s: float | None,
    reference_mps: float,
) -> tuple[float, float] | None:
    """(timestep, worst error) measured by fitting at dt/2, then dt/4 (from `found`'s fit):
    the first that meets CURVE_TOLERANCE, else the better one if it beats `found` by a
    tenth; None when neither does (the curve is beyond the contact model, not the step)."""
    best = None
    for div in (2.0, 4.0):
        finer = Setting(
            setting.speed_range_mps,
            setting.timestep_s / div,
            setting.integrator,
            setting.gravity_mps2,
        )
        again = design_curve(
            curve,
            finer,
            bound_m=bound_m,
            duration_s=duration_s,
            reference_mps=reference_mps,
            start=found.fit,
        )
        if again.worst_error <= CURVE_TOLERANCE:
            return finer.timestep_s, again.worst_error
        if again.worst_error >= 0.9 * (found.worst_error if best is None else best[1]):
            break
        best = finer.timestep_s, again.worst_error
    return best
