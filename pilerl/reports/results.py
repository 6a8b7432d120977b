"""Reading finished experiment sweeps: closed-loop cells and offline-validation curves.

A closed-loop job is a ``recipes/train_bc.py`` run directory with ``evaluation/summary.json``;
an offline-validation job is one with ``ensemble_curves.csv`` (``ensemble_seeds > 1``).
The controller, sensor set and dataset of a job come from its saved settings and Hydra's
recorded group choices (``pilerl.sweeps.hydra_record``).
"""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pilerl.evaluation.metrics import wilson_interval
from pilerl.layout import RunLayout
from pilerl.runs import read_run_settings
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator
from pilerl.sweeps.hydra_record import HYDRA_DIR, job_directories, read_choices, read_config

SUMMER, WINTER = "summer", "winter"  # the paper's two tests (a condition and a group)


@dataclass(frozen=True)
class JobSetup:
    """What a job trained: controller, sensor set (``conf/sensors`` name), dataset, seed."""

    path: Path
    controller: str
    sensors: str
    dataset: str
    seed: int
    config: dict


Outcome = tuple[int, str, int]  # (training seed, condition, start seed) of one episode


@dataclass(frozen=True)
class Cell:
    """Closed-loop successes of one (controller, sensors, dataset, test), seeds pooled.

    Attributes:
        successes, episodes: pooled over the cell's jobs (one training seed each).
        seeds: number of jobs (training seeds) pooled.
        failure_modes: failed episodes by mode; empty: not recorded.
        per_seed: training seed -> (successes, episodes); empty: not recorded.
        outcomes: (training seed, condition, start seed) -> success of every episode, for
            tests paired on the seeded starts (``episodes.csv``); empty: not recorded.
    """

    successes: int
    episodes: int
    seeds: int
    failure_modes: dict[str, int] = field(default_factory=dict)
    per_seed: dict[int, tuple[int, int]] = field(default_factory=dict)
    outcomes: dict[Outcome, bool] = field(default_factory=dict)

    @property
    def rate(self) -> float:
        return self.successes / self.episodes

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.successes, self.episodes)

    @property
    def seed_rates(self) -> dict[int, float]:
        """Success rate of each training seed (empty: not recorded)."""
        return {seed: s / n for seed, (s, n) in sorted(self.per_seed.items()) if n}

    @property
    def seed_spread(self) -> tuple[float, float] | None:
        """(lowest, highest) per-seed success rate; ``None``: no per-seed record."""
        rates = list(self.seed_rates.values())
        return (min(rates), max(rates)) if rates else None


def dataset_name(train_data: str) -> str:
    """``d_i`` / ``d_ii`` from a dataset path such as ``data/datasets/d_ii_summer``."""
    name = Path(train_data).name
    for known in ("d_ii", "d_i"):  # d_ii first: d_i is its prefix
        if name == known or name.startswith(known + "_"):
            return known
    return name


def job_setup(job_dir: Path) -> JobSetup:
    """What a train_bc job ran with: its ``run.json`` settings (Hydra's saved config for
    jobs from before run records), and Hydra's group choices."""
    try:
        config = read_run_settings(job_dir) or read_config(job_dir)
        return JobSetup(
            path=job_dir,
            controller=config["policy"]["name"],
            sensors=read_choices(job_dir)["sensors"],
            dataset=dataset_name(config["train_data"]),
            seed=int(config["seed"]),
            config=config,
        )
    except (KeyError, TypeError, ValueError) as error:
        hydra_dir = job_dir / HYDRA_DIR
        raise ValueError(f"{hydra_dir}: not a train_bc job's saved config ({error!r})") from None


def closed_loop_cells(sweep_dir: str | Path) -> tuple[dict[tuple, Cell], list[JobSetup], list]:
    """Cells keyed ``(controller, sensors, dataset, test)``, pooled over training seeds.

    Tests: ``summer`` and ``winter`` (the paper's: ``winter`` is the pooled winter entry when
    several winter conditions were tested, else the one winter condition), then every
    tested condition and pooled group by its own name (``winter_a``, ``held_out``, ...).
    Returns the cells, the finished jobs and the unfinished ones. Two finished jobs of one
    cell with the same training seed are refused (a seed is counted once).
    """
    parts: dict[tuple, list[tuple[JobSetup, TestResult]]] = defaultdict(list)
    finished, unfinished = [], []
    for job_dir in job_directories(sweep_dir):
        setup = job_setup(job_dir)
        results = job_results(job_dir / "evaluation", setup.config)
        if results is None:
            unfinished.append(setup)
            continue
        finished.append(setup)
        for test, result in results.items():
            parts[(setup.controller, setup.sensors, setup.dataset, test)].append((setup, result))
    cells = {key: pool_seeds(members, cell=key) for key, members in parts.items()}
    return cells, finished, unfinished


@dataclass(frozen=True)
class TestResult:
    """One job's episodes in one test (a condition or a pooled group)."""

    successes: int
    episodes: int
    failure_modes: dict[str, int]
    outcomes: dict[tuple[str, int], bool]  # (condition, start seed) -> success
    fill_mean: float | None = None  # mean bucket fill (1 = rated load); None: not recorded


def job_results(evaluation_dir: Path, config: dict) -> dict[str, TestResult] | None:
    """Per test, one job's closed-loop results from ``summary.json`` and ``episodes.csv``
    in ``evaluation_dir`` (``None``: no summary, the job has not finished).

    Tests: every entry of the summary (conditions and pooled groups) and, for the paper,
    ``winter`` = the one winter condition when only one was tested.
    """
    summary_file = evaluation_dir / "summary.json"
    if not summary_file.exists():
        return None
    try:
        summary = json.loads(summary_file.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{summary_file}: corrupt ({error})") from None
    simulator = (config.get("env") or {}).get("simulator", DEFAULT_SIMULATOR)
    groups = dict(get_simulator(simulator).condition_groups)
    members = {name: groups.get(name, (name,)) for name in summary}
    winters = [name for name in summary if name in groups.get(WINTER, ())]
    if WINTER not in summary and winters:
        summary[WINTER] = summary[winters[0]]
        members[WINTER] = (winters[0],)
    episodes = read_episode_outcomes(evaluation_dir / "episodes.csv")
    results = {}
    for test, row in summary.items():
        if row is None:
            continue
        outcomes = {k: ok for k, ok in episodes.items() if k[0] in members[test]}
        results[test] = TestResult(
            successes=int(row["successes"]),
            episodes=int(row["episodes"]),
            failure_modes={m: int(n) for m, n in row.get("failure_modes", {}).items()},
            outcomes=outcomes,
            fill_mean=finite_or_none(row.get("fill_mean")),
        )
    return results


def finite_or_none(value: object) -> float | None:
    """``value`` as a float if it is a finite number, else ``None``."""
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def read_episode_outcomes(path: Path) -> dict[tuple[str, int], bool]:
    """``(condition, start seed) -> success`` of every episode in ``episodes.csv``
    (empty when the file is absent: such jobs can only be compared unpaired)."""
    if not path.exists():
        return {}
    outcomes = {}
    with path.open() as file:
        for line, row in enumerate(csv.DictReader(file), start=2):
            try:
                key = (row["condition"], int(row["seed"]))
                success = {"True": True, "False": False}[row["success"]]
            except (KeyError, TypeError, ValueError):
                raise ValueError(
                    f"{path}:{line}: expected condition, seed and success (True/False)"
                ) from None
            if key in outcomes:
                raise ValueError(f"{path}:{line}: episode {key} appears twice")
            outcomes[key] = success
    return outcomes


def pool_seeds(members: list[tuple[JobSetup, TestResult]], *, cell: tuple = ()) -> Cell:
    """One cell from its jobs (one training seed each).

    A training seed that two finished jobs of the cell share is refused, naming the cell
    (``cell``: its key, for the message), the seed and the jobs: counting both would
    count that seed's episodes twice, and keeping one would choose silently between two
    runs. A resumed job finishes in its own directory, so a duplicate comes from a sweep
    run again into the same directory tree; remove (or move) the copy that should not count.
    """
    per_seed: dict[int, tuple[int, int]] = {}
    modes: dict[str, int] = {}
    outcomes: dict[Outcome, bool] = {}
    for setup, result in members:
        if setup.seed in per_seed:
            jobs = [str(s.path) for s, _ in members if s.seed == setup.seed]
            named = " / ".join(str(part) for part in cell if part != "")  # no blank parts
            where = f"cell {named}: " if named else ""
            raise ValueError(
                f"{where}training seed {setup.seed} appears in several jobs: {jobs}; a seed "
                "is counted once, so remove or move the job that should not count"
            )
        per_seed[setup.seed] = (result.successes, result.episodes)
        for mode, n in result.failure_modes.items():
            modes[mode] = modes.get(mode, 0) + n
        outcomes |= {(setup.seed, c, start): ok for (c, start), ok in result.outcomes.items()}
    return Cell(
        successes=sum(s for s, _ in per_seed.values()),
        episodes=sum(n for _, n in per_seed.values()),
        seeds=len(per_seed),
        failure_modes=modes,
        per_seed=per_seed,
        outcomes=outcomes,
    )


@dataclass(frozen=True)
class LossCurves:
    """Offline validation loss over epochs across seeds (the paper's Fig. 4)."""

    controller: str
    sensors: str
    dataset: str
    seeds: int
    epoch: np.ndarray
    steps_per_epoch: int | None  # None: the training set is not here to count its rows
    validation_mean: np.ndarray
    validation_std: np.ndarray


def offline_validation_curves(sweep_dir: str | Path) -> list[LossCurves]:
    """One ``LossCurves`` per finished ensemble job under ``sweep_dir``."""
    curves = []
    for job_dir in job_directories(sweep_dir):
        path = job_dir / "ensemble_curves.csv"
        if not path.exists():
            continue
        setup = job_setup(job_dir)
        with path.open() as file:
            rows = list(csv.DictReader(file))
        if not rows or "validation_mean" not in rows[0]:
            raise ValueError(f"{path}: no validation_mean column (trained without validation?)")
        curves.append(
            LossCurves(
                controller=setup.controller,
                sensors=setup.sensors,
                dataset=setup.dataset,
                seeds=int(json.loads(RunLayout(job_dir).metrics.read_text())["seeds"]),
                epoch=np.array([float(r["epoch"]) for r in rows]),
                steps_per_epoch=_steps_per_epoch(setup.config),
                validation_mean=np.array([float(r["validation_mean"]) for r in rows]),
                validation_std=np.array([float(r["validation_std"]) for r in rows]),
            )
        )
    return curves


def unfinished_ensemble_jobs(sweep_dir: str | Path) -> list[Path]:
    """The ensemble jobs under ``sweep_dir`` without ``ensemble_curves.csv`` (still running,
    or stopped): ``offline_validation_curves`` leaves them out, a report lists them."""
    return [job for job in job_directories(sweep_dir) if not (job / "ensemble_curves.csv").exists()]


def _steps_per_epoch(config: dict) -> int | None:
    """Gradient steps per epoch of a job, from its training set's size (if it is here)."""
    index = Path(config["train_data"]) / "index.json"
    if not index.exists():
        return None
    rows = sum(int(e["n_samples"]) for e in json.loads(index.read_text())["episodes"])
    return -(-rows // int(config.get("batch_size", 512)))
