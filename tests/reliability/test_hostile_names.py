"""Nothing a model, a spec or a log says can run in the report, load anything, or reach the
terminal as an escape: names full of HTML, Markdown images of local files, devices and URLs,
newlines and escape sequences go through `record`, `analyze` and `info` as real processes,
and report.html is opened in headless Chromium (Debian's `chromium`, which `.ci/run`
installs).

MuJoCo takes any character in a name (XML attributes escape `<`, `"`, `&` and newlines), so
the names are the payloads as an attacker would write them.
"""

from __future__ import annotations

import base64
import html
import os
import re
import resource
import shutil
import subprocess
import sys
import threading
from collections.abc import Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import ClassVar

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from markdown_it import MarkdownIt
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_copy import register_like
from specs import drop, toml

from impactlab.logs import format as logformat

pytestmark = pytest.mark.slow  # headless Chromium, figures and Markdown of every hostile name

PAGES = {
    "report.html": "Impact lab: free fall and impact",
    "report-appendix.html": "Impact lab: appendix",
}
SCRIPT_BODY = "<img src=x onerror=\"document.title='PWNED'\">"
SCRIPT_FLOOR = "<script>document.title='PWNED'</script>"
SCRIPT_FILE = "<svg onload=document.title='PWNED'>"  # a legal file name (no slash)
SPEC = toml(
    drop(
        "__init__",
        description=f"{SCRIPT_BODY} ![d](/etc/passwd)",
        body="_ball_",
        z=0.15,
        max_time=0.2,
    )
)
MEMORY_LIMIT = 3 * 2**30  # a run that reads /dev/zero fails fast instead of filling memory
TIMEOUT_S = 120  # a run that reads /dev/stdin (an open pipe here) would wait forever


def model(floor: str, bodies: Sequence[str]) -> str:
    """An MJCF model: a floor geom and balls dropped 5 cm onto it, with these names."""

    def attr(name: str) -> str:
        return html.escape(name, quote=True).replace("\n", "&#10;")

    balls = "".join(
        f'<body name="{attr(b)}" pos="{i * 0.5} 0 0.15"><freejoint/>'
        f'<geom type="sphere" size="0.1" mass="1"/></body>\n'
        for i, b in enumerate(bodies)
    )
    return (
        f'<mujoco>\n<option timestep="0.001"/>\n<worldbody>\n'
        f'<geom name="{attr(floor)}" type="plane" size="5 5 0.1"/>\n{balls}</worldbody>\n'
        "</mujoco>\n"
    )


def impactlab(*args: str) -> subprocess.CompletedProcess:
    """`python -m impactlab ARGS` in a process of its own (`python`)."""
    return python("-m", "impactlab", *args)


def python(*args: str) -> subprocess.CompletedProcess:
    """`python ARGS` in a process of its own, with a memory limit, a timeout, and an open
    pipe as stdin."""
    keep, write = os.pipe()  # nothing is ever written: a read of /dev/stdin would wait

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))

    try:
        return subprocess.run(
            [sys.executable, *args],
            stdin=keep,
            capture_output=True,
            timeout=TIMEOUT_S,
            preexec_fn=limit,
            env={**os.environ, "MUJOCO_GL": "disable"},
        )
    finally:
        os.close(keep)
        os.close(write)


def record(inputs: Sequence[Path], out: Path, *options: str) -> list[Path]:
    done = impactlab("record", *map(str, inputs), "-o", str(out), *options)
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    return sorted(out.glob("*.mcap"))


def analyze(inputs: Sequence[Path], out: Path) -> subprocess.CompletedProcess:
    return impactlab("analyze", *map(str, inputs), "-o", str(out), "--no-figures")


def rewrite(log: Path, path: Path, **changes: str) -> Path:
    """The log copied by the official writer with these metadata values (run or outcome)."""
    with open(log, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        meta = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        messages = [(c, m) for _, c, m in reader.iter_messages(log_time_order=False)]
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="hostile")
        channels = register_like(writer, summary)
        for name, values in meta:
            outcome = name == logformat.OUTCOME_METADATA
            mine = {k: v for k, v in changes.items() if (k in logformat.OUTCOME_KEYS) == outcome}
            writer.add_metadata(name, {**values, **mine})
        for channel, m in messages:
            writer.add_message(
                channels[channel.id], log_time=m.log_time, publish_time=m.log_time, data=m.data
            )
        writer.finish()
    return path


def browse(page: Path, profile: Path) -> str:
    """The page's DOM after load, as headless Chromium leaves it (scripts run, images
    loaded or failed)."""
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        pytest.fail("headless Chromium is needed: apt-get install chromium (.ci/run does)")
    cmd = [
        found,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={profile}",
        "--virtual-time-budget=5000",
        "--dump-dom",
        page.as_uri(),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def title(dom: str) -> str:
    found = re.search(r"<title>(.*?)</title>", dom, re.DOTALL)
    assert found, dom[:500]
    return html.unescape(found.group(1))


def text_of(dom: str) -> str:
    """The page's visible text (tags removed, entities decoded)."""
    body = dom[dom.index("<body") :]
    return html.unescape(re.sub(r"<[^>]*>", "", body))


class Requests(BaseHTTPRequestHandler):
    """Answers nothing; counts what it was asked."""

    seen: ClassVar[list[str]] = []

    def do_GET(self) -> None:
        Requests.seen.append(self.path)
        self.send_response(404)
        self.end_headers()

    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def spec_log(tmp_path_factory) -> Path:
    """SPEC recorded once (`impactlab record` in a process of its own, under the limits), for
    the tests that copy it with crafted metadata: they read it, never write it."""
    folder = tmp_path_factory.mktemp("spec")
    (folder / "spec.toml").write_text(SPEC)
    (log,) = record([folder / "spec.toml"], folder / "logs")
    return log


@pytest.fixture
def server():
    Requests.seen = []
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Requests)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()


def test_no_name_runs_script_in_the_page(tmp_path, spec_log):
    """Body, geom, file, experiment and input names full of HTML: the page runs no script
    (its title stays), and each name reads in the page as written."""
    xml = tmp_path / f"{SCRIPT_FILE}.xml"
    xml.write_text(model(SCRIPT_FLOOR, [SCRIPT_BODY]))
    # 0.25 s: not the same run as spec_log's (the report names a repeated run's bodies once)
    (drop,) = record([xml], tmp_path / "logs", "--duration", "0.25")
    ball = spec_log
    crafted = rewrite(ball, tmp_path / "crafted.mcap", experiment=SCRIPT_BODY, run_id="crafted")
    unreadable = tmp_path / f"{SCRIPT_FILE}.mcap"
    unreadable.write_bytes(b"not a log")
    out = tmp_path / "results"
    done = analyze([drop, ball, crafted, unreadable], out)
    assert done.returncode == 1, done.stderr  # one input could not be read, the others were
    shown = ""
    for name, expected_title in PAGES.items():  # the report and its appendix
        dom = browse(out / name, tmp_path / "profile")
        assert title(dom) == expected_title  # no onerror, onload or script ran
        page = (out / name).read_text(encoding="utf-8")
        assert "<img" not in page and "<script" not in page and "<svg" not in page
        assert "<strong>init</strong>" not in dom and "<em>ball</em>" not in dom
        shown += text_of(dom)
    for name in (SCRIPT_BODY, SCRIPT_FLOOR, SCRIPT_FILE, str(unreadable), "__init__", "_ball_"):
        assert name in shown, name


def test_no_name_puts_a_local_file_in_the_page(tmp_path):
    """Body names that are Markdown images of a secret file, /dev/zero and /dev/stdin: the
    analysis ends (within its memory limit and timeout), the page holds none of them."""
    secret = tmp_path / "secret"
    secret.write_bytes(b"TOP-SECRET-0123456789 " * 4)
    names = [f"![s]({secret})", "![z](/dev/zero)", "![i](/dev/stdin)"]
    xml = tmp_path / "files.xml"
    xml.write_text(model("floor", names))
    logs = record([xml], tmp_path / "logs", "--duration", "0.2")
    out = tmp_path / "results"
    done = analyze(logs, out)
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-2000:]
    page = (out / "report.html").read_text(encoding="utf-8")
    data = secret.read_bytes()
    assert b"TOP-SECRET" not in page.encode() and base64.b64encode(data).decode() not in page
    assert "<img" not in page and "data:" not in page.split("</head>")[1]
    for name in names:
        assert html.escape(name, quote=False) in page, name


def test_no_name_loads_a_url_or_makes_a_heading(tmp_path, server):
    """Names that are Markdown and HTML images of a URL: a browser opening the page sends no
    request. A newline in a name makes no heading in report.md."""
    names = [f"![r]({server}/markdown.png)", f'<img src="{server}/html.png">']
    floor = "floor\n# HEADING\n"
    xml = tmp_path / "net.xml"
    xml.write_text(model(floor, names))
    logs = record([xml], tmp_path / "logs", "--duration", "0.2")
    out = tmp_path / "results"
    done = analyze(logs, out)
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-2000:]
    shown = ""
    for name in PAGES:  # the report and its appendix
        page = out / name
        dom = browse(page, tmp_path / "profile")
        assert Requests.seen == []
        assert "Content-Security-Policy" in page.read_text(encoding="utf-8")
        assert not re.search(r"<h\d[^>]*>\s*HEADING", dom)
        shown += text_of(dom)
    assert all(name in shown for name in names)
    for report in ("report.md", "report-appendix.md"):
        text = (out / report).read_text(encoding="utf-8")
        assert not re.search(r"^\s*#+ HEADING", text, re.MULTILINE)
    assert "floor\\n# HEADING\\n" in shown  # the newline shown as an escape


def test_info_and_errors_print_no_terminal_escape(tmp_path, spec_log):
    """A log whose metadata retitles the terminal and clears the screen: `impactlab info`
    prints the escapes as text; an input whose name holds them is named the same way."""
    crafted = rewrite(
        spec_log,
        tmp_path / "crafted.mcap",
        experiment="\x1b]0;title\x07",
        source="\x1b[2J\x9b2J",
        reason="cleared\x1b[2J\nforged line",
    )
    done = impactlab("info", str(crafted))
    assert done.returncode == 0, done.stderr
    out = done.stdout + done.stderr
    assert b"\x1b" not in out and b"\x07" not in out and "\x9b".encode() not in out
    text = done.stdout.decode()
    assert "experiment: \\x1b]0;title\\x07 (\\x1b[2J\\x9b2J)" in text
    assert "cleared\\x1b[2J\\nforged line" in text
    bad = tmp_path / "bad\x1b[2J\x1b]0;x\x07.mcap"
    bad.write_bytes(b"junk")
    for command in (["info", str(bad)], ["analyze", str(bad), "-o", str(tmp_path / "r")]):
        done = impactlab(*command)
        assert done.returncode in (1, 2)
        assert b"\x1b" not in done.stdout + done.stderr, command
        assert b"bad\\x1b[2J\\x1b]0;x\\x07.mcap" in done.stderr, command


def test_names_in_figures_are_text(tmp_path):
    """Names with `$` are drawn as written, not parsed as mathtext (an unknown command there
    failed the analysis of the log)."""
    xml = tmp_path / "math.xml"
    xml.write_text(model("$\\frac{$", ["$\\undefinedcmd$"]))
    logs = record([xml], tmp_path / "logs", "--duration", "0.2")
    out = tmp_path / "results"
    done = impactlab("analyze", *map(str, logs), "-o", str(out))
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-2000:]
    assert len(list((out / "figures").glob("energy-*.png"))) == 1
    assert "$\\undefinedcmd$" in text_of((out / "report.html").read_text(encoding="utf-8"))


TEMPLATES = ("{}", "- {} tail", "x {} y", "| a | {} |\n|---|---|\n| {} | b |\n", "- {} on {}")


@settings(max_examples=400, deadline=None)
@given(st.text(alphabet=st.sampled_from(list("ab1 _*`[]()!<>&|\\#-+=.~$:\"'\n\t\x1b\x85\u202e"))))
def test_md_text_renders_as_the_text_itself(name):
    """Any text through `md_text`, in a paragraph, a list item or a table cell, renders as
    that text (control characters as their escapes) and adds no element; in a table,
    through report.html's direct path for plain cells too."""
    # imported here, so that the other tests of the file run on any version
    from impactlab.text import md_text, visible

    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    expected = visible(name).strip(" ")
    assume(expected)  # blank: no paragraph at all
    for template in TEMPLATES:
        plain = md.render(template.replace("{}", "Q"))
        rendered = md.render(template.replace("{}", md_text(name)))
        tags = re.findall(r"<[a-z0-9]+", rendered)
        assert tags == re.findall(r"<[a-z0-9]+", plain), (template, rendered)
        texts = re.findall(r">([^<]*)<", rendered)
        shown = [html.unescape(t) for t in texts if t.strip()]
        assert any(expected in t for t in shown), (template, rendered)


def test_no_name_writes_outside_the_output_folder(tmp_path, spec_log):
    """A log whose run id is a path out of the output folder: its figure is written inside the
    folder, under a name made safe (before, it went to that path)."""
    target = tmp_path / "outside"  # figures/energy-x/../../.. ... /outside.png
    crafted = rewrite(
        spec_log, tmp_path / "crafted.mcap", run_id="x/" + "../" * 40 + str(target)[1:]
    )
    out = tmp_path / "results"
    done = impactlab("analyze", str(crafted), "-o", str(out))
    assert not target.with_suffix(".png").exists()
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-2000:]
    (figure,) = (out / "figures").glob("energy-*.png")
    assert figure.is_file() and "/" not in figure.name
    assert {p for p in tmp_path.iterdir()} == {out, tmp_path / "crafted.mcap"}
