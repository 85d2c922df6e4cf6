"""The handout's experiments ship with impactlab: `impactlab examples` copies them, and
`impactlab lab` without an experiments/ folder runs them (said in one line)."""

from __future__ import annotations

from pathlib import Path

import pytest
from paths import ROOT

from impactlab.cli import main
from impactlab.examples import example_specs, packaged_experiments
from impactlab.lab import _specs


def test_the_packaged_specs_are_the_repositorys():
    """In a checkout they are experiments/ itself; in a wheel, copies of it (tests/e2e/test_wheel.py)."""
    names = [p.name for p in example_specs()]
    assert names == sorted(p.name for p in (ROOT / "experiments").glob("*.toml"))
    assert "drop_restitution.toml" in names
    assert packaged_experiments().is_dir()


def test_examples_copies_them_and_never_overwrites(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["examples"]) == 0
    copied = sorted((tmp_path / "experiments").glob("*.toml"))
    assert [p.name for p in copied] == [p.name for p in example_specs()]
    assert all(
        c.read_bytes() == s.read_bytes() for c, s in zip(copied, example_specs(), strict=True)
    )
    out = capsys.readouterr().out
    assert "run them with: impactlab lab\n" in out
    (tmp_path / "experiments" / "drop.toml").write_text("# mine\n")
    assert main(["examples"]) == 2  # nothing copied, the edited spec kept
    err = capsys.readouterr().err.strip()
    assert err.startswith("impactlab: error: experiments/collision.toml: exists already")
    assert "\n" not in err
    assert (tmp_path / "experiments" / "drop.toml").read_text() == "# mine\n"
    assert main(["examples", "mine"]) == 0
    assert "impactlab lab --experiments mine" in capsys.readouterr().out
    (tmp_path / "afile").write_text("")
    assert main(["examples", "afile"]) == 2
    assert "afile: exists and is not a folder" in capsys.readouterr().err


def test_lab_runs_the_packaged_specs_without_an_experiments_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    lines = []
    specs = _specs(None, lambda event: lines.append(event.line))
    assert specs == example_specs()
    assert len(lines) == 1 and str(packaged_experiments()) in lines[0]
    assert "impactlab examples" in lines[0]
    (tmp_path / "experiments").mkdir()
    (tmp_path / "experiments" / "mine.toml").write_text("")
    lines.clear()
    assert _specs(None, lambda event: lines.append(event.line)) == [Path("experiments/mine.toml")]
    assert lines == []


def test_an_explicit_folder_without_specs_says_where_they_are(tmp_path, capsys):
    assert main(["lab", "--experiments", str(tmp_path), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "no experiment specs (*.toml) there" in err and "impactlab examples DIR" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize("module", ["impactlab.golden", "impactlab.proto.generate"])
def test_checkout_tools_fail_in_one_line_outside_a_checkout(module, tmp_path, monkeypatch, capsys):
    """Installed from a wheel there is no tests/golden/ or schemas/: one line, exit 2."""
    import importlib

    mod = importlib.import_module(module)
    if module == "impactlab.golden":
        monkeypatch.setattr(mod, "SPECS_DIR", tmp_path / "tests" / "golden" / "specs")
        assert mod.main([]) == 2
    else:
        monkeypatch.setattr(mod, "SCHEMA_DIR", tmp_path / "schemas")
        assert mod.main() == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err and "checkout" in err
