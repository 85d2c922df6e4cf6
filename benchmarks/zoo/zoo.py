"""The model zoo of issue 35: every MJCF model the pinned packages ship, against plain MuJoCo.

Usage: python benchmarks/zoo/zoo.py [--only TEXT] [--duration S] [--out FILE]
  (install the models first: pip install -e ".[zoo]"; see benchmarks/zoo/README.md)
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import importlib.metadata
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import oracle

HERE = Path(__file__).resolve().parent
OWN_MODELS = HERE / "models"
# Distributions whose wheels ship MJCF files (pinned in pyproject's `zoo` extra), and the
# name the table gives them. MuJoCo's own test models ship in its mujoco-core wheel.
PACKAGES = {
    "mujoco-core": "mujoco",
    "dm-control": "dm-control",
    "gymnasium": "gymnasium",
    "gymnasium-robotics": "gymnasium-robotics",
    "myo-sim": "myo-sim",
    "mujoco-warp": "mujoco-warp",
    "mujoco-mjx": "mujoco-mjx",
    "brax": "brax",
    "robosuite-models": "robosuite-models",
}
OWN = "zoo"  # the table's package name for benchmarks/zoo/models
STRIDES = (1, 10)
BIG_MESH_FACES = 50_000  # a mesh with at least this many faces is a big mesh
MANY_FREE_BODIES = 50
FIGURE_BODIES = 10  # a free-floating tree of at least this many bodies counts as a figure
LARGE = frozenset({"many_free_bodies", "several_humanoids"})  # issue 35's 2x record goal
MAX_RECORD_RATIO = 2.0
RESULT = "ZOO-RESULT "  # prefix of the one line a child process answers with


@dataclasses.dataclass(frozen=True)
class ZooModel:
    """One model file: its path, the package that ships it and its name there."""

    path: Path
    package: str
    name: str
    nested_include: bool  # an included file includes a file beside itself


# ---- the adapter: the lead implements this against the new log format ---------------------


@dataclasses.dataclass(frozen=True)
class ImpactlabSide:
    """What impactlab measured for one model, in the oracle's terms.

    run: an oracle.Run built from impactlab's log and analysis alone (the same logged steps,
    energies, cumulative works per kind, residual and episodes, parties named as
    oracle.party_names names them). record_seconds: the CPU time of recording its steps,
    against a bare loop of the same steps: `impactlab.record.record_runs` of the planned run
    in this process (its writer thread included) less `fixed_seconds`, the recording's fixed
    cost (a one-step recording's: the log's set-up and summary); plan_seconds: planning it
    (compiling, instrumenting, the attachments). The benchmark's definition (bench.py), for
    runs of hundreds of steps, whose fixed costs would otherwise dominate; CPU time, as
    several models run side by side on a shared machine.
    explanations: for an episode whose e is outside [0, 1], keyed by episode_key (the two
    party names in sorted order, the onset step), the sentence impactlab gives for it.
    """

    run: oracle.Run
    record_seconds: float
    explanations: Mapping[tuple[str, str, int], str] = dataclasses.field(default_factory=dict)
    plan_seconds: float = 0.0
    fixed_seconds: float = 0.0


# The adapter's convention (for the lead): True if impactlab's budget books every spring as a
# work and only gravity as potential energy (the oracle's run is then compared after
# oracle.springs_booked_as_work); False if its potential is MuJoCo's, springs included.
SPRINGS_BOOKED_AS_WORK = True


def impactlab_side(
    model_path: Path, duration: float, every: int, out_dir: Path, *, publish: bool = True
) -> ImpactlabSide:
    """Record `model_path` for `duration` s logging every `every`-th step with impactlab,
    analyze the log (the tables, and with `publish` the figures and report) and replay it
    (with `publish`), and read the oracle's quantities back from the log and the analysis
    alone (never from MuJoCo directly). Files go to `out_dir`/every<every>.

    The conventions mapped: impactlab books every spring's work as a work and gravity alone
    as potential energy (SPRINGS_BOOKED_AS_WORK); its "solver" work (the force an unconverged
    constraint solver leaves) is the oracle's residual; its surfaces are parties of their own,
    named by the geom; a flex party is "flex <name>". Rows off the logging grid (the run's
    last step, always logged) are left out.
    """
    import impactlab
    from impactlab.analyze.measure.analysis import analyze_run
    from impactlab.logs.load import load_log
    from impactlab.record import plan, record_runs

    out = out_dir / f"every{every}"
    started = time.process_time()
    runs = plan([model_path], duration=duration, overrides=[f"logging.every={every}"])
    plan_seconds = time.process_time() - started
    # the recording's fixed cost (the log's set-up and summary): a one-step recording's,
    # after a warm-up recording (the process's first learns the log's layouts)
    (planned,) = runs
    dt = float(planned.build().model.opt.timestep)
    stop = planned.stop.model_copy(update={"max_time": dt})
    one_step = [dataclasses.replace(planned, stop=stop)]
    record_runs(runs, out / "warm-up", threads=1)
    started = time.process_time()
    record_runs(one_step, out / "one-step", threads=1)
    fixed_seconds = time.process_time() - started
    started = time.process_time()
    (recorded,) = record_runs(runs, out, threads=1)
    seconds = time.process_time() - started - fixed_seconds
    if recorded.failed:
        raise RuntimeError(f"impactlab record: {recorded.reason}")
    log = load_log(recorded.path)
    analysis = analyze_run(log)
    impactlab.analyze([recorded.path], out=out / "results", figures=publish, report=publish)
    if publish:
        impactlab.replay([recorded.path], out=out / "replay.rrd")
    dt_ns = round(log.timestep_s * 1e9)
    step = log.energy["t_ns"].to_numpy() // dt_ns
    grid = step % every == 0
    kinetic = log.energy["kinetic"].to_numpy()[grid]
    g = log.gravity
    potential = np.full(step.size, log.static_potential_J)
    for name, info in log.body_info.items():
        frame = log.bodies[name]
        xyz = frame.select("x", "y", "z").to_numpy()
        potential = potential - info.mass * (xyz @ g)
    potential = potential[grid]
    names = {  # impactlab's work kinds -> the oracle's
        "contact_normal": "contact_normal",
        "contact_friction": "contact_friction",
        "limit": "limits",
        "equality": "equality",
        "friction_loss": "friction_loss",
        "damper": "damping",
        "spring": "springs",
        "gravcomp": "gravity_compensation",
        "fluid": "fluid",
        "actuator": "actuators",
    }
    work = {kind: np.zeros(kinetic.size) for kind in oracle.WORK_KINDS}
    for kind, ours in names.items():
        work[kind] = log.work[ours].to_numpy()[grid]
    energy = kinetic + potential
    total = np.sum([work[k] for k in oracle.WORK_KINDS], axis=0)
    start = energy[:1]  # none when the run stopped before its first row
    residual = (energy - start) - total  # the solver's work stays in it, as the oracle's
    nbody = len(log.body_info)
    oracle_name = _oracle_names(model_path)

    def party(name: str, kind: str) -> str:
        return f"flex {name}" if kind == "flex" else oracle_name.get(name, name)

    episodes = []
    explanations: dict[tuple[str, str, int], str] = {}
    notes = _notes(analysis)
    for ep in log.impacts.iter_rows(named=True):
        onset = ep["onset_ns"] // dt_ns
        release = None if ep["open"] else ep["release_ns"] // dt_ns
        p1, p2 = party(ep["side1"], ep["kind1"]), party(ep["side2"], ep["kind2"])
        episodes.append(
            oracle.Episode(
                party1=p1,
                party2=p2,
                onset_step=int(onset),
                onset_time=onset * log.timestep_s,
                release_step=None if release is None else int(release),
                release_time=None if release is None else release * log.timestep_s,
                onset_vn=None if onset == 0 else (ep["v_in_mps"],),
                release_vn=None if release is None else (ep["v_out_mps"],),
                max_penetration=ep["max_penetration_m"],
                work_normal=ep["work_compression_J"] + ep["work_restitution_J"],
                work_friction=ep["work_friction_J"],
            )
        )
        key = (*sorted((p1, p2)), int(onset))
        note = notes.get((ep["side1"], ep["side2"], round(ep["onset_ns"] / 1e9, 9)))
        if note:
            explanations[key] = note  # type: ignore[index]
    del nbody
    run = oracle.Run(
        model=str(model_path),
        keyframe=None,
        timestep=log.timestep_s,
        integrator=log.integrator,
        cone="",
        nsteps=int(step.max(initial=0)),
        every=every,
        step=step[grid],
        time=step[grid] * log.timestep_s,
        kinetic=kinetic,
        potential=potential,
        work=work,
        residual=residual,
        episodes=tuple(episodes),
        stopped=None if log.outcome == "completed" else log.meta.get("reason"),
        warnings={},
        seconds=seconds,
    )
    return ImpactlabSide(run, seconds, explanations, plan_seconds, fixed_seconds)


def _oracle_names(model_path: Path) -> dict[str, str]:
    """impactlab's names of the model's unnamed bodies and geoms (`body<i>`, `geom<i>`, given
    by the recorder) -> the oracle's (`body i`, `geom i`, oracle.party_names)."""
    from impactlab.record.model_names import name_unnamed

    spec = mujoco.MjSpec.from_file(str(model_path))
    if all(b.name for b in spec.bodies[1:]) and all(g.name for g in spec.geoms):
        return {}  # every name is the model's own (compiling a large model takes seconds)
    theirs = oracle.party_names(spec.compile())
    name_unnamed(spec)
    ours = spec.compile()
    out = {ours.body(b).name: theirs[b] for b in range(1, ours.nbody)}
    first_geom = ours.nbody + ours.nflex
    out |= {ours.geom(g).name: theirs[first_geom + g] for g in range(ours.ngeom)}
    return {a: b for a, b in out.items() if a != b}


def _notes(analysis: Any) -> dict[tuple[str, str, float], str]:
    """The analysis' note on each contact episode's e outside [0, 1] (every episode, a bounce
    or a collision or neither: slower than an impact), by its sides and onset (s)."""
    return {
        (row["body"], row["other"], round(row["impact_t_s"], 9)): row["e_note"]
        for row in analysis.intervals.iter_rows(named=True)
        if row["e_note"]
    }


# ---- the comparison ----------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Check:
    """One comparison: its name, whether it held (None: measured, no goal) and the figures."""

    name: str
    passed: bool | None
    detail: str


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """Tolerances of compare(): energy terms relative to the run's energy scale."""

    energy_rtol: float = 1e-9  # of Run.energy_scale, for energies, works and residual
    speed_atol: float = 1e-6  # m/s, for normal velocities at onset and release
    speed_rtol: float = 1e-6
    e_atol: float = 1e-4  # for the restitution of an episode


def compare(
    truth: oracle.Run,
    side: ImpactlabSide,
    bare_seconds: float,
    *,
    tolerances: Tolerances = Tolerances(),
    max_ratio: float | None = None,
) -> list[Check]:
    """Check impactlab's quantities against the oracle's for one model at one stride.

    Energies, every work kind and the residual at every logged step; the episodes (party
    pair, onset and release step, the fastest normal approach at onset and separation at
    release, Episode.approach_speed and separation_speed); every e within
    [0, 1] or explained; e against the oracle's; record time over the bare loop's (a goal
    only with max_ratio).
    """
    run = side.run
    checks = [_check_steps(truth, run)]
    if checks[0].passed:
        tol = tolerances.energy_rtol * truth.energy_scale + 1e-12
        checks.append(_check_series("kinetic energy", truth.kinetic, run.kinetic, truth, tol))
        checks.append(_check_series("potential energy", truth.potential, run.potential, truth, tol))
        for kind in oracle.WORK_KINDS:
            if kind not in run.work:
                checks.append(Check(f"work {kind}", False, "missing"))
                continue
            checks.append(
                _check_series(f"work {kind}", truth.work[kind], run.work[kind], truth, tol)
            )
        checks.append(_check_series("residual", truth.residual, run.residual, truth, tol))
    checks += _check_episodes(truth, run, tolerances)
    checks.append(_check_e_bounded(run, side.explanations))
    ratio = side.record_seconds / bare_seconds if bare_seconds > 0 else math.inf
    detail = (
        f"{side.record_seconds:.3g} s / {bare_seconds:.3g} s = {ratio:.3g}x "
        f"(apart: the recording's fixed cost {side.fixed_seconds:.3g} s, planning "
        f"{side.plan_seconds:.3g} s)"
    )
    if max_ratio is None:
        checks.append(Check("record time / bare loop", None, detail))
    else:
        checks.append(
            Check("record time / bare loop", ratio <= max_ratio, f"{detail} (goal <= {max_ratio}x)")
        )
    return checks


def _check_steps(truth: oracle.Run, run: oracle.Run) -> Check:
    if run.step.shape != truth.step.shape or not np.array_equal(run.step, truth.step):
        return Check(
            "logged steps", False, f"{run.step.size} logged steps, the oracle {truth.step.size}"
        )
    worst = float(np.max(np.abs(run.time - truth.time), initial=0.0))
    ok = worst <= truth.timestep / 2
    return Check("logged steps", ok, f"{truth.step.size} steps, worst time offset {worst:.3g} s")


def _check_series(
    name: str, want: np.ndarray, got: np.ndarray, truth: oracle.Run, tol: float
) -> Check:
    if got.shape != want.shape:
        return Check(name, False, f"{got.size} values, the oracle {want.size}")
    error = np.abs(got - want)
    error = np.where(np.isfinite(error), error, np.inf)
    worst = int(np.argmax(error)) if error.size else 0
    worst_error = float(error[worst]) if error.size else 0.0
    detail = f"worst {worst_error:.3g} J (tolerance {tol:.3g} J)"
    if error.size:
        detail += f" at t = {truth.time[worst]:.6g} s"
    return Check(name, worst_error <= tol, detail)


def episode_key(episode: oracle.Episode) -> tuple[str, str, int]:
    """An episode's identity: its parties' names in sorted order and its onset step."""
    low, high = sorted((episode.party1, episode.party2))
    return (low, high, episode.onset_step)


def _close(a: float | None, b: float | None, tol: Tolerances) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= tol.speed_atol + tol.speed_rtol * abs(a)


def _check_episodes(truth: oracle.Run, run: oracle.Run, tol: Tolerances) -> list[Check]:
    want = {episode_key(e): e for e in truth.episodes}
    got = {episode_key(e): e for e in run.episodes}
    missing = sorted(set(want) - set(got))
    extra = sorted(set(got) - set(want))
    onset = Check(
        "contact onsets",
        not missing and not extra,
        f"{len(want)} episodes; missing {_few(missing)}; extra {_few(extra)}",
    )
    both = sorted(set(want) & set(got))
    releases = [k for k in both if want[k].release_step != got[k].release_step]
    onset_speeds = [
        k for k in both if not _close(want[k].approach_speed, got[k].approach_speed, tol)
    ]
    release_speeds = [
        k for k in both if not _close(want[k].separation_speed, got[k].separation_speed, tol)
    ]
    e_off = []
    for k in both:
        e_want, e_got = want[k].restitution, got[k].restitution
        if (e_want is None) != (e_got is None) or (
            e_want is not None and e_got is not None and abs(e_want - e_got) > tol.e_atol
        ):
            e_off.append(k)
    return [
        onset,
        Check("contact releases", not releases, f"{len(both)} matched; differ: {_few(releases)}"),
        Check("normal speeds at onset", not onset_speeds, f"differ: {_few(onset_speeds)}"),
        Check("normal speeds at release", not release_speeds, f"differ: {_few(release_speeds)}"),
        Check("e against the oracle", not e_off, f"differ by > {tol.e_atol}: {_few(e_off)}"),
    ]


def _check_e_bounded(run: oracle.Run, explanations: Mapping[tuple[str, str, int], str]) -> Check:
    out = [
        (episode_key(e), e.restitution)
        for e in run.episodes
        if e.restitution is not None and not 0 <= e.restitution <= 1
    ]
    unexplained = [(k, e) for k, e in out if not explanations.get(k, "").strip()]
    detail = f"{len(out)} outside [0, 1], {len(unexplained)} unexplained: {_few(unexplained)}"
    return Check("e bounded or explained", not unexplained, detail)


def _few(items: Sequence[Any], n: int = 3) -> str:
    if not items:
        return "none"
    shown = ", ".join(str(i) for i in items[:n])
    return shown + (f" and {len(items) - n} more" if len(items) > n else "")


# ---- finding the models --------------------------------------------------------------------


_COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
_TAG = re.compile(r"<\s*([A-Za-z_][\w.-]*)")
_INCLUDE = re.compile(r"<\s*include\b[^>]*?\bfile\s*=\s*(?:\"([^\"]*)\"|'([^']*)')", re.DOTALL)


def _xml_text(path: Path) -> str | None:
    """A file's text without comments (MuJoCo's parser is more lenient than ElementTree's)."""
    try:
        return _COMMENT.sub("", path.read_text(encoding="utf-8", errors="replace"))
    except OSError:
        return None


def _root_tag(path: Path) -> str | None:
    text = _xml_text(path)
    match = _TAG.search(text.split("?>", 1)[-1]) if text is not None else None
    return match.group(1) if match else None


def include_tree(path: Path) -> list[tuple[Path, int, bool]]:
    """The files a model includes, as MuJoCo resolves them: (file, depth, beside).

    MuJoCo tries an include's file against the top model's folder first, then against the
    including file's folder; beside is True where only the second found it.
    """
    top = path.parent
    found: list[tuple[Path, int, bool]] = []
    seen = {path.resolve()}

    def walk(file: Path, depth: int) -> None:
        text = _xml_text(file)
        for match in _INCLUDE.finditer(text or ""):
            name = match.group(1) or match.group(2)
            first, second = top / name, file.parent / name
            target, beside = (first, False) if first.is_file() else (second, second.is_file())
            if not target.is_file() or target.resolve() in seen:
                continue
            seen.add(target.resolve())
            found.append((target, depth + 1, beside and depth >= 1))
            walk(target, depth + 1)

    walk(path, 0)
    return found


def _models_in(files: list[Path], package: str, base: Path) -> list[ZooModel]:
    """The files whose root is <mujoco> and that no other file of the list includes."""
    candidates = [f for f in sorted(files) if _root_tag(f) == "mujoco"]
    trees = {f: include_tree(f) for f in candidates}
    included = {i.resolve() for tree in trees.values() for i, _, _ in tree}
    return [
        ZooModel(f, package, f.relative_to(base).as_posix(), any(b for _, _, b in trees[f]))
        for f in candidates
        if f.resolve() not in included
    ]


def find_models() -> tuple[list[ZooModel], list[str]]:
    """Every model of the installed packages and of benchmarks/zoo/models, and what is missing."""
    models: list[ZooModel] = []
    missing: list[str] = []
    for dist_name, label in PACKAGES.items():
        try:
            dist = importlib.metadata.distribution(dist_name)
        except importlib.metadata.PackageNotFoundError:
            missing.append(f"{dist_name} is not installed (pip install -e '.[zoo]')")
            continue
        base = Path(str(dist.locate_file(""))).resolve()
        files = [
            Path(str(dist.locate_file(f))).resolve()
            for f in dist.files or []
            if str(f).endswith(".xml")
        ]
        models += _models_in(files, f"{label} {dist.version}", base)
    models += _models_in(sorted(OWN_MODELS.rglob("*.xml")), OWN, HERE)
    return models, missing


def model_classes(model: ZooModel, m: mujoco.MjModel, d: mujoco.MjData) -> list[str]:
    """The classes of issue 35 a compiled model belongs to (d: after mj_forward at its start)."""
    classes = []
    moving = np.asarray(m.body_weldid) != 0
    collides = (np.asarray(m.geom_contype) | np.asarray(m.geom_conaffinity)) != 0
    geom_body = np.asarray(m.geom_bodyid)
    massless = [
        b
        for b in range(1, m.nbody)
        if m.body_mass[b] == 0 and moving[b] and np.any(collides[geom_body == b])
    ]
    if massless:
        classes.append("massless_child")
    if m.nflex:
        classes.append("flex")
    geom_type = np.asarray(m.geom_type)
    if np.any(geom_type == int(mujoco.mjtGeom.mjGEOM_SDF)):
        classes.append("sdf")
    if np.any(geom_type == int(mujoco.mjtGeom.mjGEOM_HFIELD)):
        classes.append("hfield")
    free = np.asarray(m.jnt_type) == int(mujoco.mjtJoint.mjJNT_FREE)
    if free.sum() >= MANY_FREE_BODIES:
        classes.append("many_free_bodies")
    root = np.asarray(m.body_rootid)
    figures = [
        r
        for r in np.unique(root[1:])
        if np.sum(root == r) >= FIGURE_BODIES and np.any(free & (np.asarray(m.jnt_bodyid) == r))
    ]
    if len(figures) >= 2:
        classes.append("several_humanoids")
    muscle = int(mujoco.mjtGain.mjGAIN_MUSCLE)
    if m.nu and np.any(np.asarray(m.actuator_gaintype) == muscle):
        classes.append("muscles")
    if m.ntendon:
        classes.append("tendons")
    if m.neq:
        classes.append("equality")
    if model.nested_include:
        classes.append("nested_include")
    if m.nmesh and int(np.max(m.mesh_facenum)) >= BIG_MESH_FACES:
        classes.append("big_mesh")
    if m.nmocap:
        classes.append("mocap")
    if _outside_limits(m, d):
        classes.append("qpos0_outside_limits")
    if np.any(np.asarray(m.dof_damping) > 0):
        classes.append("joint_damping")
    if m.nu:
        classes.append("actuators")
    if m.opt.density > 0 or m.opt.viscosity > 0:
        classes.append("fluid")
    if np.any(np.asarray(m.body_gravcomp) > 0):
        classes.append("gravcomp")
    if d.ncon and np.any(np.asarray(d.contact.exclude) == 0):
        classes.append("touching_t0")
    return classes


def _outside_limits(m: mujoco.MjModel, d: mujoco.MjData) -> bool:
    hinge_or_slide = np.isin(
        m.jnt_type, [int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)]
    )
    limited = np.asarray(m.jnt_limited, bool) & hinge_or_slide
    if not limited.any():
        return False
    q = np.asarray(d.qpos)[np.asarray(m.jnt_qposadr)[limited]]
    low, high = np.asarray(m.jnt_range)[limited].T
    return bool(np.any((q < low - 1e-9) | (q > high + 1e-9)))


# ---- one model ------------------------------------------------------------------------------


def bare_loop_seconds(path: Path, nsteps: int, budget: float = 10.0) -> float:
    """The best CPU time of a plain mj_step loop of nsteps (up to 3 tries within budget s)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    best = math.inf
    spent = 0.0
    for _ in range(3):
        d = mujoco.MjData(m)
        started = time.process_time()
        for _ in range(nsteps):
            mujoco.mj_step(m, d)
        elapsed = time.process_time() - started
        best, spent = min(best, elapsed), spent + elapsed
        if spent > budget:
            break
    return best


def strides_agree(fine: oracle.Run, coarse: oracle.Run) -> bool:
    """Whether a stride-n run holds the stride-1 run's values at its logged steps."""
    index = np.searchsorted(fine.step, coarse.step)
    if np.any(index >= fine.step.size) or not np.array_equal(fine.step[index], coarse.step):
        return False
    tol = 1e-9 * max(fine.energy_scale, 1e-300)
    series = [(fine.kinetic, coarse.kinetic), (fine.potential, coarse.potential)]
    series += [(fine.residual, coarse.residual)]
    if fine.acceleration_gap is not None and coarse.acceleration_gap is not None:
        series.append((fine.acceleration_gap, coarse.acceleration_gap))
    series += [(fine.work[k], coarse.work[k]) for k in oracle.WORK_KINDS]
    close = all(np.all(np.abs(a[index] - b) <= tol) for a, b in series)
    return close and fine.episodes == coarse.episodes


def run_model(model: ZooModel, duration: float, max_steps: int) -> dict[str, Any]:
    """Compile one model, classify it, run the oracle at both strides and the bare loop."""
    row: dict[str, Any] = {"model": model.name, "package": model.package}
    try:
        m, d = oracle.load(model.path)
    except ValueError as error:
        message = str(error).strip().splitlines()[0] if str(error).strip() else "error"
        row["refused"] = message.replace(str(model.path.parent) + "/", "")
        return row
    mujoco.mj_forward(m, d)
    h = float(m.opt.timestep)
    nsteps = max(1, min(round(duration / h), max_steps))
    row.update(
        classes=model_classes(model, m, d),
        nbody=int(m.nbody),
        ngeom=int(m.ngeom),
        nflex=int(m.nflex),
        nu=int(m.nu),
        timestep=h,
        integrator=mujoco.mjtIntegrator(m.opt.integrator).name.removeprefix("mjINT_"),
        steps=nsteps,
        duration=nsteps * h,
    )
    runs = {every: oracle.run(model.path, nsteps * h, every) for every in STRIDES}
    fine = runs[1]
    row["bare_seconds"] = bare_loop_seconds(model.path, nsteps)
    row["oracle_seconds"] = fine.seconds
    row["episodes"] = len(fine.episodes)
    row["touching_t0_episodes"] = sum(e.onset_vn is None for e in fine.episodes)
    restitutions = [e.restitution for e in fine.episodes if e.restitution is not None]
    row["e_max"] = max(restitutions) if restitutions else None
    row["e_over_1"] = sum(e > 1 for e in restitutions)
    scale = fine.energy_scale
    worst = float(np.max(np.abs(fine.residual), initial=0.0))
    row["residual_relative"] = worst / scale if scale > 0 else None
    assert fine.acceleration_gap is not None
    rest = float(np.max(np.abs(fine.residual - fine.acceleration_gap), initial=0.0))
    row["residual_without_gap_relative"] = rest / scale if scale > 0 else None
    row["energy_scale"] = scale
    row["strides_agree"] = strides_agree(fine, runs[10])
    row["stopped"] = fine.stopped
    row["checks"] = _adapter_checks(model, row, runs)
    return row


def _adapter_checks(model: ZooModel, row: dict[str, Any], runs: Mapping[int, oracle.Run]) -> Any:
    large = bool(LARGE & set(row["classes"]))
    results: dict[str, list[list[Any]]] = {}
    with tempfile.TemporaryDirectory(prefix="zoo-") as tmp:
        for every, run in runs.items():
            truth = oracle.springs_booked_as_work(run) if SPRINGS_BOOKED_AS_WORK else run
            try:
                side = impactlab_side(model.path, truth.nsteps * truth.timestep, every, Path(tmp))
            except NotImplementedError:
                return "adapter not written"
            warned = re.search(r"\bmjWARN_\w+", side.run.stopped or "")
            if warned and truth.stopped is None and truth.warnings.get(warned.group(0)):
                # MuJoCo warns and runs on (the oracle); impactlab stops there, as it says
                row["refused"] = f"impactlab stops where MuJoCo warns: {side.run.stopped}"
                return None
            checks = compare(
                truth, side, row["bare_seconds"], max_ratio=MAX_RECORD_RATIO if large else None
            )
            results[str(every)] = [[c.name, c.passed, c.detail] for c in checks]
    return results


# ---- the table -------------------------------------------------------------------------------


def _fmt(value: Any, spec: str = ".3g") -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, float):
        return format(value, spec)
    return str(value)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _checks_cell(checks: Any) -> str:
    if not isinstance(checks, dict):
        return str(checks or "")
    failed = sorted({name for rows in checks.values() for name, ok, _ in rows if ok is False})
    return "all hold" if not failed else "fail: " + ", ".join(failed)


def table(rows: list[dict[str, Any]], missing: list[str], header: str) -> str:
    """The zoo as Markdown: the models, then counts per package and class, refusals, slowest."""
    out = [header, ""]
    out += [f"- {line}" for line in missing]
    columns = [
        "model", "package", "classes", "nbody", "ngeom", "nflex", "integrator", "steps",
        "bare loop CPU s", "oracle s", "episodes", "e > 1", "e max", "worst residual / scale",
        "without the gap", "strides 1, 10 agree", "stopped", "impactlab checks",
    ]  # fmt: skip
    out += ["", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    ran = [r for r in rows if "refused" not in r and "failed" not in r]
    for r in ran:
        cells = [
            r["model"], r["package"], " ".join(r["classes"]), r["nbody"], r["ngeom"], r["nflex"],
            r["integrator"], r["steps"], _fmt(r["bare_seconds"]), _fmt(r["oracle_seconds"]),
            r["episodes"], r["e_over_1"], _fmt(r["e_max"]), _fmt(r["residual_relative"], ".2e"),
            _fmt(r["residual_without_gap_relative"], ".2e"), _fmt(r["strides_agree"]), r["stopped"] or "", _checks_cell(r.get("checks")),
        ]  # fmt: skip
        out.append("| " + " | ".join(_cell(_fmt(c)) for c in cells) + " |")
    out += [
        "",
        "## Counts per package",
        "",
        "| package | models | run | refused by MuJoCo | failed |",
    ]
    out.append("|---|---|---|---|---|")
    for package in sorted({r["package"] for r in rows}):
        mine = [r for r in rows if r["package"] == package]
        refused = sum("refused" in r for r in mine)
        failed = sum("failed" in r for r in mine)
        out.append(
            f"| {package} | {len(mine)} | {len(mine) - refused - failed} | {refused} | {failed} |"
        )
    out.append(f"| all | {len(rows)} | {len(ran)} | {sum('refused' in r for r in rows)} | "
               f"{sum('failed' in r for r in rows)} |")  # fmt: skip
    per_class = Counter(c for r in ran for c in r["classes"])
    packages_per_class = {
        c: len({r["package"].split()[0] for r in ran if c in r["classes"]}) for c in per_class
    }
    out += ["", "## Counts per class", "", "| class | models | packages |", "|---|---|---|"]
    out += [f"| {c} | {n} | {packages_per_class[c]} |" for c, n in sorted(per_class.items())]
    refused_rows = [r for r in rows if "refused" in r]
    out += [
        "",
        "## Refused by MuJoCo",
        "",
        "| model | package | MuJoCo's message |",
        "|---|---|---|",
    ]
    out += [f"| {r['model']} | {r['package']} | {_cell(r['refused'])} |" for r in refused_rows]
    failed_rows = [r for r in rows if "failed" in r]
    if failed_rows:
        out += [
            "",
            "## Failed in the zoo itself",
            "",
            "| model | package | what |",
            "|---|---|---|",
        ]
        out += [f"| {r['model']} | {r['package']} | {_cell(r['failed'])} |" for r in failed_rows]
    slow = sorted(ran, key=lambda r: -r["bare_seconds"])[:10]
    out += [
        "",
        "## Slowest (bare loop)",
        "",
        "| model | package | steps | bare loop CPU s | oracle s |",
    ]
    out.append("|---|---|---|---|---|")
    out += [
        f"| {r['model']} | {r['package']} | {r['steps']} | {_fmt(r['bare_seconds'])} | "
        f"{_fmt(r['oracle_seconds'])} |"
        for r in slow
    ]
    return "\n".join(out) + "\n"


# ---- the command ---------------------------------------------------------------------------


def _run_child(model: ZooModel, args: argparse.Namespace) -> dict[str, Any]:
    command = [
        sys.executable, str(Path(__file__).resolve()), "--one", str(model.path),
        "--package", model.package, "--name", model.name, "--duration", str(args.duration),
        "--max-steps", str(args.max_steps),
    ]  # fmt: skip
    if model.nested_include:
        command.append("--nested-include")
    try:
        with tempfile.TemporaryDirectory(prefix="zoo-cwd-") as cwd:  # MuJoCo writes MUJOCO_LOG.TXT
            done = subprocess.run(
                command, capture_output=True, text=True, timeout=args.timeout, cwd=cwd
            )
    except subprocess.TimeoutExpired:
        return {"model": model.name, "package": model.package, "failed": f"over {args.timeout} s"}
    for line in reversed(done.stdout.splitlines()):
        if line.startswith(RESULT):
            result: dict[str, Any] = json.loads(line.removeprefix(RESULT))
            return result
    tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
    return {
        "model": model.name,
        "package": model.package,
        "failed": f"exit {done.returncode}: {tail}",
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--only", default="", help="run the models whose package/name contains this"
    )
    parser.add_argument(
        "--duration", type=float, default=1.0, help="simulated s per model (0.5 to 2)"
    )
    parser.add_argument("--max-steps", type=int, default=5000, help="cap on the steps of one model")
    parser.add_argument("--timeout", type=float, default=900.0, help="s for one model")
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    parser.add_argument("--list", action="store_true", help="list the models and stop")
    parser.add_argument("--one", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--package", help=argparse.SUPPRESS)
    parser.add_argument("--name", help=argparse.SUPPRESS)
    parser.add_argument("--nested-include", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        model = ZooModel(args.one, args.package, args.name, args.nested_include)
        print(RESULT + json.dumps(run_model(model, args.duration, args.max_steps)), flush=True)
        return 0
    models, missing = find_models()
    models = [m for m in models if args.only in f"{m.package}/{m.name}"]
    if args.list:
        for m in models:
            print(f"{m.package:28} {m.name}")
        print(f"{len(models)} models")
        return 0
    started = time.perf_counter()
    rows = []
    for i, model in enumerate(models, 1):
        row = _run_child(model, args)
        rows.append(row)
        status = (
            row.get("refused")
            or row.get("failed")
            or f"{row['steps']} steps, {row['episodes']} episodes"
        )
        print(
            f"[{i}/{len(models)}] {model.package} {model.name}: {status}",
            file=sys.stderr,
            flush=True,
        )
    header = (
        f"# Model zoo (issue 35): {len(rows)} models, {args.duration} s each (at most "
        f"{args.max_steps} steps)\n\n{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, MuJoCo {mujoco.__version__}, numpy {np.__version__}; "
        f"{datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}, load average "
        f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}, "
        f"{time.perf_counter() - started:.0f} s in all.\n\n"
        "Residual: (E - E0) minus the non-conservative works (oracle.run's docstring), its "
        "largest magnitude over the run over the run's energy scale; without the gap: the "
        "same for the residual less the acceleration gap (the velocity update beyond M^-1 f: "
        "solver imbalance, implicit damping, RK4 stages), i.e. the integrator's "
        "discretization of gravity and of the changing mass matrix. e > 1, e max: the "
        "episodes with an approach and a release whose e exceeds 1, and the largest e. impactlab checks: compare() of the "
        "adapter's results at strides 1 and 10."
    )
    text = table(rows, missing, header)
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
