"""Simulator plugins: discovery by name, Gymnasium registration, TorchRL wrapping."""

from .plugin import SimulatorPlugin
from .registry import (
    DEFAULT_SIMULATOR,
    UnknownSimulatorError,
    available_simulators,
    get_simulator,
    make_gym_env,
    register_gymnasium_envs,
)
from .torchrl_env import make_torchrl_env

__all__ = [
    "DEFAULT_SIMULATOR",
    "SimulatorPlugin",
    "UnknownSimulatorError",
    "available_simulators",
    "get_simulator",
    "make_gym_env",
    "make_torchrl_env",
    "register_gymnasium_envs",
]
