"""What recording gives back: one `RecordedRun` per planned run, reused ones included."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from impactlab.show import count, html_table, where


@dataclass(frozen=True, slots=True)
class RecordedRun:
    """One run of a record job (metadata-sized; the log stays on disk).

    Attributes:
        run_id, path: the run and its log.
        status: "recorded", "reused" (its complete log was there already) or "failed" (no
            log; `reason` says why).
        outcome, reason: how the run ended ("completed" or "unstable", and why).
        warnings: the run's warnings.
        t_end_s, steps, logged: simulated time (s), simulated steps and logged rows.
        wall_s: wall time spent on the run here (0 for a reused run).
    """

    run_id: str
    path: Path
    status: str
    outcome: str = ""
    reason: str = ""
    warnings: tuple[str, ...] = ()
    t_end_s: float = 0.0
    steps: int = 0
    logged: int = 0
    wall_s: float = 0.0

    @property
    def failed(self) -> bool:
        return self.status == "failed"

    @property
    def unstable(self) -> bool:
        """Recorded or reused, and not completed."""
        return not self.failed and self.outcome != "completed"

    def lines(self) -> list[str]:
        """The run's console lines: its result, then one per warning."""
        if self.failed:
            return [f"{self.path.name}: failed: {self.reason}"]
        line = (
            f"{self.path.name}: {self.outcome} ({self.reason}), t = {self.t_end_s:.4g} s, "
            f"{self.steps} steps, {self.logged} logged, {self.wall_s:.2f} s"
        )
        return [line] + [f"warning: {self.path.stem}: {w}" for w in self.warnings]

    @classmethod
    def reused(cls, run_id: str, path: Path, outcome: Mapping[str, str]) -> RecordedRun:
        """A run whose complete log exists, from the log's outcome record."""
        try:
            warnings = json.loads(outcome.get("warnings", "[]"))
        except ValueError:
            warnings = []
        if not isinstance(warnings, list):  # a damaged log's: a number, a text, an object
            warnings = []
        steps = outcome.get("steps", "0")
        return cls(
            run_id,
            path,
            "reused",
            outcome.get("outcome", ""),
            outcome.get("reason", ""),
            tuple(str(w) for w in warnings),
            steps=int(steps) if steps.isdigit() else 0,
        )


class RecordResult(list[RecordedRun]):
    """Every run of a record job, in plan order: a list of `RecordedRun`."""

    @property
    def paths(self) -> list[Path]:
        """The log of every run that has one (recorded or reused), in plan order."""
        return [r.path for r in self if not r.failed]

    @property
    def recorded(self) -> list[RecordedRun]:
        return [r for r in self if r.status == "recorded"]

    @property
    def reused(self) -> list[RecordedRun]:
        return [r for r in self if r.status == "reused"]

    @property
    def failed(self) -> list[RecordedRun]:
        return [r for r in self if r.failed]

    @property
    def unstable(self) -> list[RecordedRun]:
        return [r for r in self if r.unstable]

    @property
    def exit_code(self) -> int:
        """0 when every run completed (recorded or reused), else 1."""
        return 1 if self.failed or self.unstable else 0

    def __repr__(self) -> str:
        """`<RecordResult 3 runs: 2 recorded, 1 reused, logs/>` (unstable and failed counted)."""
        kinds = ("recorded", "reused", "unstable", "failed")
        parts = [f"{len(getattr(self, k)):,} {k}" for k in kinds if getattr(self, k)]
        folders = {r.path.parent for r in self}
        head = count(len(self), "run") + (f": {', '.join(parts)}" if parts else "")
        folder = f", {where(next(iter(folders))) if len(folders) == 1 else 'several folders'}"
        return f"<RecordResult {head}{folder if folders else ''}>"

    def _repr_html_(self) -> str:
        """A small table for notebooks, one row per run: its status, outcome and why,
        simulated time, steps, log file."""
        rows = [
            [
                r.run_id,
                r.status,
                r.outcome,
                r.reason,
                r.t_end_s or None,
                r.steps or None,
                r.path.name,
            ]
            for r in self[:30]
        ]
        headers = ["run", "status", "outcome", "why", "t end (s)", "steps", "log"]
        caption = repr(self).strip("<>")
        return html_table(headers, rows, caption=caption, total=len(self), unit="runs")

    def summary(self, out_dir: Path) -> str:
        """One line for people: how many runs were written, unstable, failed."""
        parts = [f"{len(self.recorded)} run(s) written to {out_dir}/"]
        if self.unstable:
            parts.append(f"{len(self.unstable)} unstable")
        if self.failed:
            parts.append(f"{len(self.failed)} failed")
        return ", ".join(parts)
