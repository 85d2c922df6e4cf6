"""The analysis' output tables: every run's frames concatenated, with the sweep studies."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis
from impactlab.analyze.tables.decimate import with_decimated_energy
from impactlab.analyze.tables.studies import studies, with_parameters


@dataclass
class AnalysisResult:
    """What an analysis wrote and found.

    Attributes:
        out_dir: the output folder (None: nothing was written).
        runs: the runs table (one row per analyzed run, with sweep parameters and results).
        bounces, collisions, energy, phases: the other tables (energy decimated as written,
            `outputs.decimate`).
        studies: per swept experiment, its study table.
        failed: (path, problem) of each input that could not be analyzed.
        files: every file written.
        energy_logged: rows of the energy table at full resolution, and the most of one body
            in one run (the table keeps every k-th of them, `outputs.decimate`).
    """

    out_dir: Path | None
    runs: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    energy: pl.DataFrame
    phases: pl.DataFrame
    studies: dict[str, pl.DataFrame]
    failed: list[tuple[str, str]] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    energy_logged: tuple[int, int] = (0, 0)

    @property
    def exit_code(self) -> int:
        """0 when every input was analyzed, else 1."""
        return 1 if self.failed else 0

    def __repr__(self) -> str:
        from impactlab.analyze.tables.view import analysis_repr

        return analysis_repr(self)

    def _repr_html_(self) -> str:
        """A small table for notebooks: one row per run (`impactlab.analyze.tables.view`)."""
        from impactlab.analyze.tables.view import analysis_html

        return analysis_html(self)


REDUCE_EVERY = 64
"""Runs whose frames are gathered before they are concatenated into the tables."""

_TABLES = ("bounces", "collisions", "energy", "phases")


class TableReducer:
    """The output tables, folded in run by run (`take`), then finished (`result`).

    Every REDUCE_EVERY runs the frames taken are concatenated, so memory holds about the
    tables' data rather than thousands of small frames: flat in the number of runs. The
    tables are those one concatenation of every run's frames, in order, would give.
    """

    def __init__(self) -> None:
        self._pending: dict[str, list[pl.DataFrame]] = {name: [] for name in _TABLES}
        self._parts: dict[str, list[pl.DataFrame]] = {name: [] for name in _TABLES}
        self._summaries: list[dict] = []
        self._rows = self._longest = 0

    def take(self, a: RunAnalysis) -> RunAnalysis:
        """Take a run's tables; the analysis without them (its metadata stays)."""
        a = with_decimated_energy(a)
        for name in _TABLES:
            frame = getattr(a, name)
            if frame.width:
                self._pending[name].append(frame)
        self._summaries.append(a.summary)
        rows, longest = a.energy_logged
        self._rows += rows
        self._longest = max(self._longest, longest)
        if len(self._summaries) % REDUCE_EVERY == 0:
            self._reduce()
        empty = pl.DataFrame()
        return replace(a, energy=empty, phases=empty, bounces=empty, collisions=empty)

    def _reduce(self) -> None:
        for name, frames in self._pending.items():
            if frames:
                self._parts[name].append(_cat(frames))
                frames.clear()

    def result(self, out_dir: Path | None, failed: Sequence[tuple[str, str]]) -> AnalysisResult:
        """The output tables of every run taken, with the sweep studies."""
        self._reduce()
        runs = pl.DataFrame(self._summaries, infer_schema_length=None)
        runs = with_parameters(runs) if runs.height else runs
        return AnalysisResult(
            out_dir=out_dir,
            runs=runs,
            bounces=_cat(self._parts["bounces"]),
            collisions=_cat(self._parts["collisions"]),
            energy=_cat(self._parts["energy"]),
            phases=_cat(self._parts["phases"]),
            studies=studies(runs) if runs.height else {},
            failed=list(failed),
            energy_logged=(self._rows, self._longest),
        )


def _cat(frames: list[pl.DataFrame]) -> pl.DataFrame:
    """The frames as one, in contiguous memory: a table of thousands of runs' small chunks
    would make every later operation work chunk by chunk (a mapping of run labels, for one,
    was built again per chunk: 265 MB for the bounces of 2,000 runs)."""
    frames = [f for f in frames if f.width]
    return pl.concat(frames, how="diagonal_relaxed", rechunk=True) if frames else pl.DataFrame()
