"""Progress: tqdm's bar on a terminal (items done, rate, time left), nothing but the lines
when stderr is a pipe or a file."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import struct
import subprocess
import sys
import termios

import pytest
from specs import drop, toml

from impactlab.progress import ConsoleProgress, ProgressEvent

SWEEP = toml(drop("bar", max_time=0.2, sweep={"ball.mass": [1.0, 2.0, 3.0]}))


def test_without_a_terminal_only_the_lines_are_printed(capsys):
    lines: list[str] = []
    console = ConsoleProgress(echo=lines.append)  # capsys: stderr is no terminal
    console(ProgressEvent("record", 0, 3))
    for done in (1, 2, 3):
        line = f"run {done}: completed" if done != 2 else None
        console(ProgressEvent("record", done, 3, {"finished": done}, line=line))
    console(ProgressEvent("record", 3, 3, {"failed": 1}, line="run 4: failed", level="error"))
    console.close()
    assert lines == ["run 1: completed", "run 3: completed"]
    assert capsys.readouterr() == ("", "run 4: failed\n")


def _run_on_a_terminal(argv: list[str], cwd) -> tuple[str, str, int]:
    """Run `python -m impactlab ARGV` with stderr on a pseudo-terminal of 100 columns and
    stdout a pipe; returns (what the terminal showed, stdout, exit code)."""
    main_fd, term_fd = pty.openpty()
    fcntl.ioctl(term_fd, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    proc = subprocess.Popen(
        [sys.executable, "-m", "impactlab", *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=term_fd
    )
    os.close(term_fd)
    shown = b""
    while True:
        try:
            chunk = os.read(main_fd, 65536)
        except OSError:  # EIO: the program closed the terminal's last end
            break
        if not chunk:
            break
        shown += chunk
    os.close(main_fd)
    out, _ = proc.communicate(timeout=300)
    return shown.decode(errors="replace"), out.decode(), proc.returncode


@pytest.mark.slow  # two whole programs that simulate and analyze
def test_a_terminal_shows_a_bar_per_stage_with_rate_and_time_left(tmp_path):
    (tmp_path / "bar.toml").write_text(SWEEP)
    shown, out, code = _run_on_a_terminal(["record", "bar.toml", "-o", "logs"], tmp_path)
    assert code == 0, shown
    assert "record: 100%" in shown and "3/3 [" in shown  # tqdm: desc, count, [elapsed<left
    assert "run/s" in shown and "<00:00" in shown
    assert "Traceback" not in shown
    assert out.count(".mcap: completed") == 3 and "3 run(s) written" in out  # stdout: lines
    assert "\r" not in out and "%" not in out

    shown, out, code = _run_on_a_terminal(["analyze", "logs", "-o", "results"], tmp_path)
    assert code == 0, shown
    assert "analyze:" in shown and "3/3 [" in shown and "log/s" in shown
    assert "report: results/report.md" in out and "\r" not in out


@pytest.mark.slow
def test_piped_stderr_gets_no_bar(tmp_path):
    (tmp_path / "bar.toml").write_text(SWEEP)
    done = subprocess.run(
        [sys.executable, "-m", "impactlab", "record", "bar.toml", "-o", "logs"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0
    assert done.stderr == ""
    assert done.stdout.count(".mcap: completed") == 3


class Terminal(io.StringIO):
    """A stderr that says it is a terminal: tqdm draws its bar into it."""

    def isatty(self) -> bool:
        return True


def test_a_finished_job_closes_its_bar_and_the_next_job_opens_one(monkeypatch):
    screen = Terminal()
    monkeypatch.setattr(sys, "stderr", screen)
    lines: list[str] = []
    console = ConsoleProgress(echo=lines.append)
    for job in range(2):  # the same stage twice: the count starts again
        for done in range(4):
            console(ProgressEvent("record", done, 3, {"finished": done}))
        console(ProgressEvent("record", 3, 3, {"finished": 3}, line=f"job {job} done"))
    console.close()
    shown = screen.getvalue()
    assert shown.count("record:   0%") == 2 and shown.count("3/3 [") >= 2
    assert lines == ["job 0 done", "job 1 done"]  # after each bar closed: plain lines
