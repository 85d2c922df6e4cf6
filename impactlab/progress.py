"""Progress of long jobs (`ProgressEvent`s to a callable), shown only when asked."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from impactlab.text import one_line

COUNT_KEYS = ("finished", "unstable", "failed", "reused")


@dataclass(frozen=True)
class ProgressEvent:
    """Where a job stands.

    Attributes:
        stage: "record", "analyze", "replay" or "calibrate".
        done: items done so far (reused items not counted), of `total`.
        total: items to do.
        counts: items done so far by kind (finished, unstable, failed, reused).
        line: a sentence for people (a run's result, a warning), or None.
        level: the line's kind: "info", "warning" or "error" (an item failed).
    """

    stage: str
    done: int
    total: int
    counts: Mapping[str, int] = field(default_factory=dict)
    line: str | None = None
    level: str = "info"


# every stage that works through items takes one: called after each item and for each line
# of news; None reports nothing; `ConsoleProgress()` is the command line's and verbose=True's
Progress = Callable[[ProgressEvent], None]


class Tracker:
    """Counts a job's items and sends each change to `progress` (None: silent)."""

    def __init__(self, stage: str, total: int, progress: Progress | None, *, reused: int = 0):
        self.stage = stage
        self.total = total
        self.progress = progress
        self.done = 0
        self.counts = dict.fromkeys(COUNT_KEYS, 0) | {"reused": reused}
        self._send(None)

    def _send(self, line: str | None, level: str = "info") -> None:
        if self.progress is not None:
            counts = dict(self.counts)
            self.progress(ProgressEvent(self.stage, self.done, self.total, counts, line, level))

    def add(self, key: str, n: int = 1) -> None:
        """Count `n` items done as `key` (one of COUNT_KEYS)."""
        self.counts[key] += n
        self.done += n
        self._send(None)

    def say(self, line: str, level: str = "info") -> None:
        """Pass a line of news on ("info", "warning" or "error")."""
        self._send(line, level)


def say(progress: Progress | None, stage: str, line: str, level: str = "info") -> None:
    """Pass one line of news on, outside any count (an event with total 0)."""
    if progress is not None:
        progress(ProgressEvent(stage, 0, 0, {}, line, level))


class ConsoleProgress:
    """tqdm's bar per stage on stderr (on a terminal; a widget in a notebook), with the items
    done, the rate and the time left; the lines on stdout, warnings and errors on stderr.
    Where stderr is no terminal (a pipe, a log file, CI) there is no bar: only the lines.

    With `notebook`, the bar is `tqdm.auto`'s (a widget in a Jupyter notebook), always shown
    and left in the cell when the job is over.

    Call `close()` when the job is over (the bar is removed from the terminal), or use it
    as a context manager.
    """

    def __init__(self, *, echo: Callable[[str], None] = print, notebook: bool = False) -> None:
        self.echo = echo
        self.notebook = notebook
        self._bar: Any = None
        self._stage: str | None = None
        self._done = 0

    def __call__(self, event: ProgressEvent) -> None:
        if event.total == 0:  # a line outside any count
            self._print(event)
            return
        if event.stage != self._stage or event.done < self._done:  # a new job
            self.close()
            self._stage = event.stage
            if event.total >= 2 or (self.notebook and event.total >= 1):
                self._bar = self._new_bar(event)
        self._done = event.done
        bar = self._bar
        if bar is not None:
            if event.done != bar.n:
                bar.update(event.done - bar.n)
            shown = {k: v for k, v in event.counts.items() if v}
            bar.set_postfix(shown, refresh=False)
        self._print(event)
        if bar is not None and event.done >= event.total and not self.notebook:
            bar.refresh()  # its last state, drawn whatever tqdm's rate limit
            bar.close()  # the job's work is done: its clock stops (the lines go on)
            self._bar = None

    def _new_bar(self, event: ProgressEvent) -> Any:
        """A tqdm bar for the stage (None when stderr is no terminal, outside notebooks)."""
        unit = "log" if event.stage in ("analyze", "replay") else "run"
        if self.notebook:
            from tqdm.auto import tqdm as auto_tqdm

            auto_tqdm.monitor_interval = 0
            return auto_tqdm(total=event.total, unit=unit, desc=event.stage, leave=True)
        isatty = getattr(sys.stderr, "isatty", None)
        if isatty is None or not isatty():  # tqdm's own test (disable=None), before its import
            return None
        from tqdm import tqdm

        # no monitor thread: a process with another thread cannot fork record workers
        tqdm.monitor_interval = 0
        return tqdm(total=event.total, unit=unit, desc=event.stage, leave=False, file=sys.stderr)

    def _print(self, event: ProgressEvent) -> None:
        if event.line is None:
            return
        line = one_line(event.line)  # one line, whatever names of logs or models it quotes
        if event.level in ("error", "warning"):
            print(line, file=sys.stderr)
        elif self._bar is not None:
            self._bar.write(line)
        else:
            self.echo(line)

    def __enter__(self) -> ConsoleProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Remove the bar."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        self._stage = None
        self._done = 0


def in_notebook() -> bool:
    """Whether this process is a Jupyter kernel (IPython running in an `IPKernelApp`)."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:  # an IPython without a shell, or a broken one: not a notebook
        return False
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


@contextlib.contextmanager
def reporter(progress: Progress | None, verbose: bool) -> Iterator[Progress | None]:
    """`progress` itself, or with `verbose` (and no `progress`) the console's, closed after:
    in a notebook, a `tqdm.auto` bar (a widget) that stays in the cell."""
    if progress is not None or not verbose:
        yield progress
        return
    with ConsoleProgress(notebook=in_notebook()) as console:
        yield console
