"""Seed-aware checks of closed-loop claims: "A beats B" and "A stays below / reaches x".

Seeds are an axis of every closed-loop cell (``results.Cell``): each training seed is tested
on the same seeded starts. A claim is judged by a test, not by eye:

- **A beats B** (``compare``): a paired test over seeds and starts. Episodes are paired when
  they share the training seed, the condition and the start seed (seed s of A against seed
  s of B: the strata). Cells of different tests (summer against the winter days) are paired
  per training seed and start, each side's score being its successes over its conditions
  at that start, put on a common scale. The exact one-sided sign-flip test
  (``stats.sign_flip_p``; McNemar's exact test on 0/1 pairs) gives the p-value. Without
  episodes the two cells share (per-episode records of the same training seeds, conditions
  and starts) the test falls back to Fisher's exact test on the pooled counts, and says
  so. The claim holds for the pair when p < ``ALPHA``.
- **A stays below / reaches x** (``threshold``): holds when the pooled 95% Wilson interval
  lies on the claimed side of x and no training seed's own rate is on the other side.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

from .results import Cell
from .stats import fisher_greater_p, sign_flip_p

ALPHA = 0.05  # one-sided significance level of "A beats B"


@dataclass(frozen=True)
class Comparison:
    """The test of "A's success rate is above B's".

    Attributes:
        p_value: one-sided p-value.
        method: ``paired`` (sign-flip over paired episodes) or ``unpaired`` (Fisher).
        pairs: pairs compared (paired) or 0.
        a_ahead, b_ahead: pairs where A (B) did better.
        seeds_ahead, seeds: common training seeds on which A's paired rate is above B's,
            and how many common seeds there are (0 for the unpaired test).
    """

    p_value: float
    method: str
    pairs: int = 0
    a_ahead: int = 0
    b_ahead: int = 0
    seeds_ahead: int = 0
    seeds: int = 0

    @property
    def significant(self) -> bool:
        return self.p_value < ALPHA

    def describe(self) -> str:
        if self.method == "unpaired":
            return (
                f"Fisher's exact test (no episodes paired on seed, condition and start), "
                f"p={self.p_value:.3g}"
            )
        return (
            f"paired over {self.pairs} seeded starts × seeds ({self.a_ahead} vs "
            f"{self.b_ahead} better), ahead on {self.seeds_ahead} of {self.seeds} seeds, "
            f"p={self.p_value:.3g}"
        )


def compare(a: Cell, b: Cell) -> Comparison:
    """Test whether cell ``a``'s success rate is above cell ``b``'s (see the module)."""
    differences, by_seed = _paired_differences(a, b)
    if not differences:
        p = fisher_greater_p(a.successes, a.episodes, b.successes, b.episodes)
        return Comparison(p_value=p, method="unpaired")
    seeds_ahead = sum(1 for diffs in by_seed.values() if sum(diffs) > 0)
    return Comparison(
        p_value=sign_flip_p(differences),
        method="paired",
        pairs=len(differences),
        a_ahead=sum(1 for d in differences if d > 0),
        b_ahead=sum(1 for d in differences if d < 0),
        seeds_ahead=seeds_ahead,
        seeds=len(by_seed),
    )


def _paired_differences(a: Cell, b: Cell) -> tuple[list[int], dict[int, list[int]]]:
    """Integer differences A - B per pair, and the same grouped by training seed."""
    if not a.outcomes or not b.outcomes:
        return [], {}
    conditions_a = {condition for _, condition, _ in a.outcomes}
    conditions_b = {condition for _, condition, _ in b.outcomes}
    if conditions_a == conditions_b:  # one episode against one episode
        common = a.outcomes.keys() & b.outcomes.keys()
        pairs = {k: (int(a.outcomes[k]), 1, int(b.outcomes[k]), 1) for k in common}
    else:  # per (seed, start): successes over each side's conditions
        pairs = {}
        side_a, side_b = _per_start(a), _per_start(b)
        for key in side_a.keys() & side_b.keys():
            pairs[key] = (*side_a[key], *side_b[key])
    by_seed: dict[int, list[int]] = defaultdict(list)
    differences = []
    for key in sorted(pairs):
        wins_a, n_a, wins_b, n_b = pairs[key]
        difference = wins_a * n_b - wins_b * n_a  # rates on the common scale n_a * n_b
        differences.append(difference)
        by_seed[key[0]].append(difference)
    return differences, dict(by_seed)


def _per_start(cell: Cell) -> dict[tuple[int, int], tuple[int, int]]:
    """(training seed, start seed) -> (successes, episodes) over the cell's conditions."""
    counts: dict[tuple[int, int], list[int]] = defaultdict(lambda: [0, 0])
    for (seed, _, start), ok in cell.outcomes.items():
        counts[(seed, start)][0] += int(ok)
        counts[(seed, start)][1] += 1
    return {key: (wins, n) for key, (wins, n) in counts.items()}


@dataclass(frozen=True)
class ThresholdCheck:
    """The check of "the cell's success rate is below (or at least) ``threshold``"."""

    holds: bool
    interval_side: bool  # the whole 95% interval on the claimed side
    seeds_against: int  # training seeds whose own rate is on the other side


def threshold(
    cell: Cell, *, below: float | None = None, at_least: float | None = None
) -> ThresholdCheck:
    """Check a cell against ``below`` or ``at_least`` (fractions; exactly one given)."""
    if (below is None) == (at_least is None):
        raise ValueError("threshold: give exactly one of below and at_least")
    low, high = cell.interval
    rates = cell.seed_rates.values()
    if below is not None:
        side, against = high < below, sum(1 for r in rates if r >= below)
    else:
        side, against = low >= at_least, sum(1 for r in rates if r < at_least)
    return ThresholdCheck(holds=side and against == 0, interval_side=side, seeds_against=against)


def seed_spread_text(cell: Cell) -> str:
    """``"20–47% (3 seeds)"``: the lowest and highest per-seed rates."""
    spread = cell.seed_spread
    if spread is None:
        return "not recorded"
    low, high = spread
    seeds = len(cell.seed_rates)
    unit = "seed" if seeds == 1 else "seeds"
    if math.isclose(low, high):
        return f"{100 * low:.0f}% ({seeds} {unit})"
    return f"{100 * low:.0f}–{100 * high:.0f}% ({seeds} {unit})"
