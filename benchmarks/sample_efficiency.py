"""Sample efficiency of fine-tuning methods: winter and summer success against scoops.

    python benchmarks/sample_efficiency.py --run outputs/pipeline/<time> \
        --methods ppo td3bc rlpd rlpd_residual --seeds 5 --scoops 200 \
        --override rlpd:algorithm.utd_ratio=0.2 --out outputs/sample_efficiency

For each method (a ``conf/algorithm/<name>.yaml``, composed like ``recipes/finetune.py``)
and seed, fine-tunes the main job's cloned actor (``<run>/bc/final.pt``, or ``--clone-weights best``
for ``bc/best.pt``; demonstrations
``<run>/datasets/d_ii``) in the ``winter_mix`` curriculum until ``--scoops`` training
scoops (episodes) have ended, evaluating on held-out seeded starts
(``evaluation.seed=--eval-seed``, other starts than training's) at 0 scoops and at each
of ``--at-scoops``. Evaluation episodes are not experience; they are counted and reported
apart. Then writes, into ``--report``:

- ``sample_efficiency.md``: method | scoops to 90% winter per seed, IQM [95% stratified
  bootstrap CI] | winter and summer success at 40 and 200 scoops (IQM over seeds) | area
  under the winter curve | failed (tipped) scoops during learning | wall time;
- ``sample_efficiency.json``: every run's numbers;
- ``sample_efficiency.png``: success vs scoops, each seed thin, the IQM with its interval.

Resumable: a (method, seed) run that reached ``--scoops`` is skipped; an unfinished one
continues from its ``last.ckpt`` (a later, larger ``--scoops`` extends finished runs).
``--shard i/n`` runs every n-th (method, seed) pair (two processes share the work);
``--report-only`` only summarises the runs on disk.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from pilerl.config import register_configs
from pilerl.figures import legend_outside, plt, save_figure
from pilerl.io import write_text_atomic
from pilerl.rl import FinetuneConfig, finetune
from pilerl.rl.finetuning import RUN_CHECKPOINT
from pilerl.rl.run_checkpoint import load_run
from pilerl.rl.sample_efficiency import (
    area_under_curve,
    curve,
    iqm,
    on_grid,
    scoops_to,
    stratified_bootstrap_ci,
    success_at,
)
from pilerl.runtime import limit_threads

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("ppo", "td3bc", "rlpd", "rlpd_residual")  # the default --methods
VARIANTS = ("rlpd_calibrated",)  # also known, run when named (conf/algorithm/<name>.yaml)
THRESHOLD = 0.9  # the target: winter success >= 90%
REPORT_SCOOPS = (40, 200)  # the table's columns
AT_SCOOPS = (10, 20, 40, 80, 120, 200)
BENCH_FILE = "benchmark.json"  # per run: wall time of every invocation
# every last.ckpt restarts the 8 simulators mid-scoop (so a resumed run is the same run),
# dropping on average half a scoop each (8 x ~200 frames, scoops here take ~400): about 16%
# of the frames at the finetune default of 10,000; 20,000 halves that, and a kill loses at
# most ~50 scoops of work
CHECKPOINT_EVERY_FRAMES = 20_000


def clone_checkpoint(args: argparse.Namespace) -> Path:
    """The main job's cloned actor: ``bc/final.pt`` (what the main job fine-tunes since its
    ``bc.selection=final``) or ``bc/best.pt``."""
    return args.run / "bc" / f"{args.clone_weights}.pt"


def run_config(args: argparse.Namespace, method: str, seed: int, run_dir: Path) -> FinetuneConfig:
    """The finetune recipe's config for one (method, seed), from the conf/ groups."""
    at_scoops = [s for s in args.at_scoops if s <= args.scoops]
    if args.scoops not in at_scoops:
        at_scoops.append(args.scoops)
    overrides = [
        f"algorithm={method}",
        f"curriculum={args.curriculum}",
        f"checkpoint={clone_checkpoint(args)}",
        f"demos={args.run / 'datasets' / 'd_ii'}",
        f"seed={seed}",
        f"max_scoops={args.scoops}",
        f"evaluation.at_scoops=[{','.join(map(str, at_scoops))}]",
        "evaluation.every_frames=0",
        f"evaluation.episodes={args.eval_episodes}",
        f"evaluation.final_episodes={args.eval_episodes}",
        f"evaluation.seed={args.eval_seed}",
        f"evaluation.final_seed={args.eval_seed}",  # the same starts: evaluations reused
        "logger=csv",
        f"checkpoint_every_frames={args.checkpoint_every_frames}",
        f"output_dir={run_dir}",
        *[o.split(":", 1)[1] for o in args.override if o.split(":", 1)[0] in (method, "all")],
    ]
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="finetune", overrides=overrides)
    return OmegaConf.to_object(cfg)


def process_age_s() -> float:
    """Seconds since this process started (Linux: /proc/self/stat's start time; NaN
    where there is no /proc)."""
    if not Path("/proc/self/stat").is_file():
        return float("nan")
    start_ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
    uptime_s = float(Path("/proc/uptime").read_text().split()[0])
    return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")


PHASES = ("collection_s", "update_s", "evaluation_s")  # a run's totals (last.ckpt, results)


def phase_totals(run_dir: Path) -> dict[str, float]:
    """The run's phase totals where this invocation starts: those of its ``last.ckpt``
    (what a resumed run continues from; work after it was lost), else none."""
    checkpoint = run_dir / RUN_CHECKPOINT
    if not checkpoint.exists():
        return {}
    progress, _, _ = load_run(checkpoint)
    return {p: float(progress[p]) for p in PHASES}


def run_one(args: argparse.Namespace, method: str, seed: int) -> None:
    """Fine-tune one (method, seed) up to ``--scoops`` (or skip it), then print where this
    invocation's time went: composing the config, collection, updates, evaluations, and
    the rest (building the learner and envs, checkpoints, curve plots)."""
    run_dir = args.out / method / f"seed{seed}"
    results = run_dir / "results.json"
    if results.exists() and json.loads(results.read_text())["scoops"] >= args.scoops:
        print(f"{method} seed {seed}: done, skipped")
        return
    before = phase_totals(run_dir)
    started = time.perf_counter()
    config = run_config(args, method, seed, run_dir)
    compose_s = time.perf_counter() - started
    finetune(config, run_dir, progress=False)
    wall_s = time.perf_counter() - started
    bench = run_dir / BENCH_FILE
    invocations = json.loads(bench.read_text())["invocations_s"] if bench.exists() else []
    record = {"invocations_s": [*invocations, wall_s], "scoops_budget": args.scoops}
    write_text_atomic(bench, json.dumps(record))
    after = json.loads(results.read_text())
    phases = {"compose_s": compose_s}
    phases.update({p: after[p] - before.get(p, 0.0) for p in PHASES})
    phases["other_s"] = wall_s - sum(phases.values())
    print(
        f"{method} seed {seed}: {wall_s:.0f} s, {after['scoops']} scoops, {after['frames']} "
        "frames; " + ", ".join(f"{k.removesuffix('_s')} {v:.1f} s" for k, v in phases.items())
    )


# ---------------------------------------------------------------------- the report
def load_runs(out: Path, methods: list[str]) -> tuple[dict[str, list[dict]], dict[str, list[int]]]:
    """Per method, every finished run (its evaluations, results, wall time and configured
    scoop budget), and the seeds of the runs begun but not finished."""
    runs: dict[str, list[dict]] = {}
    unfinished: dict[str, list[int]] = {}
    for method in methods:
        for run_dir in sorted((out / method).glob("seed*")):
            seed = int(run_dir.name.removeprefix("seed"))
            if not (run_dir / "results.json").exists():
                unfinished.setdefault(method, []).append(seed)
                continue
            bench = run_dir / BENCH_FILE
            record = json.loads(bench.read_text()) if bench.exists() else {}
            runs.setdefault(method, []).append(
                {
                    "seed": seed,
                    "evaluations": json.loads((run_dir / "evaluations.json").read_text()),
                    "results": json.loads((run_dir / "results.json").read_text()),
                    "wall_s": sum(record["invocations_s"]) if record else None,
                    # runs from before it was recorded: None
                    "scoops_budget": record.get("scoops_budget"),
                }
            )
    return runs, unfinished


def summarise_run(run: dict) -> dict:
    """One run's numbers. ``scoops`` is the count reached (the run stops at the first
    batch that reaches its budget, so a few more); the winter AUC is over the configured
    budget where recorded (the same span for every seed), else over the count reached."""
    results = run["results"]
    reached = int(results["scoops"])
    budget = run["scoops_budget"] or reached
    winter, summer = curve(run["evaluations"], "winter"), curve(run["evaluations"], "summer")
    summary = {
        "seed": run["seed"],
        "scoops_budget": run["scoops_budget"],
        "scoops": reached,
        "frames": results["frames"],
        "scoops_to_90": scoops_to(*winter, THRESHOLD),
        "winter_auc": area_under_curve(*winter, budget),
        "failed_scoops": results["failed_scoops"],
        "tipped_scoops": results["tipped_scoops"],
        "evaluation_episodes": results["evaluation_episodes"],
        "evaluation_s": results["evaluation_s"],
        "wall_s": run["wall_s"],
        "curve": {
            "scoops": winter[0].tolist(),
            "winter": winter[1].tolist(),
            "summer": summer[1].tolist(),
        },
    }
    for at in REPORT_SCOOPS:
        summary[f"winter_at_{at}"] = success_at(*winter, at) if reached >= at else None
        summary[f"summer_at_{at}"] = success_at(*summer, at) if reached >= at else None
    return summary


def _iqm_ci(values: list[float]) -> str:
    if not values:
        return "n/a"
    low, high = stratified_bootstrap_ci(np.array(values))
    return f"{iqm(np.array(values)):.2f} [{low:.2f}, {high:.2f}]"


def method_row(method: str, summaries: list[dict]) -> dict:
    """The table row. A run that never reached 90% shows '>N' (N: the scoops it reached);
    the IQM and its interval are given only when most seeds reached 90%, else the count."""
    budgets = sorted({s["scoops_budget"] for s in summaries if s["scoops_budget"] is not None})
    to90 = [s["scoops_to_90"] if s["scoops_to_90"] is not None else s["scoops"] for s in summaries]
    per_seed = ", ".join(
        str(s["scoops_to_90"]) if s["scoops_to_90"] is not None else f">{s['scoops']}"
        for s in summaries
    )
    reached = sum(s["scoops_to_90"] is not None for s in summaries)
    most_reached = reached > len(summaries) / 2  # else a median or IQM would be a censored value
    # an interrupted invocation's wall time is not in the bench file while its evaluation
    # time is in the run's totals: a share is only given where every run's times agree
    shares = [s["evaluation_s"] / s["wall_s"] for s in summaries if s["wall_s"]]
    row = {
        "method": method,
        "seeds": len(summaries),
        "scoops_budget": budgets[0] if len(budgets) == 1 else budgets or None,  # configured
        "min_scoops_reached": min(s["scoops"] for s in summaries),
        "scoops_to_90_per_seed": per_seed,
        "scoops_to_90_iqm_ci": _iqm_ci(to90)
        if most_reached
        else f"not reached by most seeds ({reached}/{len(summaries)})",
        "scoops_to_90_median": float(np.median(to90)) if most_reached else None,
        "reached_90": reached,
        "winter_auc": _iqm_ci([s["winter_auc"] for s in summaries]),
        "failed_scoops": f"{np.mean([s['failed_scoops'] for s in summaries]):.1f} "
        f"({np.mean([s['tipped_scoops'] for s in summaries]):.1f}) of "
        f"{np.mean([s['scoops'] for s in summaries]):.0f}",
        "evaluation_episodes": float(np.mean([s["evaluation_episodes"] for s in summaries])),
        "evaluation_share": float(np.mean(shares))
        if shares and len(shares) == len(summaries) and max(shares) <= 1.0
        else None,
        "wall_s": float(np.mean([s["wall_s"] for s in summaries if s["wall_s"] is not None]))
        if any(s["wall_s"] is not None for s in summaries)
        else None,
    }
    for at in REPORT_SCOOPS:
        for group in ("winter", "summer"):
            values = [s[f"{group}_at_{at}"] for s in summaries if s[f"{group}_at_{at}"] is not None]
            row[f"{group}_at_{at}"] = _iqm_ci(values) if len(values) == len(summaries) else "n/a"
    return row


TABLE_HEADER = (
    "| method | seeds | scoops to 90% winter: per seed; IQM [95% CI] | winter @40 | summer @40 "
    "| winter @200 | summer @200 | winter AUC | failed (tipped) scoops during learning "
    "| eval episodes (share of wall time) | wall time / run |\n|" + "---|" * 11
)


def table(rows: list[dict]) -> str:
    lines = [TABLE_HEADER]
    for r in rows:
        wall = f"{r['wall_s'] / 60:.1f} min" if r["wall_s"] is not None else "n/a"
        share = (
            f" ({100 * r['evaluation_share']:.0f}% of wall)"
            if r["evaluation_share"] is not None
            else " (share n/a: a resumed run's wall time is incomplete)"
        )
        lines.append(
            f"| {r['method']} | {r['seeds']} | {r['scoops_to_90_per_seed']}; "
            f"{r['scoops_to_90_iqm_ci']} | {r['winter_at_40']} | {r['summer_at_40']} "
            f"| {r['winter_at_200']} | {r['summer_at_200']} | {r['winter_auc']} "
            f"| {r['failed_scoops']} | {r['evaluation_episodes']:.0f}{share} | {wall} |"
        )
    return "\n".join(lines)


def plot(summaries: dict[str, list[dict]], path: Path) -> Path:
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for index, (method, runs) in enumerate(summaries.items()):
        color = f"C{index}"
        reached = min(r["scoops"] for r in runs)  # every seed's curve is known up to here
        grid = np.unique(np.concatenate([[0], np.linspace(0, reached, 41).astype(int)]))
        for ax, group in zip(axes, ("winter", "summer"), strict=True):
            curves = []
            for r in runs:
                scoops = np.array(r["curve"]["scoops"])
                rate = np.array(r["curve"][group])
                ax.step(scoops, rate, where="post", color=color, alpha=0.25, linewidth=0.8)
                curves.append(on_grid(scoops, rate, grid))
            stacked = np.array(curves)
            centre = [iqm(stacked[:, j]) for j in range(len(grid))]
            bands = [
                stratified_bootstrap_ci(stacked[:, j], repetitions=500) for j in range(len(grid))
            ]
            ax.step(grid, centre, where="post", color=color, linewidth=2, label=f"{method} (IQM)")
            ax.fill_between(
                grid,
                [b[0] for b in bands],
                [b[1] for b in bands],
                step="post",
                color=color,
                alpha=0.15,
            )
    for ax, group in zip(axes, ("winter (A-D pooled)", "summer"), strict=True):
        ax.axhline(THRESHOLD, color="grey", linestyle=":", linewidth=1)
        ax.axvline(40, color="grey", linestyle="--", linewidth=1)
        ax.set_xlabel("training scoops (evaluation episodes not counted)", fontsize=8)
        ax.set_title(group)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (seeds thin; IQM, 95% bootstrap band)")
    axes[0].set_ylim(-0.02, 1.02)
    legend_outside(axes[1], fontsize=8)
    return save_figure(fig, path)


def report(args: argparse.Namespace) -> None:
    runs, unfinished = load_runs(args.out, args.methods)
    if not runs:
        raise SystemExit(f"no finished runs under {args.out}")
    summaries = {m: [summarise_run(r) for r in rs] for m, rs in runs.items()}
    rows = [method_row(m, s) for m, s in summaries.items()]
    args.report.mkdir(parents=True, exist_ok=True)
    first = next(iter(runs.values()))[0]["evaluations"][0]  # every run starts from the clone
    clone = ", ".join(
        f"{group} {result['success_rate']:.2f}" for group, result in first["groups"].items()
    )
    text = (
        table(rows)
        + f"\n\nThe clone before fine-tuning (0 scoops, the same held-out starts): {clone}.\n"
    )
    partial = [
        f"{m}: seeds {unfinished[m]} unfinished, not in the table"
        for m in args.methods
        if unfinished.get(m)
    ] + [f"{m}: no finished run" for m in args.methods if m not in runs]
    if partial:
        text += "\n**Partial results** (the benchmark is still running): " + "; ".join(partial)
        text += ".\n"
    write_text_atomic(args.report / "sample_efficiency.md", text)
    write_text_atomic(
        args.report / "sample_efficiency.json",
        json.dumps({"rows": rows, "runs": summaries, "unfinished": unfinished}, indent=1),
    )
    plot(summaries, args.report / "sample_efficiency.png")
    print(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--run", type=Path, help="a main-job run directory (bc/, datasets/)")
    parser.add_argument(
        "--clone-weights",
        choices=("final", "best"),
        default="final",
        help="which of the main job's BC weights to fine-tune (its bc.selection)",
    )
    parser.add_argument("--methods", nargs="+", default=list(METHODS))
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--scoops", type=int, default=200, help="training scoops per run")
    parser.add_argument("--at-scoops", type=int, nargs="+", default=list(AT_SCOOPS))
    parser.add_argument("--eval-episodes", type=int, default=2, help="per condition")
    parser.add_argument("--eval-seed", type=int, default=1000, help="held-out starts")
    parser.add_argument("--curriculum", default="winter_mix")
    parser.add_argument(
        "--checkpoint-every-frames",
        type=int,
        default=CHECKPOINT_EVERY_FRAMES,
        help="last.ckpt interval; each one restarts the simulators, ending their scoops unfinished",
    )
    parser.add_argument("--out", type=Path, default=Path("outputs/sample_efficiency"))
    parser.add_argument("--report", type=Path, default=ROOT / "docs/results/finetune")
    parser.add_argument("--shard", default="0/1", help="i/n: run every n-th (method, seed)")
    parser.add_argument(
        "--override",
        nargs="*",
        default=[],
        help="METHOD:KEY=VALUE (or all:KEY=VALUE): a finetune config override for that method, "
        "e.g. rlpd:algorithm.utd_ratio=0.2",
    )
    parser.add_argument("--report-only", action="store_true")
    args = parser.parse_args()
    unknown = sorted(set(args.methods) - set(METHODS + VARIANTS))
    if unknown:
        parser.error(f"--methods: unknown {unknown}; known: {list(METHODS + VARIANTS)}")
    bad = [o for o in args.override if ":" not in o or "=" not in o]
    if bad:
        parser.error(f"--override: expected METHOD:KEY=VALUE, got {bad}")
    if args.seeds < 1 or args.scoops < 1:
        parser.error("--seeds and --scoops must be >= 1")
    if not args.report_only:
        if args.run is None or not clone_checkpoint(args).is_file():
            where = f"bc/{args.clone_weights}.pt"
            parser.error(f"--run: no {where} under {args.run} (see --clone-weights)")
        logging.basicConfig(level=logging.WARNING)
        limit_threads(1)
        register_configs()
        print(f"startup (process start, imports, configs): {process_age_s():.1f} s")
        shard, shards = (int(x) for x in args.shard.split("/"))
        pairs = [(m, s) for s in range(args.seeds) for m in args.methods]  # seed-major
        for method, seed in pairs[shard::shards]:
            run_one(args, method, seed)
    report(args)


if __name__ == "__main__":
    main()
