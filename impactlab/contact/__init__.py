"""The contact model: a target coefficient of restitution -> MuJoCo contact parameters.

Owns: the linear spring-dashpot's closed form (`closed_form`), emulations of MuJoCo's step for
one impact per integrator (`emulation`, and `fast` without stepping the contact), the
discretisation tables built from them (`table`, `restitution_table*.json`), gravity's effect
on e (`gravity`), the designer that turns a target over a range of impact speeds into
parameters (`design`, returning `params.ContactParams`; `advice` adds predictions and what to
do when the timestep is too coarse), and a user's model's pairs (`pairs`, `tune`).

May import: numpy, `impactlab.mjcf` (MuJoCo in `pairs` only). Must not import: any stage
(record, analyze, replay, calibrate) or the log format; record and calibrate build on it.
"""

from impactlab.contact.advice import ContactDesign, Prediction, design_contact, predict
from impactlab.contact.closed_form import (
    RESTITUTION_FLOOR,
    ContactModelError,
    contact_time_factor,
    max_penetration_factor,
    restitution_closed_form,
    zeta_for_restitution,
)
from impactlab.contact.design import SPEED_FLOOR_MPS, SPREAD_BUDGET, contact_params
from impactlab.contact.emulation import IMPEDANCE, SCHEMES, SOLIMP
from impactlab.contact.gravity import restitution_spread
from impactlab.contact.params import ContactParams
from impactlab.contact.table import RESTITUTION_TOLERANCE

INTEGRATORS = tuple(SCHEMES)
"""MuJoCo's integrators, every one calibrated (implicit and implicitfast step this contact as
Euler does)."""

__all__ = [
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
    "Prediction",
    "contact_params",
    "contact_time_factor",
    "design_contact",
    "max_penetration_factor",
    "predict",
    "restitution_closed_form",
    "restitution_spread",
    "zeta_for_restitution",
]
