"""Summarise a Hydra multirun directory: one table, grouped by the swept keys.

Each job directory holds ``.hydra/overrides.yaml`` (its overrides) and, once finished,
``metrics.json`` (what was measured). Jobs are grouped by the swept keys (overrides whose
value differs between jobs) except the averaged ones (``seed`` by default); each numeric
metric is reported as mean, std and the number of jobs.

    python -m pilerl.sweeps.summary multirun/my_sweep                # CSV + Markdown + PNG
    python -m pilerl.sweeps.summary multirun/my_sweep --metric summer_fill_fraction
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import statistics
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from pilerl.evaluation.metrics import wilson_interval
from pilerl.io import write_text_atomic

from .completion import METRICS_FILE
from .hydra_record import job_directories, read_overrides

AVERAGED_KEYS = ("seed",)  # overrides averaged over, not grouped by


@dataclass
class Job:
    path: Path
    overrides: dict[str, str]
    metrics: dict[str, float] | None  # None: not finished


def load_jobs(sweep_dir: str | Path) -> list[Job]:
    """Every Hydra job directory under ``sweep_dir`` with its overrides and metrics
    (``hydra_record`` reads what Hydra recorded)."""
    jobs = []
    for job_dir in job_directories(sweep_dir):
        overrides = read_overrides(job_dir)
        metrics_file = job_dir / METRICS_FILE
        metrics = None
        if metrics_file.exists():
            try:
                metrics = json.loads(metrics_file.read_text())
            except json.JSONDecodeError as error:
                raise ValueError(f"{metrics_file}: corrupt metrics ({error})") from None
        jobs.append(Job(job_dir, overrides, metrics))
    if not jobs:
        raise ValueError(f"{sweep_dir}: no Hydra job directories (.hydra/overrides.yaml) found")
    return jobs


def summarize_sweep(
    sweep_dir: str | Path,
    *,
    average_over: tuple[str, ...] = AVERAGED_KEYS,
    out_dir: str | Path | None = None,
    plot_metric: str | None = None,
) -> list[dict]:
    """Group finished jobs by swept keys and write ``sweep_summary.{csv,md,png}``.

    Returns one row per group: the swept values, ``n_jobs``, and for every numeric metric
    ``<metric>_mean`` and ``<metric>_std`` (std is 0 for a single job). Jobs that report
    ``<test>_successes`` and ``<test>_episodes`` (train_bc's closed-loop step, evaluate)
    also get ``<test>_pooled_success_rate`` with its 95% Wilson interval
    (``<test>_success_low`` / ``_high``) over all the group's episodes, and the seed
    spread: the lowest and highest job's own rate (``<test>_seed_min`` / ``_seed_max``;
    the jobs of a group differ by their seed). Plotting ``<test>_success_rate`` then
    shows the interval.
    """
    jobs = load_jobs(sweep_dir)
    finished = [j for j in jobs if j.metrics is not None]
    if not finished:
        raise ValueError(f"{sweep_dir}: {len(jobs)} jobs, none finished ({METRICS_FILE})")
    # swept keys: overrides whose value differs between jobs (fixed ones are not groups)
    candidates = {k for j in finished for k in j.overrides if k not in average_over}
    group_keys = sorted(
        k for k in candidates if len({j.overrides.get(k, "") for j in finished}) > 1
    )
    groups: dict[tuple, list[Job]] = defaultdict(list)
    for job in finished:
        groups[tuple(job.overrides.get(k, "") for k in group_keys)].append(job)
    metric_names = sorted(
        {k for j in finished for k, v in j.metrics.items() if isinstance(v, int | float)}
    )
    # success counts (<test>_successes, <test>_episodes) are pooled over a group's jobs
    counted = sorted(
        name.removesuffix("_successes")
        for name in metric_names
        if name.endswith("_successes")
        and name.removesuffix("_successes") + "_episodes" in metric_names
    )
    rows = []
    for values, members in sorted(groups.items()):
        row: dict = dict(zip(group_keys, values, strict=True))
        row["n_jobs"] = len(members)
        for name in metric_names:
            samples = [float(j.metrics[name]) for j in members if name in j.metrics]
            row[f"{name}_mean"] = statistics.fmean(samples) if samples else math.nan
            row[f"{name}_std"] = statistics.stdev(samples) if len(samples) > 1 else 0.0
        for test in counted:
            successes = sum(int(j.metrics.get(f"{test}_successes", 0)) for j in members)
            episodes = sum(int(j.metrics.get(f"{test}_episodes", 0)) for j in members)
            low, high = wilson_interval(successes, episodes) if episodes else (math.nan,) * 2
            row[f"{test}_pooled_success_rate"] = successes / episodes if episodes else math.nan
            row[f"{test}_success_low"] = low
            row[f"{test}_success_high"] = high
            rates = [
                int(j.metrics[f"{test}_successes"]) / int(j.metrics[f"{test}_episodes"])
                for j in members
                if int(j.metrics.get(f"{test}_episodes", 0))
            ]
            row[f"{test}_seed_min"] = min(rates) if rates else math.nan
            row[f"{test}_seed_max"] = max(rates) if rates else math.nan
        rows.append(row)
    out_dir = Path(out_dir or sweep_dir)
    columns = list(rows[0])
    _write_csv(out_dir / "sweep_summary.csv", rows, columns)
    if plot_metric is not None and plot_metric not in metric_names:
        raise ValueError(f"--metric {plot_metric!r}: the jobs report {metric_names}")
    shown = columns if plot_metric is None else metric_columns(columns, group_keys, plot_metric)
    _write_markdown(out_dir / "sweep_summary.md", rows, shown, len(jobs), len(finished))
    metric = plot_metric or (metric_names[0] if metric_names else None)
    if metric:
        _plot(out_dir / "sweep_summary.png", rows, group_keys, metric)
    return rows


def metric_columns(columns: list[str], group_keys: list[str], metric: str) -> list[str]:
    """The group keys, ``n_jobs`` and ``metric``'s own columns (mean, std; for a success
    rate also the pooled rate, its interval and the seed spread)."""
    test = metric.removesuffix("_success_rate")
    own = [f"{metric}_mean", f"{metric}_std"]
    if metric.endswith("_success_rate"):
        own += [f"{test}_pooled_success_rate", f"{test}_success_low", f"{test}_success_high"]
        own += [f"{test}_seed_min", f"{test}_seed_max"]
    return [*group_keys, "n_jobs", *(c for c in own if c in columns)]


def _write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns)
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(path, buffer.getvalue())


def _write_markdown(
    path: Path, rows: list[dict], columns: list[str], n_jobs: int, n_finished: int
) -> None:
    def cell(value) -> str:
        return f"{value:.4g}" if isinstance(value, float) else str(value)

    lines = [
        f"# Sweep summary ({n_finished} of {n_jobs} jobs finished)",
        "",
        "| " + " | ".join(columns) + " |",
        "|" + "---|" * len(columns),
    ]
    lines += ["| " + " | ".join(cell(row[c]) for c in columns) + " |" for row in rows]
    write_text_atomic(path, "\n".join(lines) + "\n")


def _plot(path: Path, rows: list[dict], group_keys: list[str], metric: str) -> None:
    import matplotlib.pyplot as plt

    from pilerl.figures import save_figure

    labels = [", ".join(f"{k}={row[k]}" for k in group_keys) or "all" for row in rows]
    test = metric.removesuffix("_success_rate")
    if metric.endswith("_success_rate") and f"{test}_pooled_success_rate" in rows[0]:
        # a success rate: pooled over the group's episodes, with its 95% Wilson interval
        means = [row[f"{test}_pooled_success_rate"] for row in rows]
        errors = [
            [m - row[f"{test}_success_low"] for m, row in zip(means, rows, strict=True)],
            [row[f"{test}_success_high"] - m for m, row in zip(means, rows, strict=True)],
        ]
        label = f"{metric} (pooled over jobs, 95% Wilson interval)"
    else:
        means = [row.get(f"{metric}_mean", math.nan) for row in rows]
        errors = [row.get(f"{metric}_std", 0.0) for row in rows]
        label = f"{metric} (mean ± std over jobs)"
    # horizontal bars: long group labels read left of their bar, never rotated or clipped
    height = 1.2 + 0.35 * len(rows)
    width = 4.5 + 0.07 * max(len(label) for label in labels)
    fig, ax = plt.subplots(figsize=(min(width, 14), height))
    positions = range(len(rows))[::-1]  # first group on top, as in the table
    ax.barh(positions, means, xerr=errors, capsize=3, color="tab:blue", alpha=0.8)
    ax.set_yticks(list(positions), labels, fontsize=8)
    ax.set_xlabel(label, fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Summarise a Hydra multirun directory.")
    parser.add_argument("sweep_dir")
    parser.add_argument(
        "--metric", help="the one metric to tabulate and plot (default: every one; plot the first)"
    )
    parser.add_argument("--average-over", nargs="*", default=list(AVERAGED_KEYS))
    args = parser.parse_args(argv)
    try:
        rows = summarize_sweep(
            args.sweep_dir, average_over=tuple(args.average_over), plot_metric=args.metric
        )
    except (FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    table = Path(args.sweep_dir) / "sweep_summary.md"
    print(table.read_text(), end="")
    print(f"{len(rows)} groups -> {table} (all columns: sweep_summary.csv)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
