"""The one place that builds the scripted expert (the operator that records demonstrations).

Recording, the scripted evaluation baseline and the rollout tests all build their operator
here. Today it is ``ScriptedScoopOperator`` with a style from ``sample_style``; when the
simulator plugin declares its own expert (``make_expert`` in the plugin, see
``docs/simulator_plugins.md``), this function is the one line to point at it.
"""

from __future__ import annotations

import numpy as np

from .scripted import OperatorStyle, ScriptedScoopOperator, sample_style

EXPERT_OPTIONS = ("style", "trigger_sensor", "mistake_rate")


def make_scripted_expert(
    *, dt: float, rng: np.random.Generator | None = None, **options
) -> ScriptedScoopOperator:
    """The scripted expert acting every ``dt`` seconds.

    Args:
        dt: control period [s].
        rng: ``None``: the nominal operator (``style`` if given, else ``OperatorStyle()``);
            a generator: one operator style drawn from it (``sample_style``).
        options: ``style`` (an ``OperatorStyle``, only without ``rng``), ``trigger_sensor``
            and ``mistake_rate`` (for drawn styles, see ``sample_style``).
    """
    unknown = sorted(set(options) - set(EXPERT_OPTIONS))
    if unknown:
        raise ValueError(
            f"make_scripted_expert: unknown option(s) {unknown}; known: {list(EXPERT_OPTIONS)}"
        )
    style = options.get("style")
    if rng is None:
        return ScriptedScoopOperator(style or OperatorStyle(), dt=dt)
    if style is not None:
        raise ValueError("make_scripted_expert: give a style or an rng to draw one, not both")
    drawn = sample_style(
        rng,
        mistake_rate=options.get("mistake_rate", 0.28),
        trigger_sensor=options.get("trigger_sensor", "drive_pressure"),
    )
    return ScriptedScoopOperator(drawn, dt=dt)
