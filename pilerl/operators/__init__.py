"""Operators: controllers that act from named sensor readings.

A simulator ships its own scripted expert (its plugin's ``scripted_expert``, built by
``pilerl.sim.get_simulator(name).make_expert``); this package holds what runs any operator.

| module | what |
|---|---|
| ``module`` | ``OperatorModule``: one operator per batch element as a TensorDict module |
| ``keyboard`` | ``KeyboardOperator`` for teleoperation |
"""

from .module import OperatorModule, operator_phases

__all__ = ["OperatorModule", "operator_phases"]
