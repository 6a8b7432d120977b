"""Statistics of closed-loop results."""

from __future__ import annotations

import math
from statistics import NormalDist


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
