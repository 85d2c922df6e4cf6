"""Contact parameters that deliver a target restitution (what the designer returns)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ContactParams:
    """MuJoCo contact parameters that deliver a target restitution.

    Attributes:
        solref: ``(-stiffness, -damping)``, MuJoCo's direct form.
        solimp: constant impedance ``(d, d, width, midpoint, power)``.
        stiffness: k in 1/s^2 (acceleration per metre of penetration; mass independent).
        damping: b in 1/s (acceleration per m/s of normal velocity).
        zeta: damping ratio b / (2 sqrt(k)), calibrated for ``timestep_s``.
        duration_s: predicted contact duration in s (independent of the impact speed).
        max_penetration_m: predicted worst-case penetration in m at ``impact_speed_mps``.
        restitution: the target e.
        impact_speed_mps: design impact speed in m/s.
        timestep_s: the timestep in s the calibration is for.
        gravity_mps2: gravity along the contact normal the calibration is for (0: none).
        gravity_shift: predicted change of e by gravity at the design speed (about
            -2 zeta g / (w0 v); 0 without gravity), calibrated out: zeta is chosen so that the
            zero-gravity e is ``restitution - gravity_shift``.
    """

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]
    stiffness: float
    damping: float
    zeta: float
    duration_s: float
    max_penetration_m: float
    restitution: float
    impact_speed_mps: float
    timestep_s: float
    gravity_mps2: float = 0.0
    gravity_shift: float = 0.0

    def mjcf_attributes(self) -> dict[str, str]:
        """Return ``{"solref": ..., "solimp": ...}`` as MJCF attribute strings (full precision)."""
        return {
            "solref": " ".join(repr(float(x)) for x in self.solref),
            "solimp": " ".join(repr(float(x)) for x in self.solimp),
        }
