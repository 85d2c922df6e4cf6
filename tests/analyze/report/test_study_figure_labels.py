"""A drop-height study of many runs writes the impact speed of a few runs, evenly spaced,
the first and last among them, and says so in its title (64 labels overlap into a smear)."""

from __future__ import annotations

import polars as pl
import pytest

from impactlab.analyze.report import figures


@pytest.mark.parametrize("runs", [5, 64])
def test_study_figure_labels_a_few_speeds(tmp_path, monkeypatch, runs):
    drawn = {}

    def keep(fig, path):
        drawn["fig"] = fig
        return path

    monkeypatch.setattr(figures, "save_figure", keep)
    heights = [0.1 + 0.01 * i for i in range(runs)]
    study = pl.DataFrame(
        {
            "drop_height_m": heights,
            "e_velocity_first": [0.8] * runs,
            "first_impact_speed_mps": [(2 * 9.81 * h) ** 0.5 for h in heights],
        }
    )
    figures.bounce_study_figure(study, "z", title="t", path=tmp_path / "s.png")
    ax = drawn["fig"].axes[0]
    labels = [t.get_text() for t in ax.texts]
    speeds = [f"{(2 * 9.81 * h) ** 0.5:.3g} m/s" for h in heights]
    if runs <= figures.MAX_SPEED_LABELS:
        assert labels == speeds
        assert ax.get_title().endswith("(grey: impact speed at the first contact)")
    else:
        assert len(labels) == figures.MAX_SPEED_LABELS
        assert labels[0] == speeds[0] and labels[-1] == speeds[-1]
        assert set(labels) <= set(speeds)
        assert f"{figures.MAX_SPEED_LABELS} of {runs} runs" in ax.get_title()
