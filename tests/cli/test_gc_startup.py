"""The program's garbage collector: off while a command starts, on once it has started."""

from __future__ import annotations

import gc

import pytest
from specs import drop, write

from impactlab.cli import main


@pytest.fixture
def collector_off():
    """The state `impactlab.cli.command` runs `main` in: the collector off, nothing frozen."""
    assert gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.unfreeze()
        gc.enable()


def test_record_turns_the_collector_back_on_with_its_start_up_frozen(
    collector_off, tmp_path, monkeypatch
):
    spec = write(tmp_path, drop(max_time=0.05))
    seen = {}
    from impactlab.record import recorder

    real = recorder.record_runs

    def recording(*args, **kwargs):  # what the collector is while the runs are recorded
        seen["enabled"], seen["frozen"] = gc.isenabled(), gc.get_freeze_count()
        return real(*args, **kwargs)

    monkeypatch.setattr(recorder, "record_runs", recording)
    assert main(["record", str(spec), "-o", str(tmp_path / "logs")]) == 0
    assert seen["enabled"] and seen["frozen"] > 0
    assert len(list((tmp_path / "logs").glob("*.mcap"))) == 1


def test_other_commands_turn_it_on_as_soon_as_their_options_are_read(collector_off, capsys):
    with pytest.raises(SystemExit):
        main(["info", "--help"])  # argparse exits before any command runs: still off
    assert not gc.isenabled()
    assert main(["info", "/nonexistent/x.mcap"]) != 0  # a user mistake: one line, exit code
    assert gc.isenabled()
