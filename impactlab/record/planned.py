"""A job's planned runs as a sequence built on demand: a sweep is kept as its grid, not its runs.

A 100,000-point sweep planned as a list holds 100,000 resolved specs (about 7 KB each) in
the process that records them, and in every worker forked from it. `PlannedRuns` keeps
each input as planned (a `SpecSweep`, or an MJCF model's one `PlannedRun`) and builds a
sweep's run when it is asked for (about 0.1 ms: the spec validated again), so recording
holds only the runs in flight. `Subset` is a view of some of its runs, by index.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Iterator, Sequence
from typing import TypeVar, overload

from impactlab.record.spec import RunSpec
from impactlab.record.sweep import SpecSweep

T = TypeVar("T")  # a planned run (`impactlab.record.job.PlannedRun`)


class PlannedRuns(Sequence[T]):
    """The runs of a job's inputs, in plan order, each built when it is read.

    Args:
        parts: per input, its sweep (checked already) or its one planned run.
        build: a sweep's run -> its planned run (names it, estimates its work).
    """

    def __init__(self, parts: Sequence[SpecSweep | T], build: Callable[[RunSpec], T]) -> None:
        self._parts = list(parts)
        self._build = build
        self._starts: list[int] = []
        total = 0
        for part in self._parts:
            self._starts.append(total)
            total += len(part) if isinstance(part, SpecSweep) else 1
        self._len = total

    def __len__(self) -> int:
        return self._len

    @overload
    def __getitem__(self, index: int) -> T: ...
    @overload
    def __getitem__(self, index: slice) -> list[T]: ...
    def __getitem__(self, index: int | slice) -> T | list[T]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._len))]
        if index < 0:
            index += self._len
        if not 0 <= index < self._len:
            raise IndexError(f"run {index} of {self._len}")
        at = bisect.bisect_right(self._starts, index) - 1
        part = self._parts[at]
        if isinstance(part, SpecSweep):
            return self._build(part.run(index - self._starts[at]))
        return part

    def __iter__(self) -> Iterator[T]:
        for part in self._parts:
            if isinstance(part, SpecSweep):
                yield from map(self._build, part.iter_runs())
            else:
                yield part

    def __repr__(self) -> str:
        return f"PlannedRuns({self._len} runs)"


class Subset(Sequence[T]):
    """Some runs of a sequence, by index, read from it when asked for."""

    def __init__(self, runs: Sequence[T], indices: Sequence[int]) -> None:
        self._runs, self._indices = runs, indices

    def __len__(self) -> int:
        return len(self._indices)

    @overload
    def __getitem__(self, index: int) -> T: ...
    @overload
    def __getitem__(self, index: slice) -> Subset[T]: ...
    def __getitem__(self, index: int | slice) -> T | Subset[T]:
        if isinstance(index, slice):
            return Subset(self._runs, self._indices[index])
        return self._runs[self._indices[index]]

    def __iter__(self) -> Iterator[T]:
        for i in self._indices:
            yield self._runs[i]
