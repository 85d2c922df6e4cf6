"""The analysis' output tables: every run's frames concatenated, with the sweep studies."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis
from impactlab.analyze.tables.decimate import with_decimated_energy
from impactlab.analyze.tables.studies import parameters, studies
from impactlab.files import atomic_path, write_parquet
from impactlab.show import count, html_table, where

T = TypeVar("T")

TABLES = ("runs", "bounces", "collisions", "energy", "phases")
"""The output tables, each written as `<name>.parquet`."""


@dataclass
class AnalysisResult:
    """What an analysis wrote and found.

    Attributes:
        out_dir: the output folder (None: nothing was written).
        runs: the runs table (one row per analyzed run, with sweep parameters and results).
        bounces, collisions, energy, phases: the other tables (energy decimated as written,
            `tables.decimate`). Held in memory when nothing was written; read from the
            written Parquet file on each access when the analysis wrote a folder (`scan`
            gives a lazy frame instead), so a result of any size holds no table.
        studies: per swept experiment, its study table.
        failed: (path, problem) of each input that could not be analyzed.
        files: every file written.
        energy_logged: rows of the energy table at full resolution, and the most of one body
            in one run (the table keeps every k-th of them, `tables.decimate`).
        sources: each of the four tables, as a frame or the Parquet file it was written to.
    """

    out_dir: Path | None
    runs: pl.DataFrame
    studies: dict[str, pl.DataFrame]
    failed: list[tuple[str, str]] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    energy_logged: tuple[int, int] = (0, 0)
    sources: dict[str, pl.DataFrame | Path] = field(default_factory=dict, repr=False)

    @property
    def bounces(self) -> pl.DataFrame:
        """One row per bounce of a body on a surface (see `sources`)."""
        return self.table("bounces")

    @property
    def collisions(self) -> pl.DataFrame:
        """One row per body-body contact (see `sources`)."""
        return self.table("collisions")

    @property
    def energy(self) -> pl.DataFrame:
        """Energy per body and the total, decimated as written (see `sources`)."""
        return self.table("energy")

    @property
    def phases(self) -> pl.DataFrame:
        """Flight and contact phases with their energy drift and loss (see `sources`)."""
        return self.table("phases")

    def table(self, name: str) -> pl.DataFrame:
        """The table `name` as a frame (read from its file when it was written)."""
        source = self.sources.get(name)
        if isinstance(source, Path):  # one chunk, not one per part (see `_cat`)
            return pl.read_parquet(source).rechunk()
        return source if source is not None else pl.DataFrame()

    def scan(self, name: str) -> pl.LazyFrame:
        """The table `name` as a lazy frame (a scan of its file when it was written)."""
        source = self.sources.get(name)
        if isinstance(source, Path):
            return pl.scan_parquet(source)
        return (source if source is not None else pl.DataFrame()).lazy()

    @property
    def exit_code(self) -> int:
        """0 when every input was analyzed, else 1."""
        return 1 if self.failed else 0

    def __repr__(self) -> str:
        """`<Analysis 17 runs, 42 bounces, 3 collisions, results/>` (failed inputs counted;
        the counts are the runs table's: a run without bounces has a row saying why)."""

        def total(column: str) -> int:
            return int(self.runs[column].sum() or 0) if column in self.runs.columns else 0

        parts = [
            count(self.runs.height, "run"),
            count(total("n_bounces"), "bounce"),
            count(total("n_collisions"), "collision"),
        ]
        if self.failed:
            parts.append(f"{len(self.failed):,} failed")
        parts.append(where(self.out_dir) if self.out_dir is not None else "nothing written")
        return f"<Analysis {', '.join(parts)}>"

    def _repr_html_(self) -> str:
        """A notebook's table: one row per run (its bounces, e, collisions, energy lost),
        then the failed inputs."""
        columns = [c for c in NOTEBOOK_COLUMNS if c in self.runs.columns]
        rows = self.runs.head(30).select(columns).rows() if columns else []
        headers = [NOTEBOOK_COLUMNS[c] for c in columns]
        caption = repr(self).strip("<>")
        table = html_table(headers, rows, caption=caption, total=self.runs.height, unit="runs")
        if self.failed:
            failed = [[path, why] for path, why in self.failed]
            table += html_table(["failed input", "why"], failed, unit="inputs")
        return table


NOTEBOOK_COLUMNS = {  # column of the runs table: its header in a notebook's table
    "run_id": "run",
    "experiment": "experiment",
    "outcome": "outcome",
    "n_bounces": "bounces",
    "e_velocity_mean": "e (mean)",
    "n_collisions": "collisions",
    "e_collision": "e (collision)",
    "energy_loss_frac": "energy lost (fraction)",
}


REDUCE_EVERY = 64
"""Runs whose frames are gathered before they are concatenated into the tables (or written
as one part of each table's file)."""

RUNS_PIECES = 16
"""Pieces of the runs table kept before they are joined into one (docs/performance.md)."""

_TABLES = ("bounces", "collisions", "energy", "phases")


class TableReducer:
    """The output tables, folded in run by run (`take`), then finished (`result`).

    Every REDUCE_EVERY runs the frames taken are concatenated: kept in memory (the tables'
    data rather than thousands of small frames), or, with `folder`, written there as one
    Parquet part per table (`<table>/part-NNNNNN.parquet`, the runs table's rows too) and
    dropped, so that memory holds one batch of frames whatever the number of runs; `result`
    then joins each table's parts into `folder/<table>.parquet` (a streaming polars scan)
    and reads the runs table's parts back, once the others are joined. Either way the tables
    are those one concatenation of every run's frames, in order, would give.
    """

    def __init__(self, folder: Path | None = None) -> None:
        self.folder = folder
        self._pending: dict[str, list[pl.DataFrame]] = {name: [] for name in _TABLES}
        self._parts: dict[str, list[pl.DataFrame]] = {name: [] for name in _TABLES}
        self._files: dict[str, list[Path]] = {name: [] for name in TABLES}
        self._schemas: dict[str, pl.Schema] = {name: pl.Schema() for name in TABLES}
        self._summaries: list[dict[str, Any]] = []
        self._runs: list[pl.DataFrame] = []
        self._taken = self._rows = self._longest = 0

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
        self._taken += 1
        if self._taken % REDUCE_EVERY == 0:
            self._reduce()
        empty = pl.DataFrame()
        return replace(a, energy=empty, phases=empty, bounces=empty, collisions=empty)

    def _reduce(self) -> None:
        if self._summaries:
            rows = pl.DataFrame(self._summaries, infer_schema_length=None)
            self._summaries.clear()
            if self.folder is not None:
                self._write_part("runs", rows)
            else:
                self._runs.append(rows)
                if len(self._runs) >= RUNS_PIECES:
                    self._runs = [_cat(self._runs)]
        for name, frames in self._pending.items():
            if not frames:
                continue
            frame = _cat(frames)
            frames.clear()
            if self.folder is None:
                self._parts[name].append(frame)
            else:
                self._write_part(name, frame)

    def _write_part(self, name: str, frame: pl.DataFrame) -> None:
        """Write the next part of table `name` into the folder, widening its schema."""
        assert self.folder is not None
        part = self.folder / name / f"part-{len(self._files[name]):06d}.parquet"
        part.parent.mkdir(parents=True, exist_ok=True)
        self._files[name].append(write_parquet(frame, part))
        self._schemas[name] = _relaxed(self._schemas[name], frame.schema)

    def result(self, out_dir: Path | None, failed: Sequence[tuple[str, str]]) -> AnalysisResult:
        """The output tables of every run taken, with the sweep studies; with `folder`, the
        four tables are files there (`AnalysisResult.sources`), the parts removed."""
        self._reduce()
        sources: dict[str, pl.DataFrame | Path] = {}
        for name in _TABLES:
            if self.folder is None:
                sources[name] = _cat(self._parts[name])
            else:
                path = self.folder / f"{name}.parquet"
                sources[name] = _join(self._files[name], path, self._schemas[name])
                self._files[name] = []
        if self.folder is not None and self._files["runs"]:  # read back after the joins
            self._runs = [_read(self._files["runs"], self._schemas["runs"])]
            self._files["runs"] = []
        runs = _cat(self._runs)
        params, runs = parameters(runs) if runs.height else ([], runs)
        self._runs = [runs]  # not the table without its parameters too: one copy is kept
        return AnalysisResult(
            out_dir=out_dir,
            runs=runs,
            studies=studies(runs, params) if runs.height else {},
            failed=list(failed),
            energy_logged=(self._rows, self._longest),
            sources=sources,
        )


def _relaxed(a: pl.Schema, b: pl.Schema) -> pl.Schema:
    """The schema of the diagonal, relaxed concatenation of frames of schemas `a` and `b`
    (every column of either, each of the supertype of its types)."""
    empty = [pl.DataFrame(schema=s) for s in (a, b) if s]
    return pl.concat(empty, how="diagonal_relaxed").schema if empty else pl.Schema()


def _join(parts: list[Path], path: Path, schema: pl.Schema) -> Path:
    """The parts as one Parquet file at `path` (one part: renamed), in order, each read as
    `schema` (`_scan`), in one streaming scan (docs/performance.md); the parts are removed.
    No parts: an empty table, as an empty frame is written."""
    if not parts:
        return write_parquet(pl.DataFrame(), path)
    if len(parts) == 1:  # the part is the table: renamed, not written again
        os.replace(parts[0], path)
    else:

        def sink(scan: pl.LazyFrame) -> None:
            with atomic_path(path) as tmp:
                scan.sink_parquet(tmp, compression="zstd")

        _widened(parts, schema, sink)
    _remove(parts)
    return path


def _read(parts: list[Path], schema: pl.Schema) -> pl.DataFrame:
    """The parts as one frame, as `_join` would write them; the parts are removed."""
    frame = _widened(parts, schema, pl.LazyFrame.collect)
    _remove(parts)
    return frame.rechunk()


def _widened(parts: list[Path], schema: pl.Schema, use: Callable[[pl.LazyFrame], T]) -> T:
    """`use` of the parts' scan as `schema` (`_scan`); where the scan will not widen a type,
    of the concatenation of one scan per part instead."""
    try:
        return use(_scan(parts, schema))
    except pl.exceptions.SchemaError:
        return use(_scan(parts, None))


_WIDEN = pl.ScanCastOptions(
    integer_cast=["upcast", "allow-float"],
    float_cast="upcast",
    missing_struct_fields="insert",
    extra_struct_fields="ignore",
    categorical_to_string="allow",
)


def _scan(parts: list[Path], schema: pl.Schema | None) -> pl.LazyFrame:
    """The parts, in order, as their diagonal, relaxed concatenation: one scan of them all,
    each part read as `schema` (that concatenation's schema, `_relaxed`, known as they were
    written: the parts are not read twice), missing columns inserted as nulls and types
    widened; that scan stops at types it will not widen (a float column that another part
    has as text): with `schema` None, a concatenation of one scan per part instead."""
    if schema is None:
        return pl.concat([pl.scan_parquet(p) for p in parts], how="diagonal_relaxed")
    return pl.scan_parquet(parts, schema=schema, missing_columns="insert", cast_options=_WIDEN)


def _remove(parts: list[Path]) -> None:
    """Remove the parts and their folder."""
    for part in parts:
        part.unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        parts[0].parent.rmdir()


def _cat(frames: list[pl.DataFrame]) -> pl.DataFrame:
    """The frames as one, in contiguous memory (not thousands of runs' small chunks, which
    every later operation would work through one by one: docs/performance.md)."""
    frames = [f for f in frames if f.width]
    return pl.concat(frames, how="diagonal_relaxed", rechunk=True) if frames else pl.DataFrame()
