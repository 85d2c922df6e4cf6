"""pytest plugin: golden tests of a spec's or model's physics (docs/golden-tests.md)."""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from impactlab.testing.golden_physics import PhysicsComparison, PhysicsTolerance

UPDATE_FLAG = "--impactlab-update-golden"
_WRITTEN = pytest.StashKey[list[str]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("impactlab", "impactlab golden logs")
    group.addoption(
        UPDATE_FLAG,
        action="store_true",
        default=False,
        help="record the golden logs of impactlab_golden checks anew (and pass) instead of "
        "comparing against them",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.stash[_WRITTEN] = []


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    written = config.stash.get(_WRITTEN, [])
    if written:
        terminalreporter.section("impactlab golden logs written")
        for line in written:
            terminalreporter.line(line)


@dataclass(kw_only=True)
class GoldenCheck:
    """What the `impactlab_golden` fixture gives a test (see `check`)."""

    root: Path
    work: Path
    update: bool
    written: list[str]

    def check(
        self,
        spec: str | Path | Mapping[str, Any],
        golden: str | Path,
        *,
        overrides: Sequence[str] = (),
        duration: float | None = None,
        tolerance: PhysicsTolerance | None = None,
        **tolerances: float,
    ) -> PhysicsComparison:
        """Record `spec` (a .toml, an MJCF model with `duration` in s, or a spec document;
        paths relative to pytest's rootdir; one run: `overrides` as `impactlab record --set`)
        and compare its physics with the golden log `golden` (.mcap) within `tolerance` or
        some of its fields by name (`e=0.01`). Fails the test when the physics differs, the
        golden log is missing, the spec gives several runs or cannot be recorded; with
        `--impactlab-update-golden`, writes the golden log instead. The comparison."""
        from dataclasses import replace

        from impactlab.errors import ImpactlabError
        from impactlab.testing.golden_physics import PhysicsComparison, PhysicsTolerance

        tol = replace(tolerance or PhysicsTolerance(), **tolerances)
        target = self._path(golden)
        if target.suffix != ".mcap":
            raise ValueError(f"{golden}: a golden log is an .mcap file")
        try:
            new = self._record(spec, overrides, duration)
        except ImpactlabError as exc:
            pytest.fail(f"impactlab golden: {exc}", pytrace=False)
        if self.update:
            self._write(new, target)
            return PhysicsComparison()
        if not target.is_file():
            pytest.fail(
                f"impactlab golden: {self._shown(target)} does not exist; record it with "
                f"`pytest {UPDATE_FLAG}` and commit it",
                pytrace=False,
            )
        comparison = self._compare(target, new, tol)
        if not comparison.equal:
            pytest.fail(self._explain(spec, target, new, comparison), pytrace=False)
        return comparison

    def _path(self, path: str | Path) -> Path:
        p = Path(path)
        return p if p.is_absolute() else self.root / p

    def _shown(self, path: Path) -> str:
        """A path as messages name it: relative to the rootdir when inside it."""
        from impactlab.show import plain

        return plain(path.relative_to(self.root) if path.is_relative_to(self.root) else path)

    def _record(
        self, spec: str | Path | Mapping[str, Any], overrides: Sequence[str], duration: float | None
    ) -> Path:
        from impactlab.record import plan, record

        source = spec if isinstance(spec, Mapping) else self._path(spec)
        runs = plan(source, overrides=overrides, duration=duration)
        if len(runs) != 1:
            pytest.fail(
                f"impactlab golden: {spec} gives {len(runs)} runs; a golden log holds one: "
                "set each swept field to one value with overrides",
                pytrace=False,
            )
        (run,) = record(runs, out=self.work / "impactlab-golden", overwrite=True)
        if run.failed:
            pytest.fail(f"impactlab golden: {spec}: not recorded: {run.reason}", pytrace=False)
        return run.path

    def _compare(self, golden: Path, new: Path, tol: PhysicsTolerance) -> PhysicsComparison:
        from impactlab.analyze import analyze
        from impactlab.testing.golden_physics import compare_physics

        return compare_physics(analyze(golden), analyze(new), tol)

    def _write(self, new: Path, target: Path) -> None:
        from impactlab.files import atomic_path
        from impactlab.testing.golden_physics import PhysicsTolerance

        before = "new"
        if target.is_file():
            changes = self._compare(target, new, PhysicsTolerance()).differences
            before = f"{len(changes)} physical difference(s) from the previous one"
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(target) as tmp:
            shutil.copyfile(new, tmp)
        self.written.append(f"{self._shown(target)}: {before}")

    def _explain(self, spec: Any, golden: Path, new: Path, comparison: PhysicsComparison) -> str:
        from impactlab.logs.load import load_log
        from impactlab.show import plain
        from impactlab.testing.golden_physics import spec_changes

        what = "a spec document" if isinstance(spec, Mapping) else plain(spec)
        lines = [
            f"impactlab golden: the physics of {what} differs from {self._shown(golden)} "
            f"({len(comparison.differences)} of {comparison.compared} compared):"
        ]
        lines += [f"  {d}" for d in comparison.differences[:40]]
        if len(comparison.differences) > 40:
            lines.append(f"  ... and {len(comparison.differences) - 40} more")
        changed = spec_changes(load_log(golden).spec, load_log(new).spec)
        if changed:
            lines.append("the spec differs from the golden log's (golden -> new):")
            lines += [f"  {c}" for c in changed[:20]]
        lines.append(f"if the change is intended, regenerate: pytest {UPDATE_FLAG}")
        return "\n".join(lines)


@pytest.fixture
def impactlab_golden(request: pytest.FixtureRequest, tmp_path: Path) -> GoldenCheck:
    """Record a spec or model and compare its physics with a golden log (`GoldenCheck.check`);
    `pytest --impactlab-update-golden` writes the golden logs instead."""
    config = request.config
    return GoldenCheck(
        root=config.rootpath,
        work=tmp_path,
        update=bool(config.getoption(UPDATE_FLAG)),
        written=config.stash.get(_WRITTEN, []),
    )
