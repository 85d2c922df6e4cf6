"""The figures as a person sees them (the PNG): log-axis ticks drawn as math (10⁰, not the raw
`$\\mathdefault{10^{0}}$`), one colour per experiment for every marker family, the energy
figure's time axis ending with the data; and drawing leaves the user's matplotlib alone."""

from __future__ import annotations

import subprocess
import sys
import warnings

import matplotlib.colors
import numpy as np
import polars as pl
import pytest
from matplotlib import image

from impactlab.analyze.report import figures

HUES = {"C0 blue": 205, "C1 orange": 28, "C2 green": 120, "C3 red": 0}


def _pixels(png):
    rgb = image.imread(png)[..., :3]
    return rgb, matplotlib.colors.rgb_to_hsv(rgb)


def hue_count(png, hue: float) -> int:
    _, hsv = _pixels(png)
    vivid = (hsv[..., 1] > 0.45) & (hsv[..., 2] > 0.25)
    return int(np.count_nonzero(vivid & (np.abs((hsv[..., 0] * 360 - hue + 180) % 360 - 180) < 12)))


def spines(png) -> tuple[int, int]:
    """The x of the plot's left and right spines: the outermost columns that are dark over
    more than a third of the image's height."""
    rgb, _ = _pixels(png)
    dark = (rgb.max(axis=-1) < 0.25).sum(axis=0) > rgb.shape[0] / 3
    xs = np.flatnonzero(dark)
    return int(xs[0]), int(xs[-1])


def test_log_axis_ticks_are_math_not_raw_text(tmp_path):
    runs = [f"r{i}" for i in range(3)]
    bounces = pl.DataFrame(
        {
            "run_id": [r for r in runs for _ in range(3)],
            "body": "ball",
            "surface": "floor",
            "bounce": [1, 2, 3] * 3,
            "apex_before_m": [h * 0.64**b for h in (0.9, 1.9, 2.9) for b in range(3)],
            "apex_m": [h * 0.64 ** (b + 1) for h in (0.9, 1.9, 2.9) for b in range(3)],
            "complete": True,
            "note": "",
        }
    )
    png = tmp_path / "decay.png"
    figures.bounce_decay_figure(bounces, {r: r for r in runs}, title="decay", path=png)
    left, _ = spines(png)
    width = image.imread(png).shape[1]
    # raw `$\mathdefault{10^{0}}$` tick labels pushed the axes to 29 % of the width
    assert left < 0.15 * width, (left, width)


def test_every_experiment_has_its_colour_in_every_marker_family(tmp_path):
    bounces = pl.DataFrame(
        {
            "run_id": ["d1", "d1", "d2", "d2"],
            "complete": True,
            "v_in_mps": [-4.2, -3.4, -6.1, -4.9],
            "e_velocity": [0.8, 0.8, 0.07, 0.05],
            "e_apex": [0.8, 0.8, None, 0.05],
        }
    )
    collisions = pl.DataFrame(
        {
            "run_id": ["c1", "c2", "c3"],
            "complete": True,
            "v1n_before_mps": [3.0, 3.0, 2.0],
            "v2n_before_mps": [-1.0, -1.0, -1.0],
            "e_velocity": [0.5, 0.99, 0.14],
        }
    )
    experiments = {"d1": "calibrated", "d2": "handout", "c1": "sweep", "c2": "sweep", "c3": "pair"}
    png = tmp_path / "e.png"
    figures.restitution_figure(
        bounces, collisions, experiments, path=png, targets={"calibrated": [0.8]}
    )
    for name, hue in HUES.items():  # one colour each for the four experiments
        assert hue_count(png, hue) > 40, name


def test_energy_figure_time_axis_ends_with_the_data(tmp_path):
    t = np.linspace(0.0, 1.15, 500)
    h = np.maximum(2.9 - 0.5 * 9.81 * t**2, 0.0)
    energy = pl.DataFrame(
        {
            "body": ["ball"] * 500 * 2,
            "is_total": [False] * 500 + [True] * 500,
            "t_s": np.concatenate([t, t]),
            "height_m": np.concatenate([h, h]),
            "ke_trans_J": np.concatenate([t, t]),
            "ke_rot_J": 0.0,
            "pe_J": np.concatenate([h, h]),
            "total_J": np.concatenate([h + t, h + t]),
            "mujoco_total_J": None,
        },
        schema_overrides={"mujoco_total_J": pl.Float64},
    )
    contacts = pl.DataFrame({"start_t_s": [0.77, 0.97], "end_t_s": [0.86, 3.9]})  # one runs on
    png = tmp_path / "energy.png"
    figures.energy_figure(energy, contacts, title="drop", path=png)
    left, right = spines(png)
    blue = np.flatnonzero((_pixels(png)[1][..., 1] > 0.45).any(axis=0))
    assert right - blue.max() < 0.03 * (right - left)  # the line reaches the right spine


@pytest.mark.slow  # a fresh interpreter imports matplotlib and the analysis: over 2 s
def test_drawing_leaves_the_users_matplotlib_as_it_was():
    code = (
        "import matplotlib, sys\n"
        "matplotlib.rcParams['lines.linewidth'] = 7.0\n"
        "before = dict(dict.items(matplotlib.rcParams))  # raw: reading 'backend' resolves it\n"
        "backend = dict.__getitem__(matplotlib.rcParams, 'backend')\n"
        "from pathlib import Path\n"
        "import tempfile\n"
        "from impactlab.analyze.report import figures\n"
        "from impactlab.plotting import subplots, save_figure, styled\n"
        "@styled\n"
        "def draw(path):\n"
        "    fig, ax = subplots(figsize=(2, 1)); ax.plot([0, 1]); ax.set_yscale('log')\n"
        "    assert matplotlib.rcParams['lines.linewidth'] == 1.5\n"
        "    return save_figure(fig, path)\n"
        "draw(Path(tempfile.mkdtemp()) / 'x.png')\n"
        "assert dict(dict.items(matplotlib.rcParams)) == before\n"
        "assert dict.__getitem__(matplotlib.rcParams, 'backend') == backend\n"
        "assert matplotlib.rcParams['text.parse_math']\n"
        "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot imported'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]


def test_energy_figure_of_many_bodies_labels_none_and_lays_out(tmp_path):
    """A legend entry per body would outgrow the figure (100 boxes: tight_layout gave up and the
    legend covered the energy plot): beyond MAX_LEGEND_LINES the title counts the bodies."""
    t = np.linspace(0.0, 0.5, 50)
    bodies = [f"box{i:03d}" for i in range(100)]
    energy = pl.DataFrame(
        {
            "body": [b for b in bodies for _ in t] + ["total"] * t.size,
            "is_total": [False] * (t.size * len(bodies)) + [True] * t.size,
            "t_s": np.tile(t, len(bodies) + 1),
            "height_m": np.tile(1.0 - t, len(bodies) + 1),
            "ke_trans_J": np.tile(t, len(bodies) + 1),
            "ke_rot_J": 0.0,
            "pe_J": np.tile(1.0 - t, len(bodies) + 1),
            "total_J": 1.0,
            "mujoco_total_J": None,
        },
        schema_overrides={"mujoco_total_J": pl.Float64},
    )
    for contacts in (  # with a contact to shade, and none (no legend at all)
        pl.DataFrame({"start_t_s": [0.1], "end_t_s": [0.5]}),
        pl.DataFrame(
            {"start_t_s": [], "end_t_s": []},
            schema={"start_t_s": pl.Float64, "end_t_s": pl.Float64},
        ),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # "Tight layout not applied", "No artists with labels"
            png = figures.energy_figure(energy, contacts, title="pile", path=tmp_path / "e.png")
        assert png.stat().st_size > 0
    assert len(bodies) > figures.MAX_LEGEND_LINES
