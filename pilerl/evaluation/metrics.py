"""Statistics of closed-loop results and of demonstrations."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from statistics import NormalDist

import numpy as np


def wilson_interval(
    successes: int, trials: int, *, confidence: float = 0.95
) -> tuple[float, float]:
    """Wilson score interval for a success rate (Wilson 1927): sensible at 0/n and n/n,
    unlike the normal approximation."""
    if trials <= 0:
        raise ValueError(f"wilson_interval: trials must be > 0, got {trials}")
    if not 0 <= successes <= trials:
        raise ValueError(f"wilson_interval: successes must lie in [0, {trials}], got {successes}")
    if not 0 < confidence < 1:
        raise ValueError(f"wilson_interval: confidence must lie in (0, 1), got {confidence}")
    z = NormalDist().inv_cdf(0.5 + confidence / 2)
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    # at 0/n and n/n the interval touches 0 or 1 exactly; floating point lands a hair off
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


def lagged_features(
    readings: Mapping[str, np.ndarray], *, dt: float, history_s: Sequence[float]
) -> np.ndarray:
    """Per row, each sensor's reading now and ``history_s`` seconds earlier (the first
    reading before the episode started), shape [T, n_sensors * (1 + len(history_s))]."""
    columns = []
    for lag_s in (0.0, *history_s):
        lag = round(lag_s / dt)
        for values in readings.values():
            values = np.asarray(values, dtype=np.float64)
            shifted = np.concatenate([np.full(lag, values[0]), values])[: len(values)]
            columns.append(shifted)
    return np.stack(columns, axis=1)


def explainable_variance(
    episodes: Sequence[tuple[Mapping[str, np.ndarray], np.ndarray]],
    *,
    dt: float,
    history_s: Sequence[float] = (0.25, 0.5, 1.0),
    folds: int = 4,
    seed: int = 0,
) -> np.ndarray:
    """How much of each control's variance the sensors explain: R² of a gradient-boosted
    tree model predicting the action from the readings now and ``history_s`` earlier,
    cross-validated by episode (no episode is in both the fitted and the scored part).

    Args:
        episodes: (readings {sensor name: [T]}, actions [T, n_controls]) per episode; the
            readings are those the operator acted on.
        dt: control period [s]. history_s: how far back the model may look [s] (<= 1 s
            in the issue's definition).
        folds: number of episode-wise folds (at most the number of episodes).

    Returns:
        R² per control (pooled over the held-out predictions), shape [n_controls].
    """
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.model_selection import GroupKFold

    if len(episodes) < 2:
        raise ValueError(f"explainable_variance: needs >= 2 episodes, got {len(episodes)}")
    features = np.concatenate([lagged_features(r, dt=dt, history_s=history_s) for r, _ in episodes])
    actions = np.concatenate([np.asarray(a, dtype=np.float64) for _, a in episodes])
    groups = np.concatenate([np.full(len(a), i) for i, (_, a) in enumerate(episodes)])
    predicted = np.zeros_like(actions)
    for fit, held_out in GroupKFold(n_splits=min(folds, len(episodes))).split(
        features, groups=groups
    ):
        for c in range(actions.shape[1]):
            model = HistGradientBoostingRegressor(max_iter=200, random_state=seed)
            model.fit(features[fit], actions[fit, c])
            predicted[held_out, c] = model.predict(features[held_out])
    residual = ((actions - predicted) ** 2).sum(axis=0)
    total = ((actions - actions.mean(axis=0)) ** 2).sum(axis=0)
    return 1.0 - residual / np.where(total > 0, total, np.nan)


FILL_BINS = (0.25, 0.5, 0.75, 1.0)  # edges of the fill histogram [fraction of rated load]
FILL_BIN_LABELS = ("<0.25", "0.25-0.5", "0.5-0.75", "0.75-1", ">=1")


def fill_and_cycle_time(rows: Sequence[Mapping]) -> dict[str, object]:
    """Beside the success rate: the distribution of fill and the cycle time.

    Fill quartiles and a histogram (``fill_histogram``: counts below 0.25, 0.25-0.5,
    0.5-0.75, 0.75-1.0 and from 1.0, of the rated load), and the cycle time of the scoops
    that were finished (curled and raised, whether full or not): mean, median and 90th
    percentile [s] (NaN when none finished)."""
    fills = np.asarray([float(r["fill_fraction"]) for r in rows])
    if fills.size == 0:
        raise ValueError("fill_and_cycle_time: no episode records")
    counts = np.bincount(np.searchsorted(FILL_BINS, fills, side="right"), minlength=5)
    times = np.asarray([float(r.get("time_to_finish_s", math.nan)) for r in rows])
    cycle = times[~np.isnan(times)]  # time_to_finish_s is NaN unless the scoop was finished
    q10, q25, q75, q90 = np.quantile(fills, (0.1, 0.25, 0.75, 0.9))
    return {
        "fill_p10": float(q10),
        "fill_p25": float(q25),
        "fill_p75": float(q75),
        "fill_p90": float(q90),
        "fill_histogram": {label: int(n) for label, n in zip(FILL_BIN_LABELS, counts, strict=True)},
        "finished": int(cycle.size),
        "cycle_time_s_mean": float(cycle.mean()) if cycle.size else math.nan,
        "cycle_time_s_median": float(np.median(cycle)) if cycle.size else math.nan,
        "cycle_time_s_p90": float(np.quantile(cycle, 0.9)) if cycle.size else math.nan,
    }
