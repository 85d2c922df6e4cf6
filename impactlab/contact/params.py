"""Contact parameters that deliver a target restitution (what the designer returns)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from impactlab.contact.curve import RestitutionCurve
from impactlab.mjcf.pairs import quoteattr


@dataclass(frozen=True)
class ContactParams:
    """MuJoCo contact parameters that deliver a target restitution over a range of speeds.

    Attributes:
        solref: ``(-stiffness, -damping)``, MuJoCo's direct form.
        solimp: ``(dmin, dmax, width, midpoint, power)``: a constant impedance (dmin = dmax)
            for a constant e, one rising with penetration for a curve.
        stiffness: k in 1/s^2 (acceleration per metre of penetration; mass independent).
        damping: b in 1/s (acceleration per m/s of normal velocity).
        zeta: damping ratio b / (2 sqrt(k)), calibrated for ``timestep_s``.
        duration_s: predicted contact duration in s (independent of the impact speed; for a
            curve the time in contact at ``reference_speed_mps``, mean over step phases).
        max_penetration_m: predicted worst-case penetration in m at the top of the speed range.
        restitution: the target e (for a curve: its target at ``reference_speed_mps``; take
            a curve's targets from ``curve.at(v)``).
        speed_range_mps: (lowest, highest) normal impact speed in m/s at which e is promised
            within the tolerance.
        timestep_s: the timestep in s the calibration is for.
        integrator: MuJoCo's integrator the calibration is for.
        gravity_mps2: gravity along the contact normal the calibration is for (0: none).
        gravity_shift: gravity's change of e in the middle of its effect over the speed range
            (about -2 zeta g / (w0 v)), calibrated out: zeta is chosen so that the zero-gravity
            e is ``restitution - gravity_shift``.
        gravity_spread: half the change of e by gravity between the ends of the speed range
            (e is ``restitution - gravity_spread`` at the lowest speed and
            ``restitution + gravity_spread`` at the highest, on average over step phases).
        phase_error: worst-case change of e by where in a step the contact begins (for a
            curve: the worst |e - target| measured by the step emulation over the range,
            between the points too, and over step phases).
        curve: the target e(v) when it depends on the impact speed (None: the constant
            ``restitution``).
        reference_speed_mps: for a curve, the impact speed of ``duration_s`` and
            ``restitution`` (None for a constant).
        curve_achieved: for a curve, the e it delivers at the curve's points (mean over step
            phases; empty for a constant).
    """

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]
    stiffness: float
    damping: float
    zeta: float
    duration_s: float
    max_penetration_m: float
    restitution: float
    speed_range_mps: tuple[float, float]
    timestep_s: float
    integrator: str = "Euler"
    gravity_mps2: float = 0.0
    gravity_shift: float = 0.0
    gravity_spread: float = 0.0
    phase_error: float = 0.0
    curve: RestitutionCurve | None = None
    reference_speed_mps: float | None = None
    curve_achieved: tuple[float, ...] = ()

    @property
    def predicted_error(self) -> float:
        """Predicted worst |e - target| at any impact speed in the range (phase + gravity)."""
        return self.phase_error + self.gravity_spread

    @property
    def steps_per_contact(self) -> float:
        """Contact duration in timesteps."""
        return self.duration_s / self.timestep_s

    def mjcf_attributes(self) -> dict[str, str]:
        """Return ``{"solref": ..., "solimp": ...}`` as MJCF attribute strings (full precision)."""
        return {
            "solref": " ".join(repr(float(x)) for x in self.solref),
            "solimp": " ".join(repr(float(x)) for x in self.solimp),
        }

    def mjcf_pair(
        self, geom1: str, geom2: str, *, condim: int = 1, extra: Sequence[str] = ()
    ) -> str:
        """The one MJCF ``<pair>`` builder: the pair of geoms with this contact (frictionless
        with condim 1), `extra` attributes (e.g. ``friction="1 0.005 0.0001"``) before it."""
        a = self.mjcf_attributes()
        attrs = [f"geom1={quoteattr(geom1)}", f"geom2={quoteattr(geom2)}", f'condim="{condim}"']
        attrs += [*extra, f'solref="{a["solref"]}"', f'solimp="{a["solimp"]}"']
        return "<pair " + " ".join(attrs) + "/>"
