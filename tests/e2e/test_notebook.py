"""Notebooks: examples/quickstart.ipynb runs in a real Jupyter kernel (nbclient) from examples/
and from any folder; results show as one line and small escaped HTML tables; verbose=True
draws tqdm.auto's bar; an inline replay holds the same recording `impactlab replay` writes."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import rerun as rr
from paths import ROOT

import impactlab
from impactlab.analyze.tables.combine import AnalysisResult
from impactlab.progress import ConsoleProgress, ProgressEvent, in_notebook, reporter
from impactlab.replay.notebook import NotebookReplay, Recordings

pytestmark = [pytest.mark.slow, pytest.mark.extras]  # a Jupyter kernel (the notebook extra)

NOTEBOOK = ROOT / "examples" / "quickstart.ipynb"
RERUN = Path(sys.executable).parent / "rerun"
WIDGET = "application/vnd.jupyter.widget-view+json"


def _outputs(nb, first_line: str) -> list:
    (cell,) = [c for c in nb.cells if c.cell_type == "code" and c.source.startswith(first_line)]
    return cell.outputs


def _result(outputs) -> dict:
    (result,) = [o for o in outputs if o.output_type == "execute_result"]
    return result["data"]


def _kernel(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A kernel spec of this interpreter, found first (JUPYTER_PATH), so the notebook runs
    with the impactlab under test whatever other kernels the machine has; Jupyter's and
    IPython's files go into tmp_path."""
    spec = tmp_path / "jupyter" / "kernels" / "impactlab-test"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(
        json.dumps({"argv": argv, "display_name": "impactlab test", "language": "python"})
    )
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("JUPYTER_RUNTIME_DIR", str(tmp_path / "runtime"))
    monkeypatch.setenv("IPYTHONDIR", str(tmp_path / "ipython"))
    return "impactlab-test"


@pytest.mark.parametrize("where", ["examples", "elsewhere"])
def test_the_quickstart_notebook_runs_in_a_kernel(tmp_path, monkeypatch, where):
    """Opened from `examples/` (Jupyter's working folder is the notebook's) or from any other
    folder, as after a pip install: no `experiments/` beside it, the packaged specs are read."""
    work = tmp_path / where
    work.mkdir()
    if where == "examples":
        shutil.copy(NOTEBOOK, work)
    assert not (work / "experiments").exists() and not (tmp_path / "experiments").exists()
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code"), "stored outputs"
    client = NotebookClient(
        nb,
        timeout=300,
        kernel_name=_kernel(tmp_path, monkeypatch),
        resources={"metadata": {"path": str(work)}},
    )
    client.execute()  # raises CellExecutionError with the cell's traceback when a cell fails

    # the specs as installed: every experiment the package ships
    listed = _result(_outputs(nb, "import impactlab"))["text/plain"]
    assert all(p.name in listed for p in (ROOT / "experiments").glob("*.toml"))

    # record: a progress widget, the runs' lines, the result as one line and a table
    record = _outputs(nb, "runs = impactlab.record(")
    assert any(WIDGET in o.get("data", {}) for o in record)
    data = _result(record)
    assert data["text/plain"] == "<RecordResult 2 runs: 2 recorded, logs/>"
    logs = sorted((work / "logs").glob("*.mcap"))
    assert len(logs) == 2
    html = data["text/html"]
    assert html.startswith('<table class="impactlab">') and html.count("<tr>") == 3
    assert all(f"<td>{p.name}</td>" in html for p in logs)

    # load and analyze: the same one-liners as in this process
    log = impactlab.load(logs[0])
    assert _result(_outputs(nb, "log = impactlab.load"))["text/plain"] == repr(log)
    analysis = _result(_outputs(nb, "result = impactlab.analyze"))
    here = impactlab.analyze(logs)
    assert (
        analysis["text/plain"]
        == repr(here)
        == "<Analysis 2 runs, 4 bounces, 0 collisions, nothing written>"
    )
    assert analysis["text/html"] == here._repr_html_()

    # the progress bars: tqdm.auto's widgets, full at the end (2 of 2 runs, 2 of 2 logs)
    state = nb.metadata["widgets"]["application/vnd.jupyter.widget-state+json"]["state"]
    bars = [m["state"] for m in state.values() if m["model_name"] == "FloatProgressModel"]
    assert [(b["value"], b["max"]) for b in bars] == [(2.0, 2.0), (2.0, 2.0)]

    # the inline replay: Rerun's viewer widget, displayed at the cell's size
    (shown,) = [o for o in _outputs(nb, "replay = impactlab.replay") if WIDGET in o.get("data", {})]
    viewer = state[shown["data"][WIDGET]["model_id"]]["state"]
    assert viewer["_height"] == 480 and viewer["_width"] == "auto"


@pytest.fixture(scope="module")
def drop(tmp_path_factory) -> list[Path]:
    out = tmp_path_factory.mktemp("drop")
    runs = impactlab.record(
        ROOT / "experiments" / "free_fall.toml", out=out / "logs", overrides=["stop.max_time=0.6"]
    )
    return runs.paths


def _entities(path: Path) -> set[str]:
    return {c.entity_path for c in rr.chunk.RrdReader(path).stream() if not c.is_static}


def test_an_inline_replay_holds_the_recording_replay_writes(drop, tmp_path):
    inline = impactlab.replay(drop, notebook=True)
    assert isinstance(inline, NotebookReplay)
    assert (
        repr(inline) == f"<NotebookReplay 1 run, {len(inline.data) / 1e6:.2f} MB: {drop[0].stem}>"
    )
    saved = inline.save(tmp_path / "inline.rrd")
    done = subprocess.run([str(RERUN), "rrd", "verify", str(saved)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()
    written = impactlab.replay(drop, out=tmp_path / "files")
    assert isinstance(written, Recordings) and isinstance(written, list)
    assert written == [tmp_path / "files" / f"{drop[0].stem}.rrd"]
    assert _entities(saved) == _entities(written[0]) and len(_entities(saved)) > 3
    assert rr.chunk.RrdReader(saved).blueprints(), "no default blueprint"
    assert repr(written).startswith("<Recordings 1 .rrd file, ") and "files/>" in repr(written)
    from rerun_notebook import Viewer

    assert isinstance(inline.viewer(), Viewer)
    with pytest.raises(ValueError, match="writes no file"):
        impactlab.replay(drop, notebook=True, out=tmp_path / "x.rrd")


def test_reprs_are_short_and_html_escapes_names_from_logs(drop):
    log = impactlab.load(drop[0])
    assert len(repr(log)) < 200 and repr(log).startswith("<RunLog free_fall")
    bad = "<img src=x onerror=alert(1)>\x1b[31m"
    evil = dataclasses.replace(log, run_id=bad, bodies={bad: log.bodies["ball"]})
    assert "\x1b" not in repr(evil) and "\\x1b[31m" in repr(evil)
    html = evil._repr_html_()
    assert "<img" not in html and "&lt;img src=x onerror=alert(1)&gt;" in html
    result = impactlab.analyze(drop)
    assert result.bounces["impact_t_s"].to_list() == [None]  # a row saying why: no contact
    assert repr(result) == "<Analysis 1 run, 0 bounces, 0 collisions, nothing written>"
    runs = result.runs.with_columns(run_id=result.runs["run_id"] + bad)
    shown = dataclasses.replace(result, runs=runs, failed=[(bad, "not a log")])
    assert isinstance(shown, AnalysisResult)
    assert "<img" not in shown._repr_html_() and "&lt;img" in shown._repr_html_()
    assert "1 failed" in repr(shown)


def test_verbose_progress_outside_a_notebook_is_the_console_bar(capsys):
    assert not in_notebook()
    with reporter(None, True) as shown:
        assert isinstance(shown, ConsoleProgress) and not shown.notebook
    bar = ConsoleProgress(notebook=True)  # tqdm.auto outside a kernel: the text bar, kept
    for done in range(3):
        bar(ProgressEvent("record", done, 2, {"finished": done}))
    bar.close()
    err = capsys.readouterr().err
    assert "record: 100%" in err and "2/2" in err
