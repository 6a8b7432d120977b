"""Controllers learned from demonstrations and their TorchRL actor wrappers.

| module | what |
|---|---|
| ``controllers`` | ``NNet`` (Halbach et al. 2019), ``NNetV2`` (revised paper) |
| ``attention`` | ``ANNet``, ``DANNet`` (revised paper) |
| ``random_forest`` | ``RandomForestController`` (Yang et al. 2020) |
| ``normalization`` | ``InputNormalizer``: per-sensor z-score buffers |
| ``config`` | ``ActorConfig``: what a checkpoint rebuilds an actor from |
| ``policy`` | ``SensorPolicy``: sensor keys -> normalised s, s' -> controller |
| ``registry`` | ``make_controller`` and the registered names |
| ``settings`` | ``PolicyConfig``, ``SensorsConfig``: the policy and sensors config groups |
| ``actors`` | ``make_actor``: a ``TensorDictModule`` writing ``action`` (+ masks) |
| ``stochastic`` | ``make_stochastic_actor``: ``ProbabilisticActor`` + ``TanhNormal`` for RL |
| ``collection_policy`` | ``FusedTanhNormalPolicy``: that actor's sampling in one forward |
| ``levenberg_marquardt`` | ``fit_lm`` |
| ``checkpoint`` | ``save_actor`` / ``load_actor`` (no pickle code execution) |

See docs/controllers.md.
"""

from .actors import RandomForestActor, actor_policy, make_actor, policy_actor
from .attention import ANNet, AttentionNet, DANNet
from .checkpoint import CheckpointError, load_actor, save_actor
from .config import ActorConfig
from .controllers import Controller, ControllerOutput, NNet, NNetV2
from .levenberg_marquardt import fit_lm
from .normalization import InputNormalizer
from .policy import ACTION_KEY, ACTION_LOC_KEY, INPUT_MASK_KEY, OUTPUT_MASK_KEY, SensorPolicy
from .random_forest import RandomForestController
from .registry import (
    CONTROLLERS,
    NEURAL_CONTROLLERS,
    ControllerSpec,
    UnknownControllerError,
    available_controllers,
    build_policy,
    controller_inputs,
    get_spec,
    make_controller,
)
from .stochastic import ACTION_SCALE_KEY, BC_ACTION_KEY, make_stochastic_actor

__all__ = [
    "ACTION_KEY",
    "ACTION_LOC_KEY",
    "ACTION_SCALE_KEY",
    "ANNet",
    "BC_ACTION_KEY",
    "CONTROLLERS",
    "INPUT_MASK_KEY",
    "NEURAL_CONTROLLERS",
    "OUTPUT_MASK_KEY",
    "ActorConfig",
    "AttentionNet",
    "CheckpointError",
    "Controller",
    "ControllerOutput",
    "ControllerSpec",
    "DANNet",
    "InputNormalizer",
    "NNet",
    "NNetV2",
    "RandomForestActor",
    "RandomForestController",
    "SensorPolicy",
    "UnknownControllerError",
    "actor_policy",
    "available_controllers",
    "build_policy",
    "controller_inputs",
    "fit_lm",
    "get_spec",
    "load_actor",
    "make_actor",
    "make_controller",
    "make_stochastic_actor",
    "policy_actor",
    "save_actor",
]
