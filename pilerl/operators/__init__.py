"""Operators: controllers that act from named sensor readings (scripted for now)."""

from .scripted import OperatorStyle, ScriptedScoopOperator

__all__ = ["OperatorStyle", "ScriptedScoopOperator"]
