"""Operators: controllers that act from named sensor readings (scripted for now).

| module | what |
|---|---|
| ``scripted`` | ``ScriptedScoopOperator``, its ``OperatorStyle`` and ``sample_style`` |
| ``expert`` | ``make_scripted_expert``: the one factory of the scripted expert |
| ``module`` | ``OperatorModule``: one operator per batch element as a TensorDict module |
| ``keyboard`` | ``KeyboardOperator`` for teleoperation |
"""

from .expert import make_scripted_expert
from .module import OperatorModule, operator_phases
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
    "OperatorModule",
    "OperatorStyle",
    "ScriptedScoopOperator",
    "active_controls",
    "make_scripted_expert",
    "operator_phases",
    "phase_index",
    "sample_style",
]
