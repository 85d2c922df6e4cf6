"""Calibration grids and the experiment specs (TOML text) of their points.

Three kinds of run, each one short impact with a calibrated contact (``[contact] restitution``):

- ``plane``: a ball (radius 0.1 m) on the floor with gravity. It starts a few steps of travel
  above the plane, moving down so that it arrives at the requested impact speed, and the
  contact is designed for that speed (``contact.speed_range = [v, v]``). The run ends a little after
  the contact (``stop.max_time``), long before the apex.
- ``ball``: two balls (radius 0.1 m) head-on along x in zero gravity, closing at the requested
  speed (ball 1 at +0.6 v, ball 2 at -0.4 v, so the total momentum is not zero), stopped once
  their surfaces are apart again (``stop.separation``).
- ``lowspeed``: the ``plane`` run with the contact designed for ``design_speed`` (1 m/s) and
  hitting the floor slower (0.05 .. 1 m/s): e then depends on the impact speed through gravity.
- ``bounces``: a ball of some radius and mass dropped onto the floor and bouncing several times
  (``impactlab.calibrate.bounces``), its contact holding e over a speed range.

The timestep of each point is the largest of ``TIMESTEP_LADDER`` that the restitution module
accepts for the contact (``contact_params`` raises when the timestep does not resolve it), and
every step is logged (the analysis takes the velocities one logged step before and after the
contact, so a coarser log would add up to ``every * g * dt`` of free flight).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from impactlab.contact import ContactModelError, ContactParams, contact_params

RADIUS_M = 0.1
GRAVITY_MPS2 = 9.81
TIMESTEP_LADDER = (5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6, 5e-7)
GAP_STEPS = 3.37
"""Free flight before the contact, in steps of travel (not an integer, so the contact does
not begin at the same phase of a step in every run)."""
BALL_SPLIT = 0.6
"""Ball 1 moves at +BALL_SPLIT * v, ball 2 at -(1 - BALL_SPLIT) * v (closing speed v)."""
LOWSPEED_MAX_TIMESTEP = 5e-6
"""The analysis takes the velocities one logged step before and after the contact, so they
carry up to g * dt of free flight; at 0.05 m/s and dt = 5e-5 s that is 1 % of e. The
low-speed study uses at most 5e-6 s (0.1 % at 0.05 m/s)."""
KINDS = ("plane", "ball", "lowspeed", "bounces")


@dataclass(frozen=True)
class BounceCase:
    """One multi-bounce drop: target e, radius (m), mass (kg), the contact's range, integrator.

    ``low`` None: the default speed range the recorder derives from the experiment; else the
    range ``[low, first impact speed]`` in m/s. ``bounces`` None: until the impact speed is
    about 0.15 m/s (at most 8).
    """

    target: float
    radius: float
    mass: float
    low: float | None = None
    integrator: str = "Euler"
    bounces: int | None = None


@dataclass(frozen=True)
class Grid:
    """What to calibrate: targets e, impact speeds (m/s), masses (kg), and the low-speed study.

    Ball-ball pairs use masses (m[i], m[-1 - i]) of the sorted masses, so the extremes give the
    largest mass ratios both ways and an odd count includes an equal-mass pair.
    """

    name: str
    targets: tuple[float, ...]
    speeds: tuple[float, ...]
    masses: tuple[float, ...]
    low_targets: tuple[float, ...]
    low_speeds: tuple[float, ...]
    design_speed: float = 1.0
    low_mass: float = 1.0
    bounce_cases: tuple[BounceCase, ...] = ()

    def with_values(
        self,
        *,
        targets: Sequence[float] | None = None,
        speeds: Sequence[float] | None = None,
        masses: Sequence[float] | None = None,
    ) -> Grid:
        """The grid with some lists replaced (the command line's --targets etc.)."""

        def given(values: Sequence[float] | None, default: tuple[float, ...]) -> tuple[float, ...]:
            return tuple(sorted(float(v) for v in values)) if values else default

        return replace(
            self,
            name=self.name + ("+custom" if targets or speeds or masses else ""),
            targets=given(targets, self.targets),
            speeds=given(speeds, self.speeds),
            masses=given(masses, self.masses),
        )

    @property
    def n_runs(self) -> int:
        """Number of runs: ball-plane, ball-ball, low-speed and multi-bounce."""
        main = len(self.targets) * len(self.speeds) * 2 * len(self.masses)
        return main + len(self.low_targets) * len(self.low_speeds) + len(self.bounce_cases)

    def mass_pairs(self) -> list[tuple[float, float]]:
        """(m1, m2) of the ball-ball runs."""
        m = sorted(self.masses)
        return [(m[i], m[-1 - i]) for i in range(len(m))]


QUICK_BOUNCES = (
    BounceCase(0.5, 0.1, 1.0),
    BounceCase(0.9, 0.05, 0.1),
    BounceCase(0.8, 0.2, 10.0, low=1.5),
)
MEDIUM_BOUNCES = (
    *QUICK_BOUNCES,
    BounceCase(0.2, 0.1, 1.0),
    BounceCase(0.35, 0.3, 7.7),
    BounceCase(0.65, 0.03, 0.13),
    BounceCase(0.95, 0.1, 1.0),
    BounceCase(0.7, 0.1, 1.0, integrator="RK4"),
    BounceCase(0.8, 0.1, 1.0, integrator="implicitfast"),
)
FULL_BOUNCES = (
    *MEDIUM_BOUNCES,
    BounceCase(0.99, 0.2, 1.0),
    BounceCase(0.25, 0.05, 0.1, low=1.0),
    BounceCase(0.5, 0.3, 10.0, integrator="RK4"),
    BounceCase(0.9, 0.03, 0.1, low=2.0, integrator="implicit"),
)

GRIDS: dict[str, Grid] = {
    "quick": Grid(
        name="quick",
        targets=(0.2, 0.5, 0.9, 0.99),
        speeds=(1.0, 10.0),
        masses=(0.1, 10.0),
        low_targets=(0.5, 0.9),
        low_speeds=(0.05, 0.1, 0.3, 1.0),
        bounce_cases=QUICK_BOUNCES,
    ),
    "medium": Grid(
        name="medium",
        targets=(0.2, 0.35, 0.5, 0.65, 0.8, 0.9, 0.95, 0.99),
        speeds=(1.0, 3.0, 10.0),
        masses=(0.1, 1.0, 10.0),
        low_targets=(0.3, 0.5, 0.8, 0.9),
        low_speeds=(0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0),
        bounce_cases=MEDIUM_BOUNCES,
    ),
    "full": Grid(
        name="full",
        targets=(0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95, 0.97, 0.99),
        speeds=(1.0, 2.0, 3.0, 5.0, 7.0, 10.0),
        masses=(0.1, 1.0, 10.0),
        low_targets=(0.2, 0.3, 0.5, 0.7, 0.8, 0.9, 0.99),
        low_speeds=(0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0),
        bounce_cases=FULL_BOUNCES,
    ),
}


@dataclass(frozen=True)
class GridPoint:
    """One run of the calibration: its spec and what it is meant to deliver.

    Attributes:
        name: experiment name (unique in the grid; letters, digits, _).
        kind: "plane", "ball", "lowspeed" or "bounces".
        target: target e.
        speed: impact (closing) speed in m/s.
        m1, m2: masses in kg (m2 None for a ball on the plane).
        design_speed: the contact's design impact speed in m/s (the top of its range).
        timestep: simulation timestep in s.
        params: the contact parameters the recorder will compute for this spec.
        toml: the spec's text.
        radius: the ball's radius in m.
    """

    name: str
    kind: str
    target: float
    speed: float
    m1: float
    m2: float | None
    design_speed: float
    timestep: float
    params: ContactParams = field(repr=False)
    toml: str = field(repr=False)
    radius: float = RADIUS_M


def _tag(x: float) -> str:
    return f"{x:g}".replace(".", "p").replace("-", "m").replace("+", "")


def pick_timestep(
    target: float, design_speed: float, *, gravity: float, max_timestep: float = 1.0
) -> tuple[float, ContactParams]:
    """The largest timestep of TIMESTEP_LADDER (at most `max_timestep`) that resolves the
    contact, and the contact's parameters for it.

    Raises:
        ContactModelError: the target cannot be reached, or no timestep of the ladder works.
    """
    last: ContactModelError | None = None
    for dt in (t for t in TIMESTEP_LADDER if t <= max_timestep):
        try:
            params = contact_params(
                target,
                radius_m=RADIUS_M,
                impact_speed_mps=design_speed,
                timestep_s=dt,
                gravity_mps2=gravity,
            )
        except ContactModelError as exc:
            if "cannot be reached" in str(exc):
                raise
            last = exc
            continue
        return dt, params
    raise ContactModelError(f"no timestep in {TIMESTEP_LADDER} works: {last}")


def plane_point(
    target: float, speed: float, mass: float, *, design_speed: float | None = None
) -> GridPoint:
    """A ball hitting the floor at `speed` (m/s) with gravity; contact designed for
    `design_speed` (default: `speed`)."""
    kind = "plane" if design_speed is None else "lowspeed"
    design = speed if design_speed is None else design_speed
    dt, params = pick_timestep(
        target,
        design,
        gravity=GRAVITY_MPS2,
        max_timestep=1.0 if design_speed is None else LOWSPEED_MAX_TIMESTEP,
    )
    gap = GAP_STEPS * speed * dt
    vz0 = -math.sqrt(speed * speed - 2.0 * GRAVITY_MPS2 * gap)
    # reach the contact, stay in it (longer at low speed, where gravity holds the ball), leave
    max_time = gap / speed + 3.0 * params.duration_s + 50.0 * dt
    name = f"cal_{kind}_e{_tag(target)}_v{_tag(speed)}_m{_tag(mass)}"
    toml = f"""name = "{name}"
description = "calibration: ball on the floor, target e = {target:g}, impact {speed:g} m/s"

[options]
timestep = {dt!r}
integrator = "Euler"
gravity = [0.0, 0.0, {-GRAVITY_MPS2!r}]

[contact]
restitution = {target!r}
speed_range = [{float(design)!r}, {float(design)!r}]

[bodies.ball]
radius = {RADIUS_M!r}
mass = {float(mass)!r}
pos = [0.0, 0.0, {RADIUS_M + gap!r}]
vel = [0.0, 0.0, {vz0!r}]

[stop]
max_time = {max_time!r}

[logging]
every = 1
"""
    return GridPoint(name, kind, target, speed, mass, None, design, dt, params, toml)


def ball_point(target: float, speed: float, m1: float, m2: float) -> GridPoint:
    """Two balls closing at `speed` (m/s) head-on along x in zero gravity."""
    dt, params = pick_timestep(target, speed, gravity=0.0)
    gap = GAP_STEPS * speed * dt
    x = RADIUS_M + gap / 2.0
    v1, v2 = BALL_SPLIT * speed, -(1.0 - BALL_SPLIT) * speed
    max_time = gap / speed + 3.0 * params.duration_s + 200.0 * dt
    separation = 20.0 * target * speed * dt  # about 20 steps after the balls part
    name = f"cal_ball_e{_tag(target)}_v{_tag(speed)}_m{_tag(m1)}_{_tag(m2)}"
    toml = f"""name = "{name}"
description = "calibration: head-on collision, target e = {target:g}, closing {speed:g} m/s"

[options]
timestep = {dt!r}
integrator = "Euler"
gravity = [0.0, 0.0, 0.0]

[contact]
restitution = {target!r}
speed_range = [{float(speed)!r}, {float(speed)!r}]

[plane]
enabled = false

[bodies.ball1]
radius = {RADIUS_M!r}
mass = {float(m1)!r}
pos = [{-x!r}, 0.0, 0.0]
vel = [{v1!r}, 0.0, 0.0]

[bodies.ball2]
radius = {RADIUS_M!r}
mass = {float(m2)!r}
pos = [{x!r}, 0.0, 0.0]
vel = [{v2!r}, 0.0, 0.0]

[stop]
max_time = {max_time!r}
separation = {separation!r}

[logging]
every = 1
"""
    return GridPoint(name, "ball", target, speed, m1, m2, speed, dt, params, toml)


def grid_points(grid: Grid, kinds: Sequence[str] = KINDS) -> list[GridPoint]:
    """The single-impact points of a grid (plane, ball, lowspeed), ordered by timestep so that
    the recorder batches them well (`bounces.all_points` adds the multi-bounce drops)."""
    points: list[GridPoint] = []
    for e in grid.targets:
        for v in grid.speeds:
            if "plane" in kinds:
                points += [plane_point(e, v, m) for m in grid.masses]
            if "ball" in kinds:
                points += [ball_point(e, v, m1, m2) for m1, m2 in grid.mass_pairs()]
    if "lowspeed" in kinds:
        for e in grid.low_targets:
            for v in grid.low_speeds:
                points.append(plane_point(e, v, grid.low_mass, design_speed=grid.design_speed))
    return sorted(points, key=lambda p: (p.timestep, KINDS.index(p.kind)))
