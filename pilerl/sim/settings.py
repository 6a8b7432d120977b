"""Environment settings: which simulator, and the constructor options it declares.

``EnvConfig`` names the simulator. Each installed simulator gets a subclass built from
its plugin's options dataclass (``settings_class``): the subclass's fields are exactly
the options the simulator declares, with their types and defaults, so Hydra checks
``env.soil=particles`` when it composes the config and rejects an option the simulator
does not take. ``register_env_configs`` stores them in Hydra's ConfigStore:

- ``env/<name>_schema``: the typed settings of simulator ``<name>`` (for YAML defaults);
- ``env/<name>``: the same, so ``env=<name>`` picks any installed simulator, unless
  ``conf/env/<name>.yaml`` exists (the pile loader's adds its condition and soil groups).

Recipes turn the settings into keyword arguments once (``make_kwargs``); a Python caller
may also build ``EnvConfig(simulator=...)`` alone, which means the simulator's defaults.
"""

from __future__ import annotations

import dataclasses
import functools
import typing
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from .plugin import SimulatorPlugin
from .registry import DEFAULT_SIMULATOR, UnknownSimulatorError, available_simulators, get_simulator


@dataclass
class EnvConfig:
    """Which simulator to build (``env.simulator``) and, in a simulator's own settings
    class, its declared constructor options (``env.condition``, ``env.soil`` ...).

    Attributes:
        simulator: plugin name (``pile_loader``, ``toy_cart``...); choose it with
            ``env=<name>`` so that the options follow.
    """

    simulator: str = DEFAULT_SIMULATOR

    # the simulator whose options a generated subclass holds (None: none, the base class)
    OPTIONS_OF: typing.ClassVar[str | None] = None

    def __post_init__(self) -> None:
        plugin = self.plugin()
        if self.OPTIONS_OF is not None and self.simulator != self.OPTIONS_OF:
            raise ValueError(
                f"env.simulator: {self.simulator!r} does not take the options of "
                f"{self.OPTIONS_OF!r} ({sorted(self.options())}); choose the simulator with "
                f"env={self.simulator} (its options: {plugin.option_names()})"
            )
        check_options(plugin, self.options())

    def plugin(self) -> SimulatorPlugin:
        """The simulator's declaration; an unknown name fails with the known ones."""
        try:
            return get_simulator(self.simulator)
        except UnknownSimulatorError as error:
            raise ValueError(f"env.simulator: {error}") from None

    def options(self) -> dict[str, Any]:
        """The declared options set here (none in the base class). A key added beside them
        (Hydra's ``+env.<key>=...`` lands as an attribute) fails with the declared ones."""
        names = [f.name for f in fields(self)]
        added = sorted(set(vars(self)) - set(names))
        if added:
            raise ValueError(
                f"env: simulator {self.simulator!r} has no option(s) {added}; "
                f"its options: {self.plugin().option_names()}"
            )
        return {name: getattr(self, name) for name in names if name != "simulator"}

    def make_kwargs(self, **overrides) -> dict[str, Any]:
        """Keyword arguments for ``pilerl.sim.make_gym_env`` (simulator name excluded):
        every declared option (its default unless set here), then ``overrides`` (e.g.
        ``control_hz=record_hz``), each checked against the options the simulator
        declares; lists become tuples."""
        plugin = self.plugin()
        plugin.check_options(overrides, where="env")
        defaults = dataclasses.asdict(plugin.options_class()())
        kwargs = {**defaults, **self.options(), **overrides}
        if overrides:
            check_options(plugin, kwargs)
        return {k: tuple(v) if isinstance(v, list) else v for k, v in kwargs.items()}


def check_options(plugin: SimulatorPlugin, options: Mapping[str, Any]) -> None:
    """Unknown options and bad values fail naming ``env.<option>``: the plugin's options
    dataclass checks the values (its messages start with the option's name)."""
    plugin.check_options(options, where="env")
    condition = options.get("condition")
    if condition is not None and condition not in plugin.conditions:
        raise ValueError(
            f"env.condition: unknown condition {condition!r} of simulator {plugin.name!r}; "
            f"known conditions: {list(plugin.conditions)}"
        )
    try:
        plugin.options_class()(**{k: _plain(v) for k, v in options.items()})
    except (TypeError, ValueError) as error:
        raise ValueError(f"env.{error}") from None


def _plain(value: Any) -> Any:
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


@functools.cache
def settings_class(name: str) -> type[EnvConfig]:
    """``EnvConfig`` with simulator ``name``'s declared options as typed fields (one class
    per simulator and process; picklable by name through this module's ``__getattr__``)."""
    plugin = get_simulator(name)
    options = plugin.options_class()
    hints = typing.get_type_hints(options)
    specs: list[tuple[str, Any, Any]] = [("simulator", str, field(default=name))]
    for option in fields(options):
        if option.name == "simulator":
            raise TypeError(f"simulator {name!r}: an option must not be called 'simulator'")
        if option.default is not dataclasses.MISSING:
            default = field(default=option.default)
        elif option.default_factory is not dataclasses.MISSING:
            default = field(default_factory=option.default_factory)
        else:
            raise TypeError(f"simulator {name!r}: option {option.name!r} needs a default")
        specs.append((option.name, hints[option.name], default))
    cls = dataclasses.make_dataclass(_class_name(name), specs, bases=(EnvConfig,))
    cls.OPTIONS_OF = name
    cls.__module__ = __name__
    cls.__doc__ = f"Settings of simulator {name!r}: ``{plugin.options}`` as config fields."
    return cls


def register_env_configs(*, yaml_names: Collection[str] = ()) -> None:
    """Store ``env/env_schema``, and ``env/<name>_schema`` and ``env/<name>`` of every
    installed simulator, in Hydra's ConfigStore; ``yaml_names`` are the simulators with
    their own ``conf/env/<name>.yaml`` (no ``env/<name>`` node then)."""
    from hydra.core.config_store import ConfigStore

    store = ConfigStore.instance()
    store.store(group="env", name="env_schema", node=EnvConfig)
    for name in available_simulators():
        cls = settings_class(name)
        store.store(group="env", name=f"{name}_schema", node=cls)
        if name not in yaml_names:
            store.store(group="env", name=name, node=cls)


def _class_name(simulator: str) -> str:
    return "".join(part.title() for part in simulator.replace("-", "_").split("_")) + "EnvConfig"


def __getattr__(attribute: str) -> type[EnvConfig]:
    """The generated settings classes by name (``PileLoaderEnvConfig``), for pickle."""
    for name in available_simulators():
        if _class_name(name) == attribute:
            return settings_class(name)
    raise AttributeError(f"module {__name__!r} has no attribute {attribute!r}")
