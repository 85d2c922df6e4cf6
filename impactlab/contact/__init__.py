"""The contact model: a target coefficient of restitution -> MuJoCo contact parameters."""

from impactlab.contact.advice import ContactDesign, Prediction, predict
from impactlab.contact.closed_form import (
    RESTITUTION_FLOOR,
    ContactModelError,
    contact_time_factor,
    max_penetration_factor,
    restitution_closed_form,
    zeta_for_restitution,
)
from impactlab.contact.curve import RestitutionCurve
from impactlab.contact.curvefit import CURVE_TOLERANCE, rest_sink_m
from impactlab.contact.design import (
    SPEED_FLOOR_MPS,
    SPREAD_BUDGET,
    CurveOutOfReach,
    contact_params,
    design_contact,
)
from impactlab.contact.emulation import IMPEDANCE, SCHEMES, SOLIMP, restitution_spread
from impactlab.contact.params import ContactParams
from impactlab.contact.table import RESTITUTION_TOLERANCE

INTEGRATORS = tuple(SCHEMES)
"""MuJoCo's integrators, every one calibrated (implicit and implicitfast step this contact as
Euler does)."""

__all__ = [
    "CURVE_TOLERANCE",
    "IMPEDANCE",
    "INTEGRATORS",
    "RESTITUTION_FLOOR",
    "RESTITUTION_TOLERANCE",
    "SOLIMP",
    "SPEED_FLOOR_MPS",
    "SPREAD_BUDGET",
    "ContactDesign",
    "ContactModelError",
    "ContactParams",
    "CurveOutOfReach",
    "Prediction",
    "RestitutionCurve",
    "contact_params",
    "contact_time_factor",
    "design_contact",
    "max_penetration_factor",
    "predict",
    "rest_sink_m",
    "restitution_closed_form",
    "restitution_spread",
    "zeta_for_restitution",
]
