"""The Markdown report: tables inline, figures linked relatively, answers from the data."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from impactlab.analyze.report import answers, findings
from impactlab.analyze.report.handout import as_written_section
from impactlab.analyze.report.headline import headline
from impactlab.analyze.tables.labels import run_labels, with_labels
from impactlab.text import md_code, md_link, md_text

METHOD = """\
- **Ground and heights** come from the model: the static geoms a body can land on (planes,
  boxes, meshes, ...) are the ground surfaces, and a body's height above a surface is its
  lowest point's, MuJoCo's own distance between the body's geoms and the surface (a sphere:
  centre minus radius above a plane). Apexes are the highest centre of each flight, refined
  ballistically, measured above the surface left and the one landed on; they are left empty
  for a body that turns in flight (its lowest point then moves relative to its centre).
- **Contacts** come from the contact channel: a body touches a surface (or another body) at a
  logged step when the log holds a contact message of one of their geom pairs; consecutive
  steps form a contact. A bounce needs a flight the log can show: released at v_out a body
  flies 2 v_out / g, so a release slower than v_min = 5 g x (time between logged steps),
  a flight of fewer than 10 logged steps, is merged with the next contact. At rest, sliding
  or rolling a contact flickers at micrometres per second (and a sliding ball hops by
  micrometres): that is one resting contact, not bounces. A contact still open at the end of
  the log is incomplete and not used for e.
- **Velocities in and out** are those of the contact point (v + w x r, from the logged linear
  and angular velocities) along the contact normal, at the moments the surfaces meet and
  part: the free flight from the last logged step before the contact (first after it) is
  extrapolated ballistically with the run's gravity and the body's rotation, so e and the
  impact speed do not depend on the logging rate. e = -v_out / v_in (for two bodies, relative
  normal velocities at the contact point; the 1D formulas only for central impacts).
- **Energy**: kinetic = translational + rotational (angular velocity rotated into the body frame
  with the logged quaternion, principal inertia from the log's metadata); potential =
  m g (height of the centre above its reference): the level of the surface the body lands on
  plus its rest height (its lowest possible centre height: a sphere's radius, a box's
  smallest half size), so a ball resting on the plane has zero potential energy; without a
  ground, potential is relative to each body's initial position. Flight phases are the logged
  steps outside every contact; a contact's loss is the energy at the last step before it
  minus that at the first step after, so initial - final energy = sum of losses - sum of
  flight drifts.
- **MuJoCo's own energy** (channel /energy) has its potential as m g z of the centre, so it is
  compared after subtracting sum(m g z_ref): `mujoco_diff_J`.
- **Impulse** is the sum over logged steps of the normal force times the logged step; peak force
  and penetration are maxima over logged steps (finer with `logging.every = 1`).
- **Collisions**: momentum change is |p' - p| / (|m1 v1| + |m2 v2|); the analytic outcome uses
  the 1D formulas with the measured e, e = 1 (elastic) and e = 0 (perfectly inelastic).
"""


RUNS = "`runs.parquet`"


def fmt(value: Any) -> str:
    """A table cell: floats to 4 significant digits, None as a dash, text as text
    (`md_text`: never markup, whatever a name holds)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value != value:
            return "-"
        return f"{value:.4g}"
    return md_text(value)


REPORT_ROWS = 500
"""Rows of a table, or sentences of a list, that the report shows. Beyond them it says how
many more there are and which file holds them all: the report of a sweep of 100,000 runs
stays one a person can read, and its size and the memory to write it do not grow with the
sweep."""


def md_table(frame: pl.DataFrame, columns: Sequence[str] | None = None, *, source: str) -> str:
    """A Markdown table of the given columns (those present): at most REPORT_ROWS rows, then
    a line saying how many more rows `source` (the file holding them all) has."""
    cols = [c for c in (columns or frame.columns) if c in frame.columns]
    if frame.is_empty() or not cols:
        return "_(no rows)_\n"
    lines = ["| " + " | ".join(md_text(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for row in frame.head(REPORT_ROWS).select(cols).iter_rows():
        lines.append("| " + " | ".join(fmt(v) for v in row) + " |")
    if frame.height > REPORT_ROWS:
        lines.append(
            f"\n_The first {REPORT_ROWS:,} of {frame.height:,} rows; all of them are in {source}._"
        )
    return "\n".join(lines) + "\n"


def bullets(sentences: Iterable[str], *, source: str, none: str) -> Iterator[str]:
    """The sentences as Markdown list items, at most REPORT_ROWS of them, then one saying how
    many more `source` (the file holding them all) has; `none` when there is no sentence."""
    n = 0
    for sentence in sentences:
        if n < REPORT_ROWS:
            yield f"- {sentence}"
        n += 1
    if not n:
        yield none
    elif n > REPORT_ROWS:
        yield f"- The first {REPORT_ROWS:,} of {n:,} are above; all of them are in {source}."


def image(path: Path, out_dir: Path, alt: str) -> str:
    """A Markdown image link relative to the report (its path URL-quoted)."""
    return f"![{md_text(alt)}]({md_link(path.relative_to(out_dir).as_posix())})\n"


def build_report(**parts: Any) -> str:
    """The report's Markdown text: `report_parts` (the same keywords) joined by newlines."""
    return "\n".join(report_parts(**parts))


def report_parts(
    *,
    out_dir: Path,
    runs: pl.DataFrame,
    bounces: pl.DataFrame,
    collisions: pl.DataFrame,
    phases: pl.DataFrame,
    studies: dict[str, pl.DataFrame],
    params: dict[str, list[str]],
    figures: dict[str, list[Path]],
    failed: Sequence[tuple[str, str]],
    energy_stride_note: str,
) -> Iterator[str]:
    """The report's Markdown, in pieces to be joined by newlines (or written one by one),
    made as they are read: the report of many runs is never held whole.

    Args:
        figures: keyed "energy", "decay", "restitution", "collision", "study".
        failed: (path, problem) of inputs that could not be analyzed.
    """
    labels = run_labels(runs)
    runs, bounces, collisions, phases = (
        with_labels(f, labels) for f in (runs, bounces, collisions, phases)
    )
    studies = {name: with_labels(s, labels) for name, s in studies.items()}
    yield "# Impact lab: analysis report\n"
    yield (
        f"{runs.height} run(s) analyzed from {runs['experiment'].n_unique()} experiment(s)"
        + (f"; {len(failed)} input(s) could not be read." if failed else ".")
        + " Units: SI (m, s, m/s, J, N, N s).\n"
    )
    if failed:
        yield "\n**Inputs not analyzed:**\n"
        yield from bullets(
            (f"{md_code(p)}: {md_text(why)}" for p, why in failed),
            source="`summary.json` (`failed`)",
            none="",
        )
        yield ""
    partial = runs.filter(pl.col("partial"))
    if partial.height:
        yield "\n**Partial logs** (damaged or incomplete; what could be read was analyzed):\n"
        yield from bullets(
            (
                f"{md_code(r)}: {md_text(why)}"
                for r, why in partial.select("run_id", "problems").iter_rows()
            ),
            source="`runs.parquet` (`partial`, `problems`)",
            none="",
        )
        yield ""
    yield from headline(
        out_dir=out_dir,
        runs=runs,
        bounces=bounces,
        collisions=collisions,
        studies=studies,
        params=params,
        figures=figures,
    )
    yield from as_written_section(runs, collisions)
    yield "\n## Runs\n"
    yield "Each run's label, and its run id (the log's name) for finding its files:\n"
    param_cols = sorted({p for ps in params.values() for p in ps})
    yield (
        md_table(
            runs,
            [
                "run",
                "run_id",
                *param_cols,
                "outcome",
                "partial",
                "duration_s",
                "n_bounces",
                "n_collisions",
                "note",
            ],
            source=RUNS,
        )
    )

    yield "\n## Step 1: energy\n"
    yield from bullets(
        answers.energy_answer(runs),
        source="`summary.json` (`answers.energy`)",
        none="- No run with a ground.",
    )
    gravity_runs = runs.filter(pl.col("ground"))
    if gravity_runs.height:
        yield "\nEnergy bookkeeping per run (J):\n"
        yield (
            md_table(
                gravity_runs,
                [
                    "run",
                    "energy_initial_J",
                    "energy_final_J",
                    "energy_loss_frac",
                    "contact_loss_sum_J",
                    "flight_drift_max_J",
                    "flight_drift_max_rel",
                    "mujoco_diff_max_J",
                ],
                source=RUNS,
            )
        )
        losses = phases.filter(
            (pl.col("kind") == "contact") & pl.col("run_id").is_in(gravity_runs["run_id"].implode())
        )
        if losses.height:
            yield "\nEnergy lost at each contact (J):\n"
            yield md_table(
                losses, ["run", "start_t_s", "end_t_s", "loss_J", "open"], source="`phases.parquet`"
            )
    yield (
        "\n`mujoco_diff_max_J` is the largest |MuJoCo total (shifted by the reference) - our "
        "total| over the run: MuJoCo's own energy (its `e_kinetic` and `e_potential` sensors) "
        "against the energy computed here from the logged states.\n"
    )
    yield from [image(p, out_dir, "energy") for p in figures.get("energy", [])]

    yield "\n## Step 2: restitution\n"
    yield "**Is e constant across bounces?**\n"
    yield from bullets(
        answers.constancy_answer(runs, bounces),
        source="`summary.json` (`answers.e_constant_across_bounces`)",
        none="- No bounce data.",
    )
    yield "\n**Does e depend on the drop height (impact velocity)?**\n"
    yield from bullets(
        answers.height_answer(studies),
        source="`summary.json` (`answers.e_against_drop_height`)",
        none="- No drop-height study.",
    )
    if bounces.height:
        yield "\nBounces (heights: the body's lowest point above the surface):\n"
        yield (
            md_table(
                bounces,
                [
                    "run",
                    "body",
                    "surface",
                    "bounce",
                    "impact_t_s",
                    "duration_s",
                    "v_in_mps",
                    "v_out_mps",
                    "e_velocity",
                    "apex_before_m",
                    "apex_m",
                    "apex_predicted_m",
                    "e_apex",
                    "peak_force_N",
                    "impulse_Ns",
                    "max_penetration_m",
                    "note",
                ],
                source="`bounces.parquet`",
            )
        )
    yield from [image(p, out_dir, "bounce decay") for p in figures.get("decay", [])]
    yield from [image(p, out_dir, "e against impact speed") for p in figures.get("restitution", [])]

    yield "\n## Step 3: collision\n"
    yield from bullets(
        answers.collision_answer(collisions, runs),
        source="`summary.json` (`answers.collision`)",
        none="- No two-body run.",
    )
    if collisions.height:
        yield "\nCollisions (contact-point velocities along the contact normal, m/s):\n"
        yield (
            md_table(
                collisions,
                [
                    "run",
                    "v1n_before_mps",
                    "v2n_before_mps",
                    "v1n_after_mps",
                    "v2n_after_mps",
                    "e_velocity",
                    "momentum_rel_change",
                    "ke_before_J",
                    "ke_after_J",
                    "ke_loss_frac",
                    "ke_loss_predicted_J",
                    "v1n_after_elastic_mps",
                    "v2n_after_elastic_mps",
                    "v_after_inelastic_mps",
                    "note",
                ],
                source="`collisions.parquet`",
            )
        )
    yield from [image(p, out_dir, "collision") for p in figures.get("collision", [])]

    yield "\n## Step 4: parameter studies\n"
    yield from bullets(
        answers.study_answer(studies, params),
        source="`summary.json` (`answers.parameter_study`)",
        none="- No collision sweep.",
    )
    for name, study in studies.items():
        swept = ", ".join(md_text(p) for p in params.get(name, []))
        yield f"\n{md_code(name)} (swept: {swept}):\n"
        table = study.drop("partial", "note", "run_id", strict=False)
        yield md_table(table, source="`summary.json` (`studies`)")
    yield from [image(p, out_dir, "study") for p in figures.get("study", [])]

    yield "\n## Method\n"
    yield METHOD
    yield f"- {findings.method_line()}"
    yield f"- {energy_stride_note}\n"
    yield (
        "\n## Files\n\n- `runs.parquet`: one row per run (parameters, state of the log, results)"
        "\n- `bounces.parquet`, `collisions.parquet`, `energy.parquet`, `phases.parquet`"
        "\n- `summary.json`: the runs, the studies and the answers\n- `figures/`\n"
    )
