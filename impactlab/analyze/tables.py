"""The analysis' output tables: every run's frames concatenated, with the sweep studies."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import polars as pl

from impactlab.analyze.analysis import RunAnalysis
from impactlab.analyze.studies import studies, with_parameters


@dataclass
class AnalysisResult:
    """What an analysis wrote and found.

    Attributes:
        out_dir: the output folder (None: nothing was written).
        runs: the runs table (one row per analyzed run, with sweep parameters and results).
        bounces, collisions, energy, phases: the other tables (energy decimated).
        studies: per swept experiment, its study table.
        failed: (path, problem) of each input that could not be analyzed.
        files: every file written.
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

    @property
    def exit_code(self) -> int:
        """0 when every input was analyzed, else 1."""
        return 1 if self.failed else 0


def tables(
    analyses: Sequence[RunAnalysis], out_dir: Path | None, failed: Sequence[tuple[str, str]]
) -> AnalysisResult:
    """Concatenate the per-run frames into the output tables."""

    def cat(frames: list[pl.DataFrame]) -> pl.DataFrame:
        frames = [f for f in frames if f.width]
        return pl.concat(frames, how="diagonal_relaxed") if frames else pl.DataFrame()

    runs = pl.DataFrame([a.summary for a in analyses], infer_schema_length=None)
    runs = with_parameters(runs) if runs.height else runs
    return AnalysisResult(
        out_dir=out_dir,
        runs=runs,
        bounces=cat([a.bounces for a in analyses]),
        collisions=cat([a.collisions for a in analyses]),
        energy=cat([a.energy for a in analyses]),
        phases=cat([a.phases for a in analyses]),
        studies=studies(runs) if runs.height else {},
        failed=list(failed),
    )
