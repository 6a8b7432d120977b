"""Small tests behind the report's verdicts: paired sign-flip, Fisher, Kendall's tau, Welch.

All deterministic (no random permutations); the first three exact, in plain Python: the
report needs a handful of tests on a few hundred episodes, not a statistics package.

- ``sign_flip_p``: the paired permutation test. Under "A and B do equally well", each pair's
  difference is as likely to have either sign; the one-sided p-value is the share of the
  2^n sign flips whose sum reaches the observed one, counted exactly by convolution. On
  0/1 outcomes this is McNemar's exact test (the discordant pairs, binomial at 1/2).
- ``fisher_greater_p``: Fisher's exact test of two success counts, one-sided; the fall-back
  when the episodes cannot be paired.
- ``kendall_tau_b``: rank agreement of two score lists, ties counted as in tau-b.
- ``welch_less_p``: Welch's t-test that one mean is lower than another, from each group's
  mean, standard deviation and size: the seed-aware test of Exp. 4's loss claims, whose
  ensembles record the mean and spread of their seeds' losses, not each seed's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from scipy.stats import t as student_t


def sign_flip_p(differences: Sequence[int]) -> float:
    """One-sided p-value of ``sum(differences) > 0`` under random signs (exact).

    ``differences``: one integer per pair (A's score minus B's, on a common scale).
    Pairs with difference 0 do not change the distribution. No pairs: p = 1.
    """
    magnitudes = [abs(int(d)) for d in differences if d != 0]
    observed = sum(int(d) for d in differences)
    if not magnitudes:
        return 1.0
    total = sum(magnitudes)
    # ways[s + total]: number of sign choices giving sum s
    ways = [0] * (2 * total + 1)
    ways[total] = 1
    for m in magnitudes:
        shifted = [0] * len(ways)
        for index, count in enumerate(ways):
            if count:
                shifted[index - m] += count
                shifted[index + m] += count
        ways = shifted
    at_least = sum(ways[observed + total :])
    return at_least / 2 ** len(magnitudes)


def fisher_greater_p(successes_a: int, episodes_a: int, successes_b: int, episodes_b: int) -> float:
    """Fisher's exact one-sided p-value that A's success rate exceeds B's.

    The probability, with the margins fixed, of A having at least ``successes_a`` of all
    the successes (hypergeometric tail).
    """
    for name, k, n in (("a", successes_a, episodes_a), ("b", successes_b, episodes_b)):
        if n <= 0 or not 0 <= k <= n:
            raise ValueError(f"fisher_greater_p: {name} has {k} successes of {n} episodes")
    total, successes = episodes_a + episodes_b, successes_a + successes_b
    denominator = math.comb(total, successes)
    top = min(successes, episodes_a)
    tail = sum(
        math.comb(episodes_a, k) * math.comb(episodes_b, successes - k)
        for k in range(successes_a, top + 1)
    )
    return tail / denominator


def kendall_tau_b(x: Sequence[float], y: Sequence[float]) -> float:
    """Kendall's tau-b of paired scores (``nan`` when either list is constant).

    tau-b = (concordant - discordant) / sqrt((n0 - ties_x) (n0 - ties_y)), n0 = n(n-1)/2,
    the same as ``scipy.stats.kendalltau``'s default.
    """
    if len(x) != len(y):
        raise ValueError(f"kendall_tau_b: {len(x)} scores against {len(y)}")
    if len(x) < 2:
        raise ValueError(f"kendall_tau_b: needs at least 2 pairs, got {len(x)}")
    concordant = discordant = ties_x = ties_y = 0
    for i in range(len(x)):
        for j in range(i + 1, len(x)):
            dx, dy = x[i] - x[j], y[i] - y[j]
            if dx == 0:
                ties_x += 1
            if dy == 0:
                ties_y += 1
            if dx * dy > 0:
                concordant += 1
            elif dx * dy < 0:
                discordant += 1
    pairs = len(x) * (len(x) - 1) // 2
    denominator = math.sqrt((pairs - ties_x) * (pairs - ties_y))
    return (concordant - discordant) / denominator if denominator else math.nan


def welch_less_p(
    mean_a: float, std_a: float, n_a: int, mean_b: float, std_b: float, n_b: int
) -> float:
    """Welch's one-sided p-value that group A's mean is below group B's.

    ``std_a``, ``std_b``: sample standard deviations (ddof = 1); ``n_a``, ``n_b``: group
    sizes, at least 2 each. The t statistic (mean_a - mean_b) / sqrt(s_a^2/n_a + s_b^2/n_b)
    against Student's t with the Welch-Satterthwaite degrees of freedom. Two groups without
    any spread: p = 0 if A is lower, else 1.
    """
    for name, n, std in (("a", n_a, std_a), ("b", n_b, std_b)):
        if n < 2:
            raise ValueError(f"welch_less_p: group {name} needs at least 2 values, got {n}")
        if not (math.isfinite(std) and std >= 0):
            raise ValueError(f"welch_less_p: group {name}'s standard deviation is {std}")
    var_a, var_b = std_a**2 / n_a, std_b**2 / n_b
    if var_a + var_b == 0:
        return 0.0 if mean_a < mean_b else 1.0
    t = (mean_a - mean_b) / math.sqrt(var_a + var_b)
    df = (var_a + var_b) ** 2 / (var_a**2 / (n_a - 1) + var_b**2 / (n_b - 1))
    return float(student_t.cdf(t, df))
