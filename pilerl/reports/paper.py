"""The paper's experiments reproduced in simulation: one report, Markdown and HTML.

    python -m pilerl.reports.paper \\
        --exp1 multirun/exp1_summer_to_winter --exp2 multirun/exp2_data_and_pt \\
        --exp3 multirun/exp3_attention --exp4 multirun/exp4_offline_validation \\
        --cross-soil multirun/cross_soil_heightfield multirun/cross_soil_particles \\
        --figure-actor DANNet=<job>/best.pt --figure-demos data/demos/winter_c_validation \\
        --out docs/results/paper

Every closed-loop cell puts the paper's success rate beside the simulated one (successes /
episodes pooled over the training seeds, the 95% Wilson interval and the seed spread) and
says whether the paper's number lies inside the interval. Every trained controller gets a
row over every tested condition. Each experiment's claims from the paper are then checked
on the simulated numbers by seed-aware tests (``comparisons``: a paired test over seeds and
starts for "A beats B") and stated as holding or not. ``--cross-soil`` adds the held-out
conditions and the two soil models' rank agreement (``cross_soil``). Any experiment may be
left out; jobs that have not finished are listed, not guessed.

The paper's tables and claims are data in ``paper_numbers``; this module checks the claims
(``check_claim``) and writes the report's sections.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pilerl.figures import legend_outside, plt, save_figure
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator

from . import paper_numbers
from .comparisons import compare, seed_spread_text, threshold
from .document import Report
from .paper_numbers import Claim, Key
from .results import (
    Cell,
    LossCurves,
    closed_loop_cells,
    offline_validation_curves,
    unfinished_ensemble_jobs,
)
from .stats import welch_less_p

SENSOR_LABELS = {"s": "θ1, θ2, p_d", "s_pt": "+ p_t", "s_pt_sprime": "+ p_t, s′"}
CONTROLLER_LABELS = {
    "nnet": "NNet",
    "rf": "RF",
    "nnetv2": "NNetV2",
    "annet": "ANNet",
    "dannet": "DANNet",
}
DATASET_LABELS = {"d_i": "D_I", "d_ii": "D_II"}
LOSS_CLAIM_ALPHA = 0.05  # an Exp. 4 loss claim holds for a pair when Welch's p is below this


def controller_text(controller: str) -> str:
    """A controller's name in the report: ``dannet`` -> DANNet, a fine-tuned
    ``dannet+ppo`` (``cross_soil.controller_of``) -> DANNet + PPO."""
    cloned, _, algorithm = controller.partition("+")
    label = CONTROLLER_LABELS.get(cloned, cloned)
    return f"{label} + {algorithm.upper()}" if algorithm else label


def _percent(x: float) -> str:
    return f"{100 * x:.0f}%"


def _controller_label(controller: str, sensors: str) -> str:
    return f"{controller_text(controller)} [{SENSOR_LABELS.get(sensors, sensors)}]"


def _label(key: Key) -> str:
    controller, sensors, dataset, test = key
    dataset = DATASET_LABELS.get(dataset, dataset)
    return f"{_controller_label(controller, sensors)} {dataset} → {test}"


def cell_verdict(paper_percent: float, cell: Cell) -> str:
    """``agrees`` if the paper's rate lies in the simulated 95% interval, else which way."""
    low, high = cell.interval
    if low <= paper_percent / 100 <= high:
        return "agrees"
    return "sim higher" if cell.rate > paper_percent / 100 else "sim lower"


def same_side_of_half(paper_percent: float, cell: Cell) -> bool:
    """Whether the paper's rate and the simulated one are on the same side of 50%."""
    return (paper_percent >= 50) == (cell.rate >= 0.5)


def comparison_rows(paper: dict[Key, int], cells: dict[Key, Cell]) -> list[list[str]]:
    """One row per paper cell: paper, simulated rate, n, interval, verdict, failures and
    the training seeds with the spread of their own rates."""
    rows = []
    for key, paper_percent in paper.items():
        controller, sensors, dataset, test = key
        row = [
            controller_text(controller),
            SENSOR_LABELS.get(sensors, sensors),
            DATASET_LABELS.get(dataset, dataset),
            test,
            f"{paper_percent}%",
        ]
        cell = cells.get(key)
        if cell is None:
            rows.append(row + ["not run", "", "", "", "", "", ""])
            continue
        low, high = cell.interval
        rows.append(
            row
            + [
                _percent(cell.rate),
                f"{cell.successes}/{cell.episodes}",
                f"{_percent(low)}–{_percent(high)}",
                cell_verdict(paper_percent, cell),
                _failures(cell),
                "yes" if same_side_of_half(paper_percent, cell) else "no",
                seed_spread_text(cell),
            ]
        )
    return rows


FAILURE_LABELS = {
    "early_boom_rise": "early lift",
    "no_boom_rise": "no lift",
    "underfilled": "underfilled",
    "unfinished": "not finished in time",
    "tipped": "tipped",
}


def _failures(cell: Cell) -> str:
    """The failed episodes by failure mode (``pilerl.evaluation.evaluator.failure_mode``)."""
    parts = [f"{FAILURE_LABELS.get(m, m)} {n}" for m, n in cell.failure_modes.items() if n]
    return ", ".join(parts) if parts else ("–" if cell.failure_modes else "not recorded")


COMPARISON_HEADER = [
    "controller",
    "inputs",
    "data",
    "test",
    "paper",
    "simulation",
    "successes",
    "95% CI",
    "paper in CI?",
    "failures",
    "same side of 50%?",
    "seed spread (min–max)",
]


def plot_comparison(paper: dict[Key, int], cells: dict[Key, Cell], path: Path, title: str):
    """Simulated success with 95% intervals (bars) and the paper's rate (black diamonds)."""
    keys = [k for k in paper if k in cells]
    if not keys:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 0.9 + 0.32 * len(keys)))
    y = np.arange(len(keys))[::-1]
    rates = np.array([cells[k].rate for k in keys])
    low = rates - np.array([cells[k].interval[0] for k in keys])
    high = np.array([cells[k].interval[1] for k in keys]) - rates
    ax.barh(y, 100 * rates, xerr=100 * np.vstack([low, high]), capsize=3, label="simulation")
    ax.scatter([paper[k] for k in keys], y, marker="D", color="k", zorder=3, label="paper")
    ax.set_yticks(y, [_label(k) for k in keys], fontsize=8)
    ax.set_xlim(0, 105)
    ax.set_xlabel("success rate [%] (95% Wilson interval)")
    ax.set_title(title)
    legend_outside(ax, fontsize=8)
    return save_figure(fig, path)


# --- the paper's claims, each checked on the simulated cells -------------------------------


def _rate_text(key: Key, cell: Cell) -> str:
    low, high = cell.interval
    return (
        f"{_label(key)} {_percent(cell.rate)} (CI {_percent(low)}–{_percent(high)}, "
        f"seeds {seed_spread_text(cell)})"
    )


def _better(cells: dict[Key, Cell], a: Key, b: Key) -> tuple[bool | None, str]:
    """Does a beat b? Holds when the seed-aware test (``comparisons.compare``) says so."""
    if a not in cells or b not in cells:
        return None, "not run"
    test = compare(cells[a], cells[b])
    evidence = f"{_rate_text(a, cells[a])} vs {_rate_text(b, cells[b])}: {test.describe()}"
    return test.significant, evidence


def check_claim(claim: Claim, cells: dict[Key, Cell]) -> list[tuple[bool | None, str]]:
    """The claim checked on each of its cells or pairs: (holds?, evidence); None: not run.

    A pair holds when A beats B in the paired test over seeds and starts (p < 0.05); a
    cell holds when its 95% interval and every seed's rate are on the claimed side of the
    threshold (``comparisons``).
    """
    if claim.higher:
        return [_better(cells, a, b) for a, b in claim.higher]
    results = []
    for key in claim.each:
        if key not in cells:
            results.append((None, "not run"))
            continue
        check = threshold(cells[key], below=claim.below, at_least=claim.at_least)
        side = (
            f"below {_percent(claim.below)}"
            if claim.below is not None
            else (f"at least {_percent(claim.at_least)}")
        )
        reasons = []
        if not check.interval_side:
            reasons.append(f"interval not {side}")
        if check.seeds_against:
            reasons.append(f"{check.seeds_against} seed(s) not {side}")
        note = "; ".join(reasons) if reasons else f"interval and every seed {side}"
        results.append((check.holds, f"{_rate_text(key, cells[key])}: {note}"))
    return results


def verdict(results: list[bool | None]) -> str:
    """A claim checked on several cells (``None``: a cell not run)."""
    known = [ok for ok in results if ok is not None]
    if not known:
        return "not run"
    if all(known) and len(known) == len(results):
        return "holds"
    return "holds in part" if any(known) else "does not hold"


def claim_rows(claims: Sequence[Claim], cells: dict[Key, Cell]) -> list[list[str]]:
    """One row per claim: the statement, its verdict in simulation, the evidence."""
    rows = []
    for claim in claims:
        results = check_claim(claim, cells)
        evidence = "; ".join(text for _, text in results)
        rows.append([claim.statement, verdict([ok for ok, _ in results]), evidence])
    return rows


# --- every controller in every tested condition ------------------------------------------


def test_order(tests: set[str], simulator: str = DEFAULT_SIMULATOR) -> list[str]:
    """The tests in the simulator's order: its conditions as declared, then its groups."""
    plugin = get_simulator(simulator)
    ordered = [c for c in plugin.conditions if c in tests]
    ordered += [g for g in plugin.condition_groups if g in tests]
    return ordered + sorted(tests - set(ordered))


def rate_with_spread(cell: Cell) -> str:
    """``"47% [20–70%]"``: the pooled rate and the per-seed range (one seed: no range)."""
    spread = cell.seed_spread
    if spread is None or len(cell.seed_rates) < 2:
        return _percent(cell.rate)
    return f"{_percent(cell.rate)} [{_percent(spread[0])}–{_percent(spread[1])}]"


def condition_rows(
    cells: dict[Key, Cell], simulator: str = DEFAULT_SIMULATOR
) -> tuple[list[str], list[list[str]]]:
    """One row per trained controller (controller, inputs, data), one column per tested
    condition and pooled group (summer, each winter day, each held-out condition, ...)."""
    controllers = sorted({key[:3] for key in cells})
    tests = test_order({key[3] for key in cells}, simulator)
    header = ["controller", "inputs", "data", "seeds", *tests]
    rows = []
    for controller, sensors, dataset in controllers:
        seeds = max(c.seeds for k, c in cells.items() if k[:3] == (controller, sensors, dataset))
        row = [
            controller_text(controller),
            SENSOR_LABELS.get(sensors, sensors),
            DATASET_LABELS.get(dataset, dataset),
            str(seeds),
        ]
        for test in tests:
            cell = cells.get((controller, sensors, dataset, test))
            row.append("–" if cell is None else rate_with_spread(cell))
        rows.append(row)
    return header, rows


# --- the report ----------------------------------------------------------------------------


def add_closed_loop_experiment(
    report: Report,
    *,
    title: str,
    sweep_dir: Path,
    paper: dict[Key, int],
    claims: Sequence[Claim],
    out_dir: Path,
    figure: str,
) -> dict[Key, Cell]:
    cells, finished, unfinished = closed_loop_cells(sweep_dir)
    report.heading(title)
    setups = {
        (
            j.config["gradient_steps"],
            j.config["epochs"],
            j.config["evaluation"]["episodes"],
            tuple(j.config["evaluation"]["conditions"]),
            j.config["evaluation"]["seed"],
        )
        for j in finished
    }
    seeds = sorted({j.seed for j in finished})
    for steps, epochs, episodes, conditions, eval_seed in sorted(setups, key=str):
        budget = f"{steps} gradient steps" if steps else f"{epochs} epochs"
        report.paragraph(
            f"Sweep `{sweep_dir}`: {len(finished)} finished jobs, training seeds {seeds}, "
            f"{budget} (Levenberg-Marquardt: {epochs} rounds; RF: one fit), closed loop "
            f"{episodes} episodes per condition in {', '.join(conditions)} (evaluation seed "
            f"{eval_seed}; winter = the winter conditions pooled)."
        )
    if unfinished:
        report.paragraph(
            "Unfinished jobs (no closed-loop result, left out): "
            + ", ".join(str(j.path) for j in unfinished)
        )
    report.table(COMPARISON_HEADER, comparison_rows(paper, cells))
    simulator = (finished[0].config.get("env") or {}).get("simulator") if finished else None
    header, rows = condition_rows(cells, simulator or DEFAULT_SIMULATOR)
    if rows:
        report.paragraph(
            "Every trained controller in every tested condition: success pooled over the "
            "training seeds [lowest–highest seed]."
        )
        report.table(header, rows)
    if plot_comparison(paper, cells, out_dir / figure, title):
        report.image(figure, f"{title}: simulation (bars, 95% CI) vs the paper (diamonds)")
    report.paragraph("The paper's claims, checked on the simulated numbers:")
    report.table(["claim", "in simulation", "evidence"], claim_rows(claims, cells))
    return cells


def add_offline_validation(report: Report, sweep_dir: Path, out_dir: Path) -> None:
    curves = offline_validation_curves(sweep_dir)
    report.heading("Exp. 4: offline validation on winter demonstrations (Fig. 4)")
    if not curves:
        report.paragraph(f"`{sweep_dir}`: no finished ensemble jobs.")
        return
    datasets = sorted({c.dataset for c in curves}, reverse=True)
    fig, axes = plt.subplots(1, len(datasets), figsize=(5 * len(datasets), 3.4), squeeze=False)
    for ax, dataset in zip(axes[0], datasets, strict=True):
        for c in (c for c in curves if c.dataset == dataset):
            label = _controller_label(c.controller, c.sensors)
            x = c.epoch * c.steps_per_epoch if c.steps_per_epoch else c.epoch
            ax.plot(x, c.validation_mean, "o-" if len(x) < 10 else "-", ms=4, label=label)
            ax.fill_between(
                x,
                c.validation_mean - c.validation_std,
                c.validation_mean + c.validation_std,
                alpha=0.2,
            )
        ax.set_title(f"trained on {DATASET_LABELS.get(dataset, dataset)}")
        steps = all(c.steps_per_epoch for c in curves)
        ax.set_xlabel("gradient steps" if steps else "epoch")
        ax.set_ylabel("validation MSE (winter demos)")
        legend_outside(ax)
    save_figure(fig, out_dir / "exp4_validation_loss.png")
    rows = []
    final = {}  # (controller, sensors, dataset) -> (mean, sample std over seeds, seeds)
    for c in curves:
        final[(c.controller, c.sensors, c.dataset)] = final_validation_loss(c)
        rows.append(
            [
                controller_text(c.controller),
                SENSOR_LABELS.get(c.sensors, c.sensors),
                DATASET_LABELS.get(c.dataset, c.dataset),
                c.seeds,
                len(c.epoch),
                f"{c.validation_mean[-1]:.4f} ± {c.validation_std[-1]:.4f}",
                f"{c.validation_mean.min():.4f}",
            ]
        )
    report.paragraph(f"Sweep `{sweep_dir}`: mean ± std over seeds of the validation MSE.")
    unfinished = unfinished_ensemble_jobs(sweep_dir)
    if unfinished:
        report.paragraph(
            "Unfinished jobs (no loss curves yet, left out): "
            + ", ".join(str(job) for job in unfinished)
        )
    report.table(
        ["controller", "inputs", "data", "seeds", "epochs", "final loss", "lowest mean"], rows
    )
    report.image("exp4_validation_loss.png", "Validation loss, mean ± std over seeds")
    report.paragraph(
        "A loss claim holds for a pair when the group the paper calls lower (D_I; the "
        "attention network) has the lower final validation loss by Welch's one-sided "
        f"t-test over the seeds, p < {LOSS_CLAIM_ALPHA}."
    )
    claims = []
    pairs = [
        (k, (k[0], k[1], "d_i")) for k in final if k[2] == "d_ii" and (k[0], k[1], "d_i") in final
    ]
    if pairs:
        tests = [lower_loss(final[b], final[a]) for a, b in pairs]
        claims.append(
            [
                paper_numbers.MORE_DATA_LOSS_CLAIM,
                verdict([ok for ok, _ in tests]),
                "; ".join(
                    f"{a[0]}: D_I {loss_text(final[b])} vs D_II {loss_text(final[a])}, {p}"
                    for (a, b), (_, p) in zip(pairs, tests, strict=True)
                ),
            ]
        )
    attention = [
        (k, ("nnetv2", k[1], k[2]))
        for k in final
        if k[0] in ("annet", "dannet") and ("nnetv2", k[1], k[2]) in final
    ]
    if attention:
        tests = [lower_loss(final[a], final[b]) for a, b in attention]
        claims.append(
            [
                paper_numbers.ATTENTION_LOSS_CLAIM,
                verdict([ok for ok, _ in tests]),
                "; ".join(
                    f"{a[0]} {a[2]} {loss_text(final[a])} vs NNetV2 {loss_text(final[b])}, {p}"
                    for (a, b), (_, p) in zip(attention, tests, strict=True)
                ),
            ]
        )
    if claims:
        report.table(["claim", "in simulation", "evidence"], claims)


def final_validation_loss(curves: LossCurves) -> tuple[float, float, int]:
    """An ensemble's last-epoch validation loss: mean, sample std over its seeds (the
    curves record numpy's population std, ddof = 0) and the number of seeds."""
    n = int(curves.seeds)
    spread = float(curves.validation_std[-1])
    sample_std = spread * math.sqrt(n / (n - 1)) if n > 1 else math.nan
    return float(curves.validation_mean[-1]), sample_std, n


def lower_loss(a: tuple[float, float, int], b: tuple[float, float, int]) -> tuple[bool | None, str]:
    """Whether loss ``a`` is below ``b`` (``final_validation_loss``'s tuples) by Welch's
    one-sided test over the seeds (``None``: a group of one seed, not tested), and the
    p-value as text."""
    if a[2] < 2 or b[2] < 2:
        return None, "one seed: not tested"
    p = welch_less_p(a[0], a[1], a[2], b[0], b[1], b[2])
    return p < LOSS_CLAIM_ALPHA, f"p = {p:.2g}"


def loss_text(loss: tuple[float, float, int]) -> str:
    """A final validation loss and its number of seeds, for a claim's evidence."""
    return f"{loss[0]:.4f} ({loss[2]} seeds)"


def add_controller_figures(
    report: Report,
    out_dir: Path,
    *,
    actors: dict[str, Path],
    demos: Path,
    episodes: int = 10,
    control_hz: float = 20.0,
) -> None:
    """Fig. 3 (controls vs a demonstration) and Fig. 5 (attention per scoop phase).

    The demonstrations are down-sampled to the controllers' rate ``control_hz``; the
    controllers read the demonstrations' own readings (open loop, as the validation loss).
    """
    from pilerl.data import EpisodeStore, downsample_episode
    from pilerl.evaluation.attention_masks import phase_masks, plot_attention_masks
    from pilerl.evaluation.control_signals import compare_controls, plot_control_signals
    from pilerl.policies import load_actor
    from pilerl.policies.registry import get_spec

    store = EpisodeStore.open(demos)
    metas = store.episodes[:episodes]
    demonstrations = [
        downsample_episode(store.load(m.id), max(1, round(m.rate_hz / control_hz))) for m in metas
    ]
    loaded = {name: load_actor(path) for name, path in actors.items()}
    report.heading("Controllers against a demonstration (Fig. 3)")
    # the reference: the first successful demonstration; a failed one is said to be one
    reference = next((i for i, m in enumerate(metas) if m.success), 0)
    chosen = metas[reference]
    if chosen.success:
        outcome = f"successful, fill {chosen.fill_fraction:.2f}"
    elif chosen.success is None:
        outcome = "outcome not recorded"
    else:
        outcome = (
            f"FAILED (fill {chosen.fill_fraction:.2f}): none of the first {len(metas)} succeeded"
        )
    comparison = compare_controls(demonstrations[reference], loaded, controls=store.controls)
    plot_control_signals(
        comparison,
        out_dir / "fig3_control_signals.png",
        title=f"{Path(demos).name} episode {chosen.id} ({outcome.split(':')[0]})",
    )
    report.paragraph(
        f"Demonstration {chosen.id} of `{demos}` ({store.description}; {outcome}), "
        f"down-sampled to {control_hz:g} Hz; each controller reads the demonstration's own "
        "readings. Checkpoints: " + ", ".join(f"{n} = `{p}`" for n, p in actors.items()) + "."
    )
    report.table(
        ["controller", *comparison.controls, "all"],
        [
            [name, *(f"{mse[c]:.4f}" for c in comparison.controls), f"{mse['all']:.4f}"]
            for name, mse in comparison.mse.items()
        ],
    )
    report.image("fig3_control_signals.png", "Controls over time: demonstration vs controllers")
    for name, actor in loaded.items():
        controller = actors[name]
        if not get_spec(_controller_name(actor)).uses_attention:
            continue
        masks = phase_masks(actor, demonstrations, controls=store.controls)
        figure = f"fig5_attention_{name}.png"
        plot_attention_masks(masks, out_dir / figure, title=f"{name}: {controller}")
        report.heading(f"Attention of {name} over the phases of a scoop (Fig. 5)")
        report.paragraph(
            f"Mean masks per phase over {len(demonstrations)} demonstrations of `{demos}`. "
            "Phases from the scripted operator: approach; impact = the first 0.5 s after "
            "its impact cue; filling = the rest of its fill; finished = its finish."
        )
        for title, table in (
            ("input mask", masks.input_table()),
            ("output mask", masks.output_table()),
        ):
            if table is None:
                continue
            columns = list(next(iter(table.values())))
            report.paragraph(f"{name} {title} (mean weight per phase):")
            report.table(
                ["phase", *columns],
                [[phase, *(f"{row[c]:.2f}" for c in columns)] for phase, row in table.items()],
            )
        report.image(figure, f"{name}: attention masks per phase and over one demonstration")


def _controller_name(actor) -> str:
    from pilerl.policies import actor_policy

    return actor_policy(actor).config.controller


def add_cross_soil(report: Report, sweep_dirs: Sequence[Path]) -> None:
    """Held-out conditions and the cross-soil check, from evaluate sweeps over checkpoints
    and soils: every controller's row per soil (summer, each winter day, each held-out
    condition), then Kendall's tau over the controllers and the gap per one."""
    from .cross_soil import EVERY_CONDITION, GAP_TARGET, TAU_TARGET, soil_agreement, soil_cells

    cells = soil_cells(sweep_dirs)
    report.heading("Held-out conditions and the cross-soil check")
    soils = sorted(cells.by_soil)
    report.paragraph(
        f"Sweep{'s' if len(sweep_dirs) > 1 else ''} "
        f"{', '.join(f'`{d}`' for d in sweep_dirs)}: {len(cells.finished)} finished "
        f"evaluation jobs on the soil models {', '.join(soils) or 'none'}; every "
        "controller's training seeds pooled [lowest–highest seed]. 'every condition' pools "
        "the conditions every job evaluated: "
        f"{', '.join(cells.pooled_conditions) or 'none (so no such column)'}."
    )
    if cells.unfinished:
        report.paragraph(
            "Unfinished jobs (left out): " + ", ".join(str(p) for p in cells.unfinished)
        )
    for soil in soils:
        header, rows = condition_rows(cells.by_soil[soil])
        report.paragraph(f"Soil model `{soil}`:")
        report.table(header, rows)
    if len(soils) < 2:
        report.paragraph("One soil model only: no cross-soil comparison.")
        return
    pair = (
        (soils[0], soils[1])
        if "heightfield" not in soils
        else (
            "heightfield",
            next(s for s in soils if s != "heightfield"),
        )
    )
    shared = set.intersection(*({k[3] for k in cells.by_soil[s]} for s in pair))
    agreements, not_compared = [], []
    for test in [EVERY_CONDITION, *test_order(shared - {EVERY_CONDITION})]:
        reason = cells.comparable(pair, test)
        if reason is not None:
            not_compared.append(reason)
            continue
        try:
            agreements.append(soil_agreement(cells, pair, test))
        except ValueError:
            continue  # fewer than two controllers on both soils
    if not_compared:
        report.paragraph("Not compared: " + "; ".join(not_compared) + ".")
    if not agreements:
        report.paragraph("Fewer than two controllers on both soils: no rank agreement.")
        return
    report.paragraph(
        f"Rank agreement of {pair[0]} and {pair[1]} over the controllers (Kendall's τ-b) and "
        f"the largest success gap; target τ ≥ {TAU_TARGET} and every gap within "
        f"{100 * GAP_TARGET:.0f} points. 'τ over mean fill' ranks the controllers by their "
        "mean bucket fill instead (a graded view where success is mostly 0 or 1 on a soil; "
        "not the issue's target)."
    )
    report.table(
        ["test", "controllers", "Kendall's τ", "largest gap", "target met?", "τ over mean fill"],
        [
            [
                a.test,
                len(a.controllers),
                a.tau_text,
                f"{100 * max(abs(g) for g in a.gaps):.0f} points",
                a.target_text,
                "–" if math.isnan(a.fill_tau) else f"{a.fill_tau:.2f}",
            ]
            for a in agreements
        ],
    )
    overall = agreements[0]
    report.paragraph(f"Success gap per controller over {overall.test} ({pair[0]} − {pair[1]}):")
    fills = overall.fills or [(math.nan, math.nan)] * len(overall.controllers)
    report.table(
        ["controller", "inputs", "data", pair[0], pair[1], "gap", *(f"fill {s}" for s in pair)],
        [
            [
                controller_text(c[0]),
                SENSOR_LABELS.get(c[1], c[1]),
                DATASET_LABELS.get(c[2], c[2]),
                _percent(a),
                _percent(b),
                f"{100 * (a - b):+.0f} points",
                *("–" if math.isnan(f) else f"{f:.2f}" for f in fill),
            ]
            for c, (a, b), fill in zip(overall.controllers, overall.rates, fills, strict=True)
        ],
    )


def at_a_glance(compared: list[tuple[str, dict, dict, list]]) -> Report:
    """Per experiment: how many cells agree, which way the others lean, why scoops failed."""
    glance = Report("")
    glance.heading("At a glance")
    rows, modes = [], {}
    for title, paper, cells, claims in compared:
        verdicts = [cell_verdict(paper[key], cells[key]) for key in paper if key in cells]
        near = [
            cell_verdict(paper[key], cells[key]) == "agrees"
            or same_side_of_half(paper[key], cells[key])
            for key in paper
            if key in cells
        ]
        held = [row[1] for row in claim_rows(claims, cells)]
        rows.append(
            [
                title,
                f"{verdicts.count('agrees')}/{len(verdicts)}",
                verdicts.count("sim higher"),
                verdicts.count("sim lower"),
                f"{held.count('holds')} hold, {held.count('holds in part')} in part, "
                f"{held.count('does not hold')} do not",
                f"{sum(near)}/{len(near)}",
            ]
        )
        for key in paper:
            for mode, n in cells[key].failure_modes.items() if key in cells else ():
                modes[mode] = modes.get(mode, 0) + n
    glance.table(
        [
            "experiment",
            "paper inside the CI",
            "sim higher",
            "sim lower",
            "the paper's claims",
            "inside the CI or same side of 50%",
        ],
        rows,
    )
    failed = sum(modes.values())
    if failed:
        glance.paragraph(
            "Why the simulated scoops failed, over every failed episode of the tables above: "
            + ", ".join(
                f"{FAILURE_LABELS.get(m, m)} {100 * n / failed:.0f}%"
                for m, n in sorted(modes.items(), key=lambda kv: -kv[1])
                if n
            )
            + f' ({failed} episodes). The paper: "{paper_numbers.FAILURE_QUOTE}".'
        )
    return glance


def build_report(
    *,
    out_dir: str | Path,
    exp1: Path | None = None,
    exp2: Path | None = None,
    exp3: Path | None = None,
    exp4: Path | None = None,
    cross_soil: Path | Sequence[Path] | None = None,
    figure_actors: dict[str, Path] | None = None,
    figure_demos: Path | None = None,
    notes: list[str] | None = None,
) -> tuple[Path, Path]:
    """Write ``report.md``, ``report.html`` and the figures to ``out_dir``.

    Every sweep directory is checked before anything is written: a mistyped one raises
    ``FileNotFoundError`` and leaves ``out_dir`` as it was.
    """
    if cross_soil is None:
        cross_soil_dirs = []
    elif isinstance(cross_soil, (str, Path)):
        cross_soil_dirs = [Path(cross_soil)]
    else:
        cross_soil_dirs = [Path(d) for d in cross_soil]
    for given in [exp1, exp2, exp3, exp4, *cross_soil_dirs]:
        if given is not None and not Path(given).is_dir():
            raise FileNotFoundError(f"{given}: no such sweep directory")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    report = Report("The paper's experiments in simulation")
    report.paragraph(
        "Closed-loop success: a scoop succeeds when the bucket ends at least half full, as in "
        "the paper. The paper tested a real Avant wheel loader in winter; here every number "
        "comes from pilerl's simulator with scripted summer demonstrations "
        "(docs/demonstrations.md). 'paper in CI?' says whether the paper's rate lies "
        "inside the simulated 95% Wilson interval."
    )
    if notes:
        report.bullets(notes)
    glance_at = len(report.blocks)
    compared = []
    sweeps = {"exp1": exp1, "exp2": exp2, "exp3": exp3}
    for name, experiment in paper_numbers.EXPERIMENTS.items():
        if sweeps[name] is not None:
            cells = add_closed_loop_experiment(
                report,
                title=experiment.title,
                sweep_dir=Path(sweeps[name]),
                paper=experiment.table,
                claims=experiment.claims,
                out_dir=out_dir,
                figure=experiment.figure,
            )
            compared.append((experiment.title, experiment.table, cells, experiment.claims))
    if compared:
        report.blocks[glance_at:glance_at] = at_a_glance(compared).blocks
    if exp4 is not None:
        add_offline_validation(report, Path(exp4), out_dir)
    if cross_soil_dirs:
        add_cross_soil(report, cross_soil_dirs)
    if figure_actors and figure_demos is not None:
        add_controller_figures(report, out_dir, actors=figure_actors, demos=Path(figure_demos))
    return report.write(out_dir)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for n in (1, 2, 3, 4):
        parser.add_argument(f"--exp{n}", type=Path, help=f"multirun directory of Exp. {n}")
    parser.add_argument(
        "--cross-soil",
        type=Path,
        nargs="+",
        help="multirun directories of recipes/evaluate.py over checkpoints and env.soil, "
        "e.g. one per soil model (held-out conditions, Kendall's tau between the soils)",
    )
    parser.add_argument("--out", type=Path, required=True, help="report directory")
    parser.add_argument("--note", action="append", default=[], help="a line for the notes")
    parser.add_argument(
        "--figure-actor",
        action="append",
        default=[],
        metavar="NAME=CHECKPOINT",
        help="a controller for Fig. 3 (and Fig. 5 if it has attention); repeatable",
    )
    parser.add_argument("--figure-demos", type=Path, help="demonstrations for Fig. 3 and 5")
    args = parser.parse_args(argv)
    figure_actors = {}
    for item in args.figure_actor:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            parser.error(f"--figure-actor {item!r}: expected NAME=CHECKPOINT")
        figure_actors[name] = Path(path)
    try:
        markdown, page = build_report(
            out_dir=args.out,
            exp1=args.exp1,
            exp2=args.exp2,
            exp3=args.exp3,
            exp4=args.exp4,
            cross_soil=args.cross_soil,
            figure_actors=figure_actors,
            figure_demos=args.figure_demos,
            notes=args.note,
        )
    except (FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {markdown} and {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
