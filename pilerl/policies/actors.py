"""Controllers as TorchRL actors: ``TensorDictModule``s reading sensors by name.

An actor reads every sensor key of its config (each [..., 1]) and writes

| key | shape | written by |
|---|---|---|
| ``action`` | [..., n_u] | every controller, in [-1, 1] |
| ``action_loc`` | [..., n_u] | neural controllers: u' with action = tanh(u') |
| ``input_mask`` | [..., n_s] | ANNet, DANNet: softmax over the controller inputs s |
| ``output_mask`` | [..., n_u] | DANNet: softmax over the controls |

It works on unbatched (``batch_size=[]``) and batched tensordicts alike.

``inference_actor`` gives the same actor for acting only (evaluation, deployment): a
frozen TorchScript trace of the policy behind a thin ``TensorDictModule`` that reads the
sensor keys and writes the outputs, without the generic module's dispatch. On one
observation it answers about twice as fast as the ``TensorDictModule`` actor
(``benchmarks/actor_latency.py``) with bit-identical outputs.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule

from .policy import ACTION_KEY, SensorPolicy
from .random_forest import RandomForestController
from .registry import make_controller


class RandomForestActor(TensorDictModule):
    """The random-forest actor: a ``TensorDictModule`` that can also ``fit`` itself."""

    def fit(self, data: TensorDictBase) -> RandomForestActor:
        """Fit the forest on a tensordict [N] holding the sensor keys and ``action``."""
        policy: SensorPolicy = self.module
        s, _ = policy.controller_inputs(data)
        policy.controller.fit(s, data[ACTION_KEY])
        return self


def policy_actor(policy: SensorPolicy) -> TensorDictModule:
    """Wrap an existing ``SensorPolicy`` (its parameters are shared, not copied)."""
    cls = (
        RandomForestActor
        if isinstance(policy.controller, RandomForestController)
        else TensorDictModule
    )
    return cls(policy, in_keys=policy.in_keys, out_keys=policy.out_keys)


def make_actor(
    name: str,
    *,
    sensors: Sequence[str],
    stats: dict,
    attention_sensors: Sequence[str] | None = None,
    options: dict | None = None,
) -> TensorDictModule:
    """A freshly initialised actor for controller ``name`` (see ``make_controller``).

    ``rf`` gives a ``RandomForestActor`` to ``fit`` before use.
    """
    return policy_actor(
        make_controller(
            name,
            sensors=sensors,
            stats=stats,
            attention_sensors=attention_sensors,
            options=options,
        )
    )


def actor_policy(actor: TensorDictModule | SensorPolicy) -> SensorPolicy:
    """The ``SensorPolicy`` inside an actor made by ``make_actor`` / ``policy_actor``."""
    policy = actor.module if isinstance(actor, TensorDictModule) else actor
    if not isinstance(policy, SensorPolicy):
        raise TypeError(
            f"expected an actor made by pilerl.policies.make_actor, got {type(actor).__name__}"
        )
    return policy


INFERENCE_CHECK_ROWS = (1, 5)  # batch sizes the trace is checked at against the module
_ONE_READING = torch.Size([1])


class InferenceActor(TensorDictModule):
    """A frozen, traced copy of a neural actor, for acting only (see ``inference_actor``).

    ``forward(tensordict)`` reads the sensor keys, runs the traced graph without autograd
    and writes ``out_keys`` into the same tensordict. Its weights are a snapshot: training
    the actor it was made from afterwards does not change it.
    """

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:  # type: ignore[override]
        readings = [tensordict.get(key) for key in self.in_keys]
        for key, value in zip(self.in_keys, readings, strict=True):
            if value.shape[-1:] != _ONE_READING:
                raise ValueError(
                    f"InferenceActor: sensor {key!r} must have shape [..., 1], got "
                    f"{tuple(value.shape)}"
                )
        with torch.no_grad():
            values = self.module(*readings)
        for key, value in zip(self.out_keys, values, strict=True):
            tensordict.set(key, value)
        return tensordict


def inference_actor(actor: TensorDictModule | SensorPolicy) -> InferenceActor:
    """The actor traced (``torch.jit.trace``) and frozen in eval mode, for acting only.

    The trace is checked against the module on readings spread over each sensor's range
    (one row and a batch): its outputs must be bit-identical, else ``ValueError``. The
    random forest is refused (its trees are not traced).
    """
    policy = actor_policy(actor)
    if isinstance(policy.controller, RandomForestController):
        raise ValueError("inference_actor: the random forest is not traced; use its actor")
    policy = copy.deepcopy(policy).eval()
    example = example_readings(policy, 2)
    with torch.no_grad(), warnings.catch_warnings():
        # the shape checks in SensorPolicy are Python, not traced: InferenceActor checks
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        # torch 2.13 deprecates jit in favour of torch.compile, which on the CPU needs a
        # C++ toolchain at run time and compiles for seconds; a trace is enough here
        warnings.filterwarnings("ignore", "`torch.jit", DeprecationWarning)
        graph = torch.jit.freeze(torch.jit.trace(policy, example, check_trace=False))
        for rows in INFERENCE_CHECK_ROWS:
            readings = example_readings(policy, rows, seed=rows)
            cases = [(f"{rows} row(s)", readings)]
            if rows == 1:  # also one unbatched reading [1] per sensor, as RowByRow sends
                cases.append(("one unbatched reading", tuple(r[0] for r in readings)))
            for what, inputs in cases:
                expected, traced = policy(*inputs), graph(*inputs)
                if not all(_same(a, b) for a, b in zip(expected, traced, strict=True)):
                    raise ValueError(
                        f"inference_actor: the traced {policy.config.controller!r} differs "
                        f"from the module on {what}; use the TensorDictModule actor"
                    )
    return InferenceActor(graph, in_keys=policy.in_keys, out_keys=policy.out_keys)


def _same(expected: torch.Tensor, traced: torch.Tensor) -> bool:
    """Bit-identical outputs, NaN where the module gives NaN (a diverged actor's NaN
    outputs are the module's too; acting then fails where the simulator checks actions)."""
    return torch.equal(expected.isnan(), traced.isnan()) and torch.equal(
        expected.nan_to_num(0.0), traced.nan_to_num(0.0)
    )


def example_readings(policy: SensorPolicy, rows: int, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """Readings [rows, 1] per sensor spread over its recorded range (mean +- 3 std), for
    tracing, exporting and checking a policy."""
    generator = torch.Generator().manual_seed(seed)
    mean, std = policy.normalizer.mean, policy.normalizer.std
    values = mean + 3 * std * (2 * torch.rand(rows, len(mean), generator=generator) - 1)
    return tuple(values[:, i : i + 1].contiguous() for i in range(len(mean)))
