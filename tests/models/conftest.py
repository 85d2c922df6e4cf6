"""The model tests' fixture: a pinned zoo model run by plain MuJoCo and by impactlab, once per
session (`zoo_models.ZooRun`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from zoo_models import PINNED_S, ZooRun, model_path, oracle, working_dir, zoo


@pytest.fixture(scope="session")
def zoo_run(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, int], ZooRun]:
    """`zoo_run(name, every)`: the pinned model `name` (a key of PINNED_S) run by the oracle and
    by impactlab logging every `every`-th step, once per session; figures, report and replay
    are written for stride 1 only (the tables for every stride: the comparison reads them)."""
    cache: dict[tuple[str, int], ZooRun] = {}

    def run(name: str, every: int) -> ZooRun:
        if (name, every) not in cache:
            duration = PINNED_S[name]
            path = model_path(name)
            folder = tmp_path_factory.mktemp(Path(name).stem)
            with working_dir(folder):
                truth = oracle.run(path, duration, every)
                if zoo.SPRINGS_BOOKED_AS_WORK:
                    truth = oracle.springs_booked_as_work(truth)
                side = zoo.impactlab_side(path, duration, every, folder, publish=every == 1)
            cache[name, every] = ZooRun(name, path, truth, side, folder / f"every{every}")
        return cache[name, every]

    return run
