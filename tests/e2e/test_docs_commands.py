"""Every code block of README.md and docs/*.md runs as written, or is listed here with the
reason it cannot run in a test; a block that is neither fails, so a new one is never forgotten.

Shell blocks (```sh, ```console: the `$ ` lines) run command by command with bash in a
temporary folder holding a copy of `experiments/`, `impactlab` and `python` being this
interpreter's; a page's blocks run in order in one folder (a replay follows its record). Each
command exits 0 or the code the page documents (`EXIT`), each output line a ```console
block shows is printed (numbers and hashes aside: they vary with the machine), and no
warning is printed that the page does not show. ```python
blocks run as scripts, or under pytest when they define tests (a golden test writes its
golden log: its check records one run; test_golden_plugin.py checks against one). ```xml blocks are files the
commands read (written under the name their first line gives, `<!-- ball.xml -->`). ```toml
blocks parse, and a whole spec plans. ```text blocks are output, layouts and synopses.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from paths import ROOT

import impactlab

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.M | re.S)
SHELL = ("sh", "bash", "console")
NOT_COMMANDS = ("text", "toml", "xml")  # output, layouts, synopses; specs; a command's files
FILE_NAME = re.compile(r"<!-- ([\w.-]+) -->\n")  # an xml block's first line: the file it is

# pages whose python blocks another test runs as written
PYTHON_RUN_BY = {"docs/python-api.md": "tests/e2e/test_python_api.py"}

# what is not run here, by how a command or a python block starts, and why
NOT_RUN = {
    "python3 -m venv .venv": "the README's set-up commands: .ci/run runs them word for word "
    "(test_the_set_up_commands_are_what_ci_runs)",
    "pip install": "installs from the package index (tests/e2e/test_wheel.py installs the built "
    "wheel into a fresh venv and runs the commands from an empty folder)",
    "rerun ": "opens Rerun's viewer, a window (the recording it names is checked to exist)",
    "git add": "commits into the reader's repository",
    "pytest": "pytest in the reader's project (docs/golden-tests.md's update commands and "
    "walkthrough): tests/e2e/test_golden_plugin.py runs the same steps with pytester, on the "
    "same spec (test_the_golden_walkthrough_is_the_plugin_tests); the page's first test block "
    "runs here under pytest --impactlab-update-golden",
    "sed -i": "a step of the same walkthrough (the spec edited to restitution 0.81)",
    "cat > big.toml": "docs/reliability.md's memory figure: a 400,001-step log, about 1 GB "
    "resident; tests/reliability/test_reliability_memory.py measures the same on 100,001 steps",
    "impactlab record big.toml": "the same memory figure's recording",
    "python -c '\nimport resource": "the same memory figure's measurement",
    "impactlab_golden.check(": "a call inside a test, on the reader's own model models/arm.xml",
    "def test_drop(impactlab_golden):": "the walkthrough's test, run by "
    "tests/e2e/test_golden_plugin.py (the same check of drop.toml)",
}

# the exit code a page documents for a command, by how it starts
EXIT = {
    "impactlab diff logs/": 1,  # the README: 1 when they differ
    "impactlab contact --restitution 0.8 --radius 0.05 --speed 0.5..6 --timestep 0.0005": 1,
}

# pages whose commands start where a pip user does: no experiments/ (the first copies them)
FROM_NOTHING = {"README.md"}


@dataclasses.dataclass(frozen=True)
class Block:
    page: str  # relative to the repository
    line: int
    lang: str
    text: str

    def __str__(self) -> str:
        return f"{self.page}:{self.line} ```{self.lang}"


def blocks(page: Path) -> list[Block]:
    text = page.read_text(encoding="utf-8")
    name = page.relative_to(ROOT).as_posix()
    return [
        Block(name, text.count("\n", 0, m.start()) + 1, m.group(1).strip(), m.group(2))
        for m in FENCE.finditer(text)
    ]


ALL = [block for page in PAGES for block in blocks(page)]


def _complete(command: str) -> bool:
    """Whether `command` (lines so far) is a whole shell command: quotes closed, no line
    continued, every here-document ended."""
    if command.endswith("\\"):
        return False
    heredoc = re.search(r"<<-?\s*'?(\w+)'?", command)
    if heredoc and not re.search(rf"(?m)^{heredoc.group(1)}$", command[heredoc.end() :]):
        return False
    try:
        shlex.split(command, comments=True)
    except ValueError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class Command:
    text: str
    shown: tuple[str, ...]  # the output a console block shows


def commands(block: Block) -> list[Command]:
    """The commands of a shell block, in order; a console block's with the output shown."""
    found: list[Command] = []
    if block.lang == "console":
        for line in block.text.splitlines():
            if line.startswith("$ "):
                found.append(Command(line[2:], ()))
            elif found:
                found[-1] = Command(found[-1].text, (*found[-1].shown, line))
        return found
    current: list[str] = []
    for line in block.text.splitlines():
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        current.append(line)
        if _complete("\n".join(current)):
            found.append(Command("\n".join(current), ()))
            current = []
    assert not current, f"{block}: an unfinished command {current}"
    return found


def not_run(text: str) -> str | None:
    """The listed reason `text` (a command, a python block) is not run here, if it is listed."""
    for start, reason in NOT_RUN.items():
        if text.lstrip().startswith(start):
            return reason
    return None


def test_every_block_is_run_or_listed():
    """Every block has a language; every command and python block is run, or listed with its
    reason; every listed entry still names something (the list cannot rot)."""
    used: set[str] = set()
    for block in ALL:
        assert block.lang in (*SHELL, "python", *NOT_COMMANDS), f"{block}: no known language"
        assert block.lang != "xml" or FILE_NAME.match(block.text), f"{block}: names no file"
        texts = [c.text for c in commands(block)] if block.lang in SHELL else []
        if block.lang == "python" and block.page not in PYTHON_RUN_BY:
            texts = [block.text]
        for text in texts:
            used |= {start for start in NOT_RUN if text.lstrip().startswith(start)}
    assert set(NOT_RUN) == used, f"listed but found nowhere: {set(NOT_RUN) - used}"
    for page, test in PYTHON_RUN_BY.items():
        assert "```python" in (ROOT / page).read_text() and (ROOT / test).is_file()
        assert page in (ROOT / test).read_text(), f"{test} does not read {page}"


def test_the_set_up_commands_are_what_ci_runs():
    """The README's two set-up commands: the test one is .ci/run's install and test, word for
    word; the lab one installs the same way without the test extra."""
    (setup,) = [b for b in ALL if b.page == "README.md" and "python3 -m venv" in b.text]
    lab, tests = [c.text for c in commands(setup)]
    ci = (ROOT / ".ci" / "run").read_text()
    install, run_tests = tests.split(" && .venv/bin/python -m pytest")
    assert f"\n{install}\n" in ci
    assert f"\n.venv/bin/python -m pytest{run_tests}\n" in ci
    assert lab == install.replace('-e ".[test]"', "-e .") + " && .venv/bin/impactlab lab"


@pytest.mark.slow  # planning calibrates the specs' contacts: 4 s
def test_toml_blocks_parse_and_whole_specs_plan():
    specs = 0
    for block in [b for b in ALL if b.lang == "toml"]:
        doc = tomllib.loads(block.text)
        if "name" in doc and "bodies" in doc:
            assert len(impactlab.plan(doc)) >= 1, str(block)
            specs += 1
    assert specs >= 2  # docs/experiments.md's and docs/golden-tests.md's


def test_the_golden_walkthrough_is_the_plugin_tests():
    """docs/golden-tests.md's worked example is the lab's drop_restitution.toml shortened to one
    drop and two bounces (its description and colour aside), as tests/e2e/test_golden_plugin.py
    records it."""
    (spec,) = [b for b in ALL if b.page == "docs/golden-tests.md" and b.lang == "toml"]
    lab = (ROOT / "experiments" / "drop_restitution.toml").read_text()
    plugin = lab.replace("bounces = 4", "bounces = 2").split("[sweep]")[0]
    recorded = tomllib.loads(plugin)
    del recorded["description"], recorded["bodies"]["ball"]["rgba"]  # neither is physics
    assert tomllib.loads(spec.text) == recorded
    plugin_test = (ROOT / "tests" / "e2e" / "test_golden_plugin.py").read_text()
    assert 'SPEC.replace("restitution = 0.8", "restitution = 0.81")' in plugin_test


MASK = re.compile(r"[0-9a-f]{8,}|\d+(?:\.\d+)?(?:e[+-]?\d+)?")


def _masked(line: str) -> str:
    """A line with its numbers and hashes masked, spaces squeezed: what a machine does not
    change."""
    return " ".join(MASK.sub("#", line).split())


def _tools(folder: Path) -> dict[str, str]:
    """The environment of a reader's shell: `impactlab` and `python` are this interpreter's."""
    folder.mkdir()
    for name, head in (("impactlab", f"{sys.executable} -m impactlab"), ("python", sys.executable)):
        (folder / name).write_text(f'#!/bin/sh\nexec {head} "$@"\n')
        (folder / name).chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV",)}
    env["PATH"] = f"{folder}{os.pathsep}{env['PATH']}"
    env["MPLBACKEND"] = "Agg"
    return env


def _run_command(command: Command, block: Block, work: Path, env: dict[str, str]) -> None:
    if not_run(command.text):
        if command.text.startswith("rerun "):
            (named,) = shlex.split(command.text, comments=True)[1:]
            assert list(work.glob(named)), f"{block}: {named} is not written"
        return
    expected = next((code for start, code in EXIT.items() if command.text.startswith(start)), 0)
    done = subprocess.run(
        ["bash", "-o", "pipefail", "-c", command.text],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == expected, (
        f"{block}: `{command.text}` exited {done.returncode}\n{done.stdout}\n{done.stderr}"
    )
    printed = {_masked(line) for line in (done.stdout + done.stderr).splitlines()}
    shown = [line for line in command.shown if line.strip() not in ("...", "")]
    missing = [line for line in shown if "..." not in line and _masked(line) not in printed]
    assert missing == [], f"{block}: `{command.text}` printed\n{done.stdout}\n{done.stderr}"
    warned = [line for line in printed if "warning" in line.lower()]  # pip's, Python's, ours
    assert [w for w in warned if w not in map(_masked, shown)] == [], f"{block}: {warned}"


def _run_python(block: Block, work: Path, env: dict[str, str]) -> None:
    if not_run(block.text):
        return
    script = "test_block.py" if "def test_" in block.text else "block.py"
    (work / script).write_text(block.text)
    args = [sys.executable, script]
    if script == "test_block.py":  # tests: under pytest, writing the golden logs they check
        args = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", script]
        args += ["--impactlab-update-golden"] if "impactlab_golden" in block.text else []
    done = subprocess.run(args, cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{block}: {args}\n{done.stdout}\n{done.stderr}"
    assert "passed" in done.stdout or script == "block.py", done.stdout
    assert "warning" not in (done.stdout + done.stderr).lower(), f"{block}: {done.stdout}"


RUN_PAGES = sorted(
    {
        b.page
        for b in ALL
        if (b.lang in SHELL and any(not not_run(c.text) for c in commands(b)))
        or (b.lang == "python" and b.page not in PYTHON_RUN_BY and not not_run(b.text))
    }
)


@pytest.mark.slow
@pytest.mark.parametrize("page", RUN_PAGES)
def test_the_page_runs_as_written(page, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    if page not in FROM_NOTHING:
        shutil.copytree(ROOT / "experiments", work / "experiments")
    env = _tools(tmp_path / "bin")
    for block in [b for b in ALL if b.page == page]:
        if block.lang in SHELL:
            for command in commands(block):
                _run_command(command, block, work, env)
        elif block.lang == "python" and page not in PYTHON_RUN_BY:
            _run_python(block, work, env)
        elif block.lang == "xml":
            name = FILE_NAME.match(block.text)
            assert name, f"{block}: the first line names no file"
            (work / name.group(1)).write_text(block.text)
