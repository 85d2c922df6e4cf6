"""The console's progress where there is no terminal for a bar: count lines when quiet."""

from __future__ import annotations

from impactlab.progress import ConsoleProgress, ProgressEvent


class Clock:
    """A clock the test moves."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_a_quiet_job_prints_where_it_stands_every_few_seconds(capsys):
    clock = Clock()
    console = ConsoleProgress(quiet_s=5.0, clock=clock)  # capsys: stderr is no terminal
    console(ProgressEvent("analyze", 0, 4))
    for done, step in [(1, 2.0), (2, 4.0), (3, 1.0)]:  # 2 s, 6 s, 7 s after the start
        clock.now += step
        console(ProgressEvent("analyze", done, 4, {"finished": done}))
    clock.now += 10.0
    console(ProgressEvent("analyze", 4, 4, {"finished": 4}))  # the end: the summary says it
    console.close()
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == ["analyze: 2 of 4 logs done (50 %), 6.0 s"]


def test_lines_of_news_count_as_output(capsys):
    clock = Clock()
    lines: list[str] = []
    console = ConsoleProgress(quiet_s=5.0, clock=clock, echo=lines.append)
    console(ProgressEvent("record", 0, 3))
    clock.now += 6.0
    console(ProgressEvent("record", 1, 3, {"finished": 1}, line="a.mcap: completed"))
    clock.now += 3.0
    console(ProgressEvent("record", 2, 3, {"finished": 2}))  # 3 s after the last line
    clock.now += 6.0
    console(ProgressEvent("record", 3, 3, {"finished": 3}))
    console.close()
    assert lines == ["a.mcap: completed"]
    assert capsys.readouterr().err == ""
