"""The contact model: a target coefficient of restitution -> MuJoCo contact parameters.

Owns: the linear spring-dashpot's closed form (`closed_form`), the exact emulation of
MuJoCo's step for one impact (`emulation`), the discretisation table built from it
(`table`, `restitution_table.json`), gravity's effect on e (`gravity`), the designer that
turns a target into parameters (`design`, returning `params.ContactParams`) and helpers that
measure one impact in MuJoCo (`measure`, used by tests and the calibration).

May import: numpy, and MuJoCo inside `measure` only. Must not import: any stage (record,
analyze, replay, calibrate) or the log format; record and calibrate build on it.
"""

from impactlab.contact.checks import RESTITUTION_FLOOR, ContactModelError
from impactlab.contact.closed_form import (
    contact_time_factor,
    max_penetration_factor,
    restitution_closed_form,
    zeta_for_restitution,
)
from impactlab.contact.design import (
    GRAVITY_RATIO_MAX,
    RESTITUTION_TOLERANCE,
    check_timestep,
    contact_params,
)
from impactlab.contact.emulation import IMPEDANCE, SOLIMP
from impactlab.contact.gravity import restitution_with_gravity, surface_restitution
from impactlab.contact.params import ContactParams

__all__ = [
    "GRAVITY_RATIO_MAX",
    "IMPEDANCE",
    "RESTITUTION_FLOOR",
    "RESTITUTION_TOLERANCE",
    "SOLIMP",
    "ContactModelError",
    "ContactParams",
    "check_timestep",
    "contact_params",
    "contact_time_factor",
    "max_penetration_factor",
    "restitution_closed_form",
    "restitution_with_gravity",
    "surface_restitution",
    "zeta_for_restitution",
]
