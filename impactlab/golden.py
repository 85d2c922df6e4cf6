"""Regenerate the golden logs of the tests: `python -m impactlab.golden` (docs/log-format.md)."""

from __future__ import annotations

import argparse
import functools
import shutil
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from impactlab.logs.format import WORK_TOPIC
from impactlab.logs.load import RunLog, load_log
from impactlab.record import plan, record_runs
from impactlab.tools.diff import LogDiff, Tolerance, channel_tables, diff_logs

GOLDEN_DIR = Path(__file__).resolve().parents[1] / "tests" / "golden"
SPECS_DIR = GOLDEN_DIR / "specs"
LOGS_DIR = GOLDEN_DIR / "logs"
RESULTS_DIR = GOLDEN_DIR / "results"
# metadata that differs between two recordings of the same run on different checkouts
GOLDEN_IGNORED_META = ("impactlab_version", "source")
RESULT_TABLES = ("runs", "bounces", "collisions")
GOLDEN_RTOL = 1e-12
"""Relative agreement a new recording needs with its golden log (values, metadata, model)."""
TABLE_RTOL, TABLE_ATOL = 1e-9, 1e-12
"""Agreement of the analysis tables (polars may also change its summation order)."""
# the unit of each logged field: a field's tolerance scales with the largest value of its unit
# in its channel, so a field that is zero in the golden log (vy of a vertical drop) is held to
# the scale of its siblings
FIELD_UNITS = {
    **dict.fromkeys(("x", "y", "z", "penetration"), "m"),
    **dict.fromkeys(("qw", "qx", "qy", "qz", "nx", "ny", "nz"), "1"),
    **dict.fromkeys(("vx", "vy", "vz"), "m/s"),
    **dict.fromkeys(("wx", "wy", "wz"), "rad/s"),
    **dict.fromkeys(("normal_force", "friction_force_t1", "friction_force_t2"), "N"),
    **dict.fromkeys(("fx", "fy", "fz"), "N"),
    **dict.fromkeys(("kinetic", "potential", "total"), "J"),
    **dict.fromkeys(("work_compression_J", "work_restitution_J"), "J"),
    **dict.fromkeys(("v_in_mps", "v_out_mps"), "m/s"),
}
SUMMED_RTOL = 1e-9
"""Looser agreement for sums over every step (a contact's work, every field of WORK_TOPIC): a
last-bit difference of each step adds up; a physical change still moves them by about 1e-3."""
# columns of the analysis tables that name where the files were, not what they hold
RESULT_MACHINE_COLUMNS = ("file",)


@dataclass(frozen=True)
class Golden:
    """One golden log: its name (file stem), its spec or MJCF model (in specs/) and
    overrides (`--set`; for a model, its run options)."""

    name: str
    spec: str
    overrides: tuple[str, ...] = ()

    @property
    def spec_path(self) -> Path:
        """The spec file."""
        return SPECS_DIR / self.spec

    @property
    def log_path(self) -> Path:
        """The committed golden log."""
        return LOGS_DIR / f"{self.name}.mcap"


GOLDENS = (
    Golden("drop_bounces", "drop_bounces.toml"),
    Golden("collision", "collision.toml"),
    Golden("drop_restitution", "drop_restitution.toml"),
    Golden("collision_sweep_point", "collision_sweep.toml", ("ball2.mass=2.0",)),
    Golden(
        "box_edge",
        "box_edge.xml",
        ("stop.bounces=3", "stop.max_time=1", "logging.every=20"),
    ),
)


def record_golden(golden: Golden, out_dir: Path, *, overrides: Sequence[str] = ()) -> Path:
    """Record one golden spec (plus extra overrides) to `out_dir/<its name>.mcap`, its path;
    SpecError when the spec or an override is wrong, or it gives more than one run."""
    from impactlab.errors import SpecError

    runs = plan([golden.spec_path], overrides=[*golden.overrides, *overrides])
    if len(runs) != 1:
        raise SpecError(str(golden.spec_path), "sweep", f"gives {len(runs)} runs, need one")
    work = Path(tempfile.mkdtemp(prefix=f".{golden.name}-", dir=out_dir))
    try:
        (result,) = record_runs(runs, work)
        target = out_dir / f"{golden.name}.mcap"
        result.path.replace(target)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return target


def golden_tolerance(golden: RunLog) -> Tolerance:
    """Agreement to `GOLDEN_RTOL` of each value, or of its channel's scale in the golden log.

    Two values a, b of field f in channel c are equal when |a - b| <= GOLDEN_RTOL * (max(|a|,
    |b|) + S), S the largest magnitude of any field of f's unit in c (`FIELD_UNITS`), or of
    any field of c when those are all zero. Numbers in the metadata and the model agree to
    GOLDEN_RTOL relative.
    """
    fields: dict[str, float] = {}
    for topic, (frame, _, names) in channel_tables(golden).items():
        units = {n: unit_of(n, topic) for n in names if unit_of(n, topic)}
        largest = {n: float(frame.select(pl.col(n).abs().max()).item() or 0.0) for n in units}
        channel_scale = max(largest.values(), default=0.0)
        for unit in set(units.values()):
            same = [n for n in units if units[n] == unit]
            scale = max(largest[n] for n in same) or channel_scale  # all zero: the channel's
            fields |= {f"{topic}:{n}": _rtol(topic, n) * scale for n in same}
    return Tolerance(atol=0.0, rtol=GOLDEN_RTOL, fields=fields)


def unit_of(field: str, topic: str = "") -> str:
    """The unit of a logged field ("" for text); a clearance's `distance[<surface>]` is m, every
    field of WORK_TOPIC (the work of a kind of force so far) J."""
    if topic == WORK_TOPIC:
        return "J"
    return FIELD_UNITS.get(field, "m" if field.startswith("distance[") else "")


def _rtol(topic: str, field: str) -> float:
    summed = topic == WORK_TOPIC or field in ("work_compression_J", "work_restitution_J")
    return SUMMED_RTOL if summed else GOLDEN_RTOL


def compare_golden(golden_log: Path, new_log: Path) -> LogDiff:
    """A new recording against its golden log, within `golden_tolerance` of the golden log
    (metadata but `GOLDEN_IGNORED_META`)."""
    golden = load_log(golden_log)
    return diff_logs(
        golden,
        load_log(new_log),
        tolerance=golden_tolerance(golden),
        ignore_meta=GOLDEN_IGNORED_META,
    )


def table_change(new: pl.DataFrame, golden: pl.DataFrame) -> str | None:
    """How a new analysis table differs from the golden one (polars' first difference), or
    None: same columns and rows, numbers within TABLE_RTOL / TABLE_ATOL (any CPU)."""
    from polars.testing import assert_frame_equal

    try:
        assert_frame_equal(new, golden, check_exact=False, rel_tol=TABLE_RTOL, abs_tol=TABLE_ATOL)
    except AssertionError as exc:
        return " ".join(str(exc).split())
    return None


def analysis_tables(logs_dir: Path, work_dir: Path) -> dict[str, pl.DataFrame]:
    """Analyze every log of a folder (`impactlab analyze`); the RESULT_TABLES, sorted, without
    the columns that name files (the tables do not depend on the checkout)."""
    from impactlab.analyze.job import run_analysis

    result = run_analysis([logs_dir], work_dir)
    if result.failed:
        raise RuntimeError(f"analysis failed: {result.failed}")
    out = {}
    for name in RESULT_TABLES:
        frame = pl.read_parquet(work_dir / f"{name}.parquet")
        frame = frame.drop([c for c in RESULT_MACHINE_COLUMNS if c in frame.columns])
        out[name] = frame.sort(
            [c for c in ("run_id", "body", "bounce", "collision") if c in frame.columns]
        )
    return out


def main(argv: Sequence[str] | None = None, *, echo: Callable[[str], None] = print) -> int:
    """Regenerate (or with --check, verify) the golden logs and analysis tables."""
    parser = argparse.ArgumentParser(
        prog="python -m impactlab.golden",
        description="Re-record the golden specs of tests/golden/, report what changed against "
        "the committed logs and replace them (only report with --check).",
    )
    parser.add_argument(
        "--check", action="store_true", help="only compare; exit 1 when anything changed"
    )
    args = parser.parse_args(argv)
    if not SPECS_DIR.is_dir():  # an installed impactlab: the golden data is in the repository
        print(
            f"impactlab.golden: error: {SPECS_DIR}: no such folder: this regenerates the golden "
            "data of a checkout of impactlab (tests/golden/); run it there",
            file=sys.stderr,
        )
        return 2
    LOGS_DIR.mkdir(parents=True, exist_ok=True)
    writes: dict[str, Callable[[], object]] = {}  # what changed, and how to write it
    with tempfile.TemporaryDirectory(prefix="impactlab-golden-") as tmp:
        new_dir = Path(tmp) / "logs"
        new_dir.mkdir()
        for golden in GOLDENS:
            new = record_golden(golden, new_dir)
            if not golden.log_path.exists():
                echo(f"{golden.name}: new golden log ({new.stat().st_size} bytes)")
            elif (diff := compare_golden(golden.log_path, new)).equal:
                echo(f"{golden.name}: unchanged")
                shutil.copyfile(golden.log_path, new)  # keep the committed bytes
                continue
            else:
                echo(f"{golden.name}: changed")
                echo(diff.report())
            writes[golden.name] = functools.partial(shutil.copyfile, new, golden.log_path)
        names = {f"{g.name}.mcap" for g in GOLDENS}
        stale = sorted(p for p in LOGS_DIR.glob("*.mcap") if p.name not in names)
        for path in stale:
            echo(
                f"{path.stem}: no golden spec any more: {'would be ' if args.check else ''}removed"
            )
        for name, frame in analysis_tables(new_dir, Path(tmp) / "results").items():
            old = RESULTS_DIR / f"{name}.parquet"
            change = table_change(frame, pl.read_parquet(old)) if old.exists() else "new"
            if change is not None:
                echo(f"results/{name}.parquet: {change}")
                writes[f"results/{name}"] = functools.partial(frame.write_parquet, old)
        if args.check:
            out = [*writes, *(p.stem for p in stale)]
            echo(f"golden data out of date: {', '.join(out)}" if out else "golden data up to date")
            return 1 if out else 0
        RESULTS_DIR.mkdir(parents=True, exist_ok=True)
        for write in [*writes.values(), *(p.unlink for p in stale)]:
            write()
    total = sum(p.stat().st_size for p in GOLDEN_DIR.rglob("*") if p.is_file())
    echo(
        f"{len(writes)} golden file(s) written; tests/golden holds {total / 1e6:.2f} MB"
        if writes
        else "nothing changed"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
