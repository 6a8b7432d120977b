"""The toy cart's constructor options (a plain dataclass pilerl reads)."""

from __future__ import annotations

import math
from dataclasses import dataclass

CONDITIONS = {  # name -> (mass [kg], constant opposing force [N])
    "nominal": (10.0, 0.0),
    "heavy": (25.0, 0.0),
    "headwind": (10.0, 4.0),
}


@dataclass
class ToyCartOptions:
    """Keyword options of ``ToyCartEnv``.

    Attributes:
        condition: ``nominal``, ``heavy`` or ``headwind``.
        control_hz: control rate [Hz].
    """

    condition: str = "nominal"
    control_hz: float = 20.0

    def __post_init__(self) -> None:
        if self.condition not in CONDITIONS:
            raise ValueError(
                f"condition: unknown condition {self.condition!r}; "
                f"known conditions: {sorted(CONDITIONS)}"
            )
        if not (math.isfinite(self.control_hz) and 1.0 <= self.control_hz <= 1000.0):
            raise ValueError(f"control_hz: must lie in [1, 1000] Hz, got {self.control_hz}")
