"""Operators as TensorDict modules: one operator per batch element, acting like an actor.

``OperatorModule`` is the policy of a rollout (``pilerl.sim.rollout``) over a batched
simulator env (batch ``[N]``): at each step, operator ``i`` reads row ``i``'s sensors and
writes

| key | shape | dtype | meaning |
|---|---|---|---|
| ``action`` | [N, A] | float32 | the EXECUTED command (what the simulator is stepped with) |
| ``action_label`` | [N, A] | float32 | the clean command (the operator's ``last_label``, or |
|  |  |  | the executed command when it has none): the demonstration's label |
| ``phase`` | [N] | int64 | index of the operator's phase in its ``PHASES``, after acting |

``phase`` is written only when every operator names its phase. Rows that TorchRL's
partial-step mask ``_step`` marks as ended are not acted on (their operators are not
advanced; the rollout keeps those rows as they were).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from pilerl.sim.rollout import sensor_names
from pilerl.sim.torchrl_env import SimulatorBatchEnv

ACTION_KEY = "action"
LABEL_KEY = "action_label"
PHASE_KEY = "phase"
PARTIAL_STEP_KEY = "_step"  # TorchRL's mask of the sub-envs a partial step steps


class Operator(Protocol):
    """What an operator offers (see ``docs/demonstrations.md``)."""

    phase: str

    def reset(self) -> None: ...

    def act(self, sensors: Mapping[str, np.ndarray]) -> np.ndarray: ...


def operator_phases(operator: Operator) -> tuple[str, ...]:
    """The operator's phase names (its ``PHASES``; none for an operator without phases)."""
    return tuple(getattr(operator, "PHASES", ()))


class OperatorModule(TensorDictModuleBase):
    """``operators[i]`` acts for batch element ``i``; see the module docstring for the keys.

    Args:
        operators: one operator per batch element (``reset``, ``act``, optional ``phase``,
            ``PHASES`` and ``last_label``).
        sensors: the sensor keys the operators read (each [N, 1]).
        action_dim: number of controls.
    """

    def __init__(self, operators: Sequence[Operator], *, sensors: Sequence[str], action_dim: int):
        super().__init__()
        if not operators:
            raise ValueError("OperatorModule: needs at least one operator")
        self.operators = list(operators)
        self.sensors = list(sensors)
        self.action_dim = int(action_dim)
        self.names_phases = all(hasattr(op, "phase") for op in self.operators)
        self.in_keys = list(self.sensors)
        self.out_keys = [ACTION_KEY, LABEL_KEY, *([PHASE_KEY] if self.names_phases else [])]

    @classmethod
    def for_env(cls, operators: Sequence[Operator], env: SimulatorBatchEnv) -> OperatorModule:
        """``operators`` acting on the simulators of ``env`` (reading all its sensors)."""
        return cls(operators, sensors=sensor_names(env), action_dim=env.action_spec.shape[-1])

    def reset(self) -> None:
        """Reset every operator (before an episode)."""
        for operator in self.operators:
            operator.reset()

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        n = len(self.operators)
        if tuple(tensordict.batch_size) != (n,):
            raise ValueError(
                f"OperatorModule: holds {n} operators but got a tensordict of batch size "
                f"{tuple(tensordict.batch_size)}; expected ({n},)"
            )
        readings = {name: tensordict.get(name).detach().cpu().numpy() for name in self.sensors}
        active = tensordict.get(PARTIAL_STEP_KEY, None)
        executed = np.zeros((n, self.action_dim), dtype=np.float32)
        labels = np.zeros((n, self.action_dim), dtype=np.float32)
        phases = np.zeros(n, dtype=np.int64)
        for i, operator in enumerate(self.operators):
            if active is not None and not bool(active[i]):
                continue  # this sub-env has ended: its row is not stepped
            command = np.asarray(
                operator.act({name: values[i] for name, values in readings.items()}),
                dtype=np.float32,
            )
            executed[i] = command
            label = getattr(operator, "last_label", None)
            labels[i] = command if label is None else np.asarray(label, dtype=np.float32)
            if self.names_phases:
                phases[i] = operator_phases(operator).index(operator.phase)
        tensordict.set(ACTION_KEY, torch.from_numpy(executed))
        tensordict.set(LABEL_KEY, torch.from_numpy(labels))
        if self.names_phases:
            tensordict.set(PHASE_KEY, torch.from_numpy(phases))
        return tensordict
