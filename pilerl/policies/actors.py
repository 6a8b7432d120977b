"""Controllers as TorchRL actors: ``TensorDictModule``s reading sensors by name.

An actor reads every sensor key of its config (each [..., 1]) and writes

| key | shape | written by |
|---|---|---|
| ``action`` | [..., n_u] | every controller, in [-1, 1] |
| ``action_loc`` | [..., n_u] | neural controllers: u' with action = tanh(u') |
| ``input_mask`` | [..., n_s] | ANNet, DANNet: softmax over the controller inputs s |
| ``output_mask`` | [..., n_u] | DANNet: softmax over the controls |

It works on unbatched (``batch_size=[]``) and batched tensordicts alike.
"""

from __future__ import annotations

from collections.abc import Sequence

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
