"""Operators: controllers that act from named sensor readings (scripted for now)."""

from .scripted import (
    PHASES,
    OperatorStyle,
    ScriptedScoopOperator,
    active_controls,
    phase_index,
    sample_style,
)

__all__ = [
    "PHASES",
    "OperatorStyle",
    "ScriptedScoopOperator",
    "active_controls",
    "phase_index",
    "sample_style",
]
