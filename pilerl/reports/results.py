"""Reading finished experiment sweeps: closed-loop cells and offline-validation curves.

A closed-loop job is a ``recipes/train_bc.py`` run directory with ``evaluation/summary.json``;
an offline-validation job is one with ``ensemble_curves.csv`` (``ensemble_seeds > 1``).
The controller, sensor set and dataset of a job come from its saved settings and Hydra's
recorded group choices (``pilerl.sweeps.hydra_record``).
"""

from __future__ import annotations

import csv
import json
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


@dataclass(frozen=True)
class Cell:
    """Closed-loop successes of one (controller, sensors, dataset, test), seeds pooled."""

    successes: int
    episodes: int
    seeds: int
    failure_modes: dict[str, int] = field(default_factory=dict)  # empty: not recorded

    @property
    def rate(self) -> float:
        return self.successes / self.episodes

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.successes, self.episodes)


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
    """Cells keyed ``(controller, sensors, dataset, test)`` with test ``summer`` / ``winter``.

    ``winter`` is the pooled winter entry when several winter conditions were tested, else
    the one winter condition. Returns the cells, the finished jobs and the unfinished ones.
    """
    counts: dict[tuple, list[int]] = defaultdict(lambda: [0, 0, 0])
    modes: dict[tuple, dict[str, int]] = defaultdict(dict)
    finished, unfinished = [], []
    for job_dir in job_directories(sweep_dir):
        setup = job_setup(job_dir)
        summary_file = job_dir / "evaluation" / "summary.json"
        if not summary_file.exists():
            unfinished.append(setup)
            continue
        try:
            summary = json.loads(summary_file.read_text())
        except json.JSONDecodeError as error:
            raise ValueError(f"{summary_file}: corrupt ({error})") from None
        finished.append(setup)
        simulator = (setup.config.get("env") or {}).get("simulator", DEFAULT_SIMULATOR)
        members = get_simulator(simulator).condition_groups.get(WINTER, ())
        winters = [name for name in summary if name in members]
        tests = {SUMMER: summary.get(SUMMER)}
        tests[WINTER] = summary.get(WINTER) or (summary[winters[0]] if winters else None)
        for test, row in tests.items():
            if row is None:
                continue
            key = (setup.controller, setup.sensors, setup.dataset, test)
            counts[key][0] += int(row["successes"])
            counts[key][1] += int(row["episodes"])
            counts[key][2] += 1
            for mode, n in row.get("failure_modes", {}).items():
                modes[key][mode] = modes[key].get(mode, 0) + int(n)
    cells = {key: Cell(s, n, seeds, modes[key]) for key, (s, n, seeds) in counts.items()}
    return cells, finished, unfinished


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


def _steps_per_epoch(config: dict) -> int | None:
    """Gradient steps per epoch of a job, from its training set's size (if it is here)."""
    index = Path(config["train_data"]) / "index.json"
    if not index.exists():
        return None
    rows = sum(int(e["n_samples"]) for e in json.loads(index.read_text())["episodes"])
    return -(-rows // int(config.get("batch_size", 512)))
