"""Simulator plugins: discovery by name, their declared words, env settings, Gymnasium
registration, TorchRL wrapping (docs/simulator_plugins.md)."""

from .plugin import ALL_CONDITIONS, SensorSpec, SimulatorPlugin
from .registry import (
    DEFAULT_SIMULATOR,
    UnknownSimulatorError,
    available_simulators,
    get_simulator,
    make_gym_env,
    refresh_simulators,
    register_gymnasium_envs,
)
from .settings import EnvConfig, settings_class
from .torchrl_env import make_torchrl_env

__all__ = [
    "ALL_CONDITIONS",
    "DEFAULT_SIMULATOR",
    "EnvConfig",
    "SensorSpec",
    "SimulatorPlugin",
    "UnknownSimulatorError",
    "available_simulators",
    "get_simulator",
    "make_gym_env",
    "make_torchrl_env",
    "refresh_simulators",
    "register_gymnasium_envs",
    "settings_class",
]
