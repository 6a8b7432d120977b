"""The one registry of simulator plugins: the ``pilerl.simulators`` entry-point group.

A plugin package declares in its ``pyproject.toml``::

    [project.entry-points."pilerl.simulators"]
    my_sim = "my_package:PLUGIN"

where ``PLUGIN`` is a mapping with the fields of :class:`~pilerl.sim.plugin.SimulatorPlugin`
(name, gym_id, entry_point, its words, options and expert), so a plugin needs nothing from
pilerl to declare itself. pilerl never imports a plugin's internals: it loads the
declaration, registers ``gym_id`` with Gymnasium, and lets Gymnasium import
``entry_point`` when an env is made.
"""

from __future__ import annotations

import functools
from importlib.metadata import entry_points

import gymnasium as gym

from .plugin import SimulatorPlugin

ENTRY_POINT_GROUP = "pilerl.simulators"
DEFAULT_SIMULATOR = "pile_loader"


class UnknownSimulatorError(KeyError):
    """Raised for a simulator name no installed plugin provides."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


@functools.cache
def _plugins() -> dict[str, SimulatorPlugin]:
    found: dict[str, SimulatorPlugin] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        plugin = SimulatorPlugin.from_declaration(ep.load(), where=f"entry point {ep.value!r}")
        if plugin.name != ep.name:
            raise ValueError(
                f"entry point {ep.name!r} declares a plugin named {plugin.name!r}; "
                "the two names must match"
            )
        found[ep.name] = plugin
    return found


def refresh_simulators() -> None:
    """Read the installed plugins again (after installing one into a running process)."""
    _plugins.cache_clear()


def available_simulators() -> list[str]:
    """Names of all installed simulator plugins, sorted."""
    return sorted(_plugins())


def get_simulator(name: str) -> SimulatorPlugin:
    """The plugin called ``name``; unknown names fail with the list of known ones."""
    plugins = _plugins()
    if name not in plugins:
        raise UnknownSimulatorError(
            f"unknown simulator {name!r}; known simulators: {sorted(plugins)} "
            f"(plugins register under the {ENTRY_POINT_GROUP!r} entry-point group)"
        )
    return plugins[name]


def register_gymnasium_envs() -> None:
    """Register every plugin's ``gym_id`` with Gymnasium (idempotent)."""
    for plugin in _plugins().values():
        if plugin.gym_id not in gym.registry:
            gym.register(
                id=plugin.gym_id, entry_point=plugin.entry_point, disable_env_checker=False
            )


def make_gym_env(name: str = DEFAULT_SIMULATOR, **kwargs) -> gym.Env:
    """``gymnasium.make`` the simulator called ``name`` with its keyword arguments."""
    plugin = get_simulator(name)
    register_gymnasium_envs()
    return gym.make(plugin.gym_id, **kwargs)
