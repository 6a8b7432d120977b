"""Sample efficiency of fine-tuning runs: success against scoops, summarised over seeds.

A run's curve is its periodic evaluations (``evaluations.json``: ``scoops`` of training
experience and the success per group on held-out seeded starts). Between evaluations the
success is taken as the last one measured (a step function), so "success at 40 scoops"
is the last evaluation made with at most 40 scoops of experience: it never credits
learning the run had not done yet.

Over seeds, the interquartile mean (IQM: the mean of the middle 50%) with a
stratified-bootstrap confidence interval, as rliable (Agarwal et al., NeurIPS 2021) does:
resample the runs of each task with replacement, recompute the IQM, take the percentiles.
rliable is not installed here, so this is that computation, small, with numpy and scipy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.stats import trim_mean


def iqm(scores: np.ndarray) -> float:
    """Interquartile mean of all ``scores`` (rliable's: 25% trimmed from each end)."""
    return float(trim_mean(np.asarray(scores, dtype=float).reshape(-1), 0.25))


def stratified_bootstrap_ci(
    scores: np.ndarray,
    statistic=iqm,
    *,
    repetitions: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile interval of ``statistic`` over bootstrap resamples of ``scores``
    [runs, tasks]: each task's runs are resampled with replacement, independently."""
    scores = np.asarray(scores, dtype=float)
    if scores.ndim == 1:
        scores = scores[:, None]
    if scores.shape[0] < 1 or not np.isfinite(scores).all():
        raise ValueError(f"stratified_bootstrap_ci: need finite scores, got {scores.tolist()}")
    rng = np.random.default_rng(seed)
    runs, tasks = scores.shape
    rows = rng.integers(0, runs, size=(repetitions, runs, tasks))
    resampled = np.take_along_axis(scores[None], rows, axis=1)  # [repetitions, runs, tasks]
    if statistic is iqm:  # all resamples at once
        values = trim_mean(resampled.reshape(repetitions, -1), 0.25, axis=1)
    else:
        values = np.array([statistic(sample) for sample in resampled])
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return float(low), float(high)


def curve(evaluations: Sequence[dict], group: str) -> tuple[np.ndarray, np.ndarray]:
    """(scoops, success rate) of ``group`` at each periodic evaluation, scoops increasing;
    evaluations at the same scoop count keep their order (the later one is the later
    learning), never sorted by rate."""
    points = sorted(
        ((int(e["scoops"]), float(e["groups"][group]["success_rate"])) for e in evaluations),
        key=lambda point: point[0],
    )
    if not points:
        raise ValueError(f"curve: no evaluations of {group!r}")
    scoops, rate = zip(*points, strict=True)
    return np.array(scoops), np.array(rate)


def success_at(scoops: np.ndarray, rate: np.ndarray, budget: int) -> float | None:
    """The last success measured with at most ``budget`` scoops (``None``: none was)."""
    measured = rate[scoops <= budget]
    return float(measured[-1]) if len(measured) else None


def scoops_to(scoops: np.ndarray, rate: np.ndarray, threshold: float) -> int | None:
    """Scoops at the first evaluation with success >= ``threshold`` (``None``: never)."""
    reached = np.flatnonzero(rate >= threshold)
    return int(scoops[reached[0]]) if len(reached) else None


def area_under_curve(scoops: np.ndarray, rate: np.ndarray, budget: int) -> float:
    """Mean success over 0..``budget`` scoops of the step curve (1 = always succeeding)."""
    if budget <= 0:
        raise ValueError(f"area_under_curve: budget must be > 0, got {budget}")
    edges = np.append(np.clip(scoops, 0, budget), budget)
    return float(np.sum(rate * np.diff(edges)) / budget)


def on_grid(scoops: np.ndarray, rate: np.ndarray, grid: Sequence[int]) -> np.ndarray:
    """The step curve at each scoop count of ``grid`` (NaN before the first evaluation)."""
    values = [success_at(scoops, rate, g) for g in grid]
    return np.array([np.nan if v is None else v for v in values])
