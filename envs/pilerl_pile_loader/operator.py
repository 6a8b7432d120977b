"""TEMPORARY: the pile loader's scripted expert behind the ``make_expert`` interface.

This thin adapter wraps today's ``pilerl.operators.scripted`` so that every caller can
reach the expert through the plugin declaration (``scripted_expert``). The operator
helper's ``operator.py`` replaces this file at merge time (it must not import pilerl).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from pilerl.operators.scripted import (
    PHASES,
    OperatorStyle,
    ScriptedScoopOperator,
    sample_style,
)

DRAW_OPTIONS = {"mistake_rate": 0.28, "overlap_rate": 0.6}  # options of a drawn style
STYLE_OPTIONS = [f.name for f in dataclasses.fields(OperatorStyle)]


class ScriptedExpert(ScriptedScoopOperator):
    """``ScriptedScoopOperator`` with the ``Operator`` interface's ``PHASES`` and
    ``last_label`` (here always the executed command)."""

    PHASES = PHASES

    def act(self, sensors: Mapping[str, float]) -> np.ndarray:
        self.last_label = super().act(sensors)
        return self.last_label


def make_expert(*, dt: float, rng: np.random.Generator | None = None, **options) -> ScriptedExpert:
    """The nominal operator (``rng=None``; options: ``OperatorStyle`` fields) or one style
    drawn from ``rng`` (options: ``trigger_sensor``, ``mistake_rate``, ``overlap_rate``)."""
    known = ["trigger_sensor", *DRAW_OPTIONS] if rng is not None else STYLE_OPTIONS
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ValueError(f"pile loader expert: unknown option(s) {unknown}; known: {known}")
    if rng is None:
        return ScriptedExpert(OperatorStyle(**options), dt=dt)
    drawn = {**DRAW_OPTIONS, "trigger_sensor": "drive_pressure", **options}
    rate = drawn["mistake_rate"]
    if not (isinstance(rate, int | float) and 0.0 <= rate <= 1.0):
        raise ValueError(f"mistake_rate: must lie in [0, 1], got {drawn['mistake_rate']!r}")
    if drawn["trigger_sensor"] not in ("drive_pressure", "telescope_pressure"):
        raise ValueError(
            "trigger_sensor: must be drive_pressure or telescope_pressure, "
            f"got {drawn['trigger_sensor']!r}"
        )
    return ScriptedExpert(sample_style(rng, **drawn), dt=dt)
