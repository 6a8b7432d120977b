"""The main job's report: what was recorded, cloned, tested, fine-tuned, and how it went.

Written by ``recipes/pipeline.py`` as ``report.md`` and ``report.html`` in its run
directory; every figure and video is linked by its path relative to that directory.
"""

from __future__ import annotations

import json
from pathlib import Path

from pilerl.data import EpisodeStore
from pilerl.evaluation.metrics import wilson_interval
from pilerl.layout import RunLayout

from . import paper_numbers
from .document import Report
from .paper import FAILURE_LABELS, add_controller_figures


def _rate(row: dict) -> str:
    return (
        f"{100 * row['success_rate']:.0f}% ({row['successes']}/{row['episodes']}, "
        f"{100 * row['success_low']:.0f}–{100 * row['success_high']:.0f}%)"
    )


def _failures(row: dict) -> str:
    modes = row.get("failure_modes", {})
    return ", ".join(f"{FAILURE_LABELS.get(m, m)} {n}" for m, n in modes.items() if n) or "–"


def sensor_set_name(s: list[str], s_prime: list[str] | None) -> str:
    """The ``conf/sensors`` name of a sensor set (as the paper's tables name them)."""
    if s_prime:
        return "s_pt_sprime"
    return "s_pt" if "telescope_pressure" in s else "s"


def write_pipeline_report(
    config,
    out: Path,
    *,
    summer: EpisodeStore,
    winter: EpisodeStore,
    dataset: EpisodeStore,
    before: dict[str, dict],
    after: dict[str, dict],
) -> Path:
    """``report.md`` and ``report.html`` in ``out``; returns the Markdown path."""
    policy = config.policy.name
    report = Report(f"pilerl main job: {policy} from demonstrations to RL")
    report.paragraph(
        "Scripted demonstrations → D_II → behaviour cloning → closed-loop evaluation → "
        "RL fine-tuning → closed-loop evaluation on the same seeded starts. Success: the "
        "bucket ends at least half full (the paper's rule); rates with 95% Wilson intervals."
    )

    report.heading("Demonstrations")
    rows = []
    for name, store in (("summer (training)", summer), ("winter_c (validation)", winter)):
        successes = sum(m.success for m in store.episodes)
        rows.append([name, len(store), successes, store.n_samples])
    rows.append(["D_II (successful summer)", len(dataset), len(dataset), dataset.n_samples])
    report.table(["set", "episodes", "successful", "samples"], rows)
    report.paragraph(
        f"Recorded at {config.demos.record_hz:g} Hz, seed {config.demos.seed}, by the "
        "simulator's scripted expert (one operator style per episode); mistake rate "
        f"{config.demos.mistake_rate:g} (operators who lift on a false impact cue or "
        "under-fill). Winter demonstrations use the telescope-pressure cue (operators who "
        "feel the contact)."
    )

    report.heading("Behaviour cloning")
    report.paragraph(
        f"{policy} with s = {config.sensors.s}"
        + (f", s′ = {config.sensors.s_prime}" if config.sensors.s_prime else "")
        + f"; {config.bc.gradient_steps} gradient steps of {config.bc.batch_size}, RAdam "
        f"lr {config.bc.learning_rate:g}, seed {config.bc.seed}; the cloned controller is "
        + cloned_text(config, out)
    )
    report.image("bc/losses.png", "Training and validation loss")

    report.heading("Closed loop: cloned vs fine-tuned")
    report.paragraph(
        f"{config.evaluation.episodes} episodes per condition, evaluation seed "
        f"{config.evaluation.seed} (starts differ from the demonstrations'); the same starts "
        "for both controllers."
    )
    report.table(
        ["condition", "cloned", "fine-tuned", "cloned failures", "fine-tuned failures"],
        [
            [
                name,
                _rate(before[name]),
                _rate(after[name]),
                _failures(before[name]),
                _failures(after[name]),
            ]
            for name in before
        ],
    )
    report.image("evaluation/cloned/success.png", "Cloned controller: success per condition")
    report.image("evaluation/finetuned/success.png", "Fine-tuned: success per condition")
    report.image("evaluation/finetuned/fill.png", "Fine-tuned: fill fraction per episode")

    report.heading("RL fine-tuning")
    results_file = RunLayout(out).sub("finetune").results
    if results_file.exists():
        results = json.loads(results_file.read_text())
        fps = results.get("collection_fps")
        report.paragraph(
            f"{results['algorithm']} for {results['frames']} frames in "
            f"{results['wall_s'] / 60:.1f} min wall ("
            + (f"{fps:.0f} frames/s while collecting; " if fps else "")
            + f"curriculum {config.finetune.curriculum.name}, budget "
            f"{config.finetune.time_budget_minutes:g} min). The issue's full-budget run: "
            "docs/results/finetune."
        )
        cross_check_table(report, results, config.finetune.evaluation.final_episodes)
    if (out / "finetune" / "success_curve.png").exists():
        report.image("finetune/success_curve.png", "Success during fine-tuning")

    add_controller_figures(
        report,
        out,
        actors={
            "cloned": Path(config.finetune.checkpoint),  # the one bc.selection chose
            "fine-tuned": RunLayout(out).sub("finetune").best_actor,
        },
        demos=Path(winter.root),
        episodes=len(winter),
        control_hz=config.env.control_hz,
    )

    videos = sorted((out / "evaluation" / "finetuned" / "videos").glob("*.mp4"))
    report.heading("Videos (fine-tuned)")
    if videos:
        report.bullets([f"[{v.name}]({v.relative_to(out)})" for v in videos])
    else:
        report.paragraph(
            "No videos: they were switched off, or this machine cannot render offscreen "
            "(the run's log says which)."
        )

    report.heading("Against the paper")
    key = (policy, sensor_set_name(config.sensors.s, config.sensors.s_prime), "d_ii", "winter")
    paper = {**paper_numbers.TABLE_III, **paper_numbers.TABLE_IV}.get(key)
    winter_row = before.get("winter")
    if paper is not None and winter_row is not None:
        low, high = wilson_interval(winter_row["successes"], winter_row["episodes"])
        inside = low <= paper / 100 <= high
        report.paragraph(
            f"The paper reports {paper}% winter success for {policy} with these sensors "
            f"trained on D_II; the cloned controller here: {_rate(winter_row)}. "
            + (
                "The paper's number lies inside the interval."
                if inside
                else "The paper's number lies outside the interval: the simulation disagrees "
                "(see docs/results/paper for all experiments and the reasons known)."
            )
        )
    else:
        report.paragraph("The paper has no winter number for this controller and sensor set.")
    markdown, _ = report.write(out)
    return markdown


def _rate_and_fill(row: dict) -> str:
    return f"{_rate(row)}, fill {row['fill_mean']:.2f}"


def cross_check_table(report: Report, results: dict, episodes: int) -> None:
    """The fine-tune's before / after (``best.pt``) per evaluation group, on the training
    simulator and on the cross-check's options (``finetune.evaluation.cross_check_env``),
    if the run had one; ``episodes``: its episodes per condition."""
    cross = results.get("cross_check")
    if not cross:
        return
    report.paragraph(
        "Does the gain carry over? The fine-tune's own before / after evaluation "
        f"({episodes} episodes per condition, the same starts for both controllers), "
        "repeated with the simulator options "
        f"`{json.dumps(cross['env'])}` (finetune.evaluation.cross_check_env). A gain that "
        "shows only on the training options was learned from how the simulator models the "
        "task, not from the task (docs/finetuning.md)."
    )
    report.table(
        ["group", "cloned", "fine-tuned", "cloned, cross-check", "fine-tuned, cross-check"],
        [
            [
                group,
                _rate_and_fill(results["before"][group]),
                _rate_and_fill(results["after_best"][group]),
                _rate_and_fill(cross["before"][group]),
                _rate_and_fill(cross["after_best"][group]),
            ]
            for group in results["before"]
        ],
    )
    report.paragraph(
        "Success counts scoops at least half full; on the cross-check's soil even the scripted "
        'expert rarely gets there (docs/soil_models.md, "The scripted expert on the mouth '
        'intake"), so compare the mean fill too.'
    )


def cloned_text(config, out: Path) -> str:
    """Which weights the report calls the cloned controller (``finetune.checkpoint``: the
    file evaluated as cloned and fine-tuned)."""
    chosen = Path(config.finetune.checkpoint)
    if chosen.resolve() != (out / "bc" / f"{config.bc.selection}.pt").resolve():
        return f"{chosen} (set by finetune.checkpoint, not this run's BC step)."
    if config.bc.selection == "final":
        return (
            "final.pt, the weights after the whole budget (the winter validation loss is "
            "plotted, not used to choose)."
        )
    return "best.pt, the epoch with the lowest validation loss on the winter demonstrations."
