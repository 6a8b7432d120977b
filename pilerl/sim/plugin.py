"""What a simulator plugin declares: how pilerl builds it, and its words.

A plugin's ``PLUGIN`` is a plain mapping (the plugin imports nothing from pilerl);
``SimulatorPlugin.from_declaration`` checks it once, when the registry loads it. The core
reads a simulator's words from here (sensor units and ranges, controls, conditions and
their groups, reward parts, the ``info`` keys of success and fill) and never spells a
plugin's own names. Heavy things (the env class, its options dataclass, its scripted
expert, its episode rules) are named as ``module:attribute`` strings and imported only
when used.

What an evaluation says about an episode beyond success and fill is the simulator's too:
the ``info`` entries it reports (``episode_info``, with units), its failure modes, and
optionally its own rules turning an episode into record columns (``episode_columns``)
and records into summary numbers (``summary_columns``). Without them an evaluation
records the last value of each declared ``info`` entry and names a failure ``failed``.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

_GYM_ID = re.compile(r"^[\w.-]+/[\w.-]+-v\d+$")
_ENTRY_POINT = re.compile(r"^[\w.]+:[\w]+$")
_NAME = re.compile(r"^[A-Za-z_][\w-]*$")

ALL_CONDITIONS = "all"  # the group every simulator has: all its conditions, in declared order
SUCCESS = "success"  # the failure mode of an episode that succeeded
FAILED = "failed"  # the one failure mode of a simulator that declares none
# A group a simulator may declare: conditions for a condition-shift test, only where named
# (never in ``all`` nor in the default evaluation groups, so nothing trains on them unasked)
HELD_OUT_GROUP = "held_out"
CHECK_PERIOD_S = 0.05  # control period [s] of the expert built only to check its options
REQUIRED_FIELDS = ("name", "gym_id", "entry_point", "sensors", "controls", "conditions", "options")


@dataclass(frozen=True)
class SensorSpec:
    """One sensor a simulator declares.

    Attributes:
        unit: physical unit of the reading (``rad``, ``MPa``, ``m/s``...).
        low, high: range of the reading, in ``unit``.
    """

    unit: str
    low: float
    high: float


def resolve(reference: str) -> Any:
    """The object named by ``module:attribute`` (imported now)."""
    module, _, attribute = reference.partition(":")
    return getattr(importlib.import_module(module), attribute)


@dataclass(frozen=True)
class SimulatorPlugin:
    """A simulator, as seen by pilerl's core.

    Attributes:
        name: registry name (``pile_loader``), what configs say (``env=pile_loader``).
        gym_id: Gymnasium id it is registered under, ``namespace/Name-vN``.
        entry_point: ``module:Class`` of the ``gymnasium.Env``; imported only on make.
        sensors: sensor name -> ``SensorSpec`` (unit, low, high); the env's ``Dict``
            observation has exactly these keys (in Gymnasium's order, sorted by name).
        controls: names of the action's components, in order.
        conditions: condition name -> one-line description; the env's constructor takes
            ``condition=<name>``.
        options: ``module:Class`` of a plain dataclass whose fields are the constructor's
            keyword options (with their types and defaults); it includes ``condition``.
            Configs may set exactly these.
        condition_groups: group name -> member conditions (the pile loader: ``winter`` =
            ``winter_a`` .. ``winter_d``); ``all`` is every condition outside the group
            ``held_out`` (if declared) and is implicit.
        reward_parts: ``info`` keys of the named parts the reward is the sum of.
        success_key: ``info`` key of the episode's success (a bool at the last step).
        fill_key: ``info`` key of the episode's main score in [0, 1] (the pile loader's
            bucket fill); ``None``: the success as 0 or 1.
        scripted_expert: ``module:function`` building the scripted expert,
            ``make_expert(*, dt, rng=None, **options)`` (see docs/simulator_plugins.md);
            ``None``: no expert (nothing to record demonstrations with).
        expert_revision: the scripted expert's default behaviour, numbered: raise it when
            that behaviour changes (the pile loader's 1: the stall cue and the second push
            of session 33), and a demonstration store recorded by the earlier expert is not
            resumed by the new one (``pilerl.data.recorder.claim_plan``); default 0.
        renders: the env takes ``render_mode="rgb_array"``, ``render_size`` and ``camera``
            (videos); ``False``: recipes make no videos of it.
        episode_info: ``info`` key -> unit of the entries an evaluation records from every
            step besides success and fill (the pile loader: ``cutting_depth_m`` [m],
            ``tipped`` [bool] ...); ``bool`` marks a flag.
        failure_modes: names of the ways an episode fails (the pile loader:
            ``early_boom_rise``, ``no_boom_rise`` ...); every evaluation summary counts
            each one. Default: ``failed``.
        episode_columns: ``module:function`` turning one evaluated episode into the
            simulator's columns of its record, ``failure_mode`` among them (see
            ``docs/simulator_plugins.md``); ``None``: the last value of each
            ``episode_info`` entry, and ``failed`` for a failure.
        summary_columns: ``module:function`` turning a list of records into the
            simulator's numbers of their summary (the pile loader: mean slip, spill and
            time to fill); ``None``: none.
        curriculum: mixture ``{condition or group: weight}`` that fine-tuning practises by
            default (``curriculum=default``); the pile loader: ``winter`` and ``summer``.
            Default: every condition, weight 1.
        example_conditions: conditions (or groups) ``recipes/scoop.py`` shows by default,
            one scripted episode each; default: the first declared condition.
        report_notes: Markdown lines ``recipes/scoop.py`` adds to its report (how to read
            the numbers); default: none.
        description: one line for listings.
    """

    name: str
    gym_id: str
    entry_point: str
    sensors: Mapping[str, SensorSpec]
    controls: tuple[str, ...]
    conditions: Mapping[str, str]
    options: str
    condition_groups: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    reward_parts: tuple[str, ...] = ()
    success_key: str = "success"
    fill_key: str | None = None
    scripted_expert: str | None = None
    expert_revision: int = 0
    renders: bool = False
    episode_info: Mapping[str, str] = field(default_factory=dict)
    failure_modes: tuple[str, ...] = (FAILED,)
    episode_columns: str | None = None
    summary_columns: str | None = None
    curriculum: Mapping[str, float] = field(default_factory=lambda: {ALL_CONDITIONS: 1.0})
    example_conditions: tuple[str, ...] = ()
    report_notes: tuple[str, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        where = f"SimulatorPlugin({self.name!r})"
        if not _GYM_ID.match(self.gym_id):
            raise ValueError(f"{where}.gym_id: expected 'namespace/Name-vN', got {self.gym_id!r}")
        for key in (
            "entry_point",
            "options",
            "scripted_expert",
            "episode_columns",
            "summary_columns",
        ):
            value = getattr(self, key)
            if value is not None and not (isinstance(value, str) and _ENTRY_POINT.match(value)):
                raise ValueError(f"{where}.{key}: expected 'module:attribute', got {value!r}")
        object.__setattr__(self, "sensors", _sensor_specs(self.sensors, f"{where}.sensors"))
        object.__setattr__(self, "controls", _names(self.controls, f"{where}.controls"))
        if not isinstance(self.conditions, Mapping):
            raise ValueError(f"{where}.conditions: expected a mapping name -> description")
        _names(list(self.conditions), f"{where}.conditions")
        object.__setattr__(self, "conditions", {str(k): str(v) for k, v in self.conditions.items()})
        groups = {}
        for group, members in dict(self.condition_groups).items():
            members = _names(members, f"{where}.condition_groups.{group}")
            unknown = [m for m in members if m not in self.conditions]
            if group in self.conditions or group == ALL_CONDITIONS or unknown:
                raise ValueError(
                    f"{where}.condition_groups.{group}: a group must not reuse a condition "
                    f"name or {ALL_CONDITIONS!r}, and its members must be conditions "
                    f"{list(self.conditions)}; unknown members {unknown}"
                )
            groups[str(group)] = members
        object.__setattr__(self, "condition_groups", groups)
        object.__setattr__(self, "reward_parts", _names(self.reward_parts, f"{where}.reward_parts"))
        if isinstance(self.expert_revision, bool) or not (
            isinstance(self.expert_revision, int) and self.expert_revision >= 0
        ):
            raise ValueError(
                f"{where}.expert_revision: expected an integer >= 0, got {self.expert_revision!r}"
            )
        self._check_evaluation_words(where)

    def _check_evaluation_words(self, where: str) -> None:
        """``episode_info``, ``failure_modes``, ``curriculum``, ``example_conditions`` and
        ``report_notes`` are well formed and name declared conditions."""
        if not isinstance(self.episode_info, Mapping):
            raise ValueError(f"{where}.episode_info: expected a mapping info key -> unit")
        _names(list(self.episode_info), f"{where}.episode_info")
        info = {str(k): str(v) for k, v in self.episode_info.items()}
        clash = sorted({self.success_key, self.fill_key} & set(info))
        if clash:
            raise ValueError(
                f"{where}.episode_info: {clash} are the success or fill key, recorded anyway"
            )
        object.__setattr__(self, "episode_info", info)
        modes = _names(self.failure_modes, f"{where}.failure_modes")
        if not modes or SUCCESS in modes:
            raise ValueError(
                f"{where}.failure_modes: need at least one name, and {SUCCESS!r} is not a "
                f"failure; got {list(modes)}"
            )
        object.__setattr__(self, "failure_modes", modes)
        if not isinstance(self.curriculum, Mapping) or not self.curriculum:
            raise ValueError(f"{where}.curriculum: expected a mapping condition -> weight")
        curriculum = {str(k): float(v) for k, v in self.curriculum.items()}
        if not all(math.isfinite(w) and w >= 0 for w in curriculum.values()) or not any(
            curriculum.values()
        ):
            raise ValueError(
                f"{where}.curriculum: weights must be finite, >= 0 and not all 0, got {curriculum}"
            )
        object.__setattr__(self, "curriculum", curriculum)
        self.resolve_mixture(curriculum, where=f"{where}.curriculum")
        examples = _names(self.example_conditions, f"{where}.example_conditions")
        self.resolve_conditions(examples, where=f"{where}.example_conditions")
        object.__setattr__(self, "example_conditions", examples or (next(iter(self.conditions)),))
        if isinstance(self.report_notes, str) or not all(
            isinstance(line, str) for line in self.report_notes
        ):
            raise ValueError(f"{where}.report_notes: expected a list of Markdown lines")
        object.__setattr__(self, "report_notes", tuple(self.report_notes))

    @classmethod
    def from_declaration(cls, declaration: object, *, where: str) -> SimulatorPlugin:
        """Validate a plugin's ``PLUGIN`` mapping; errors name the entry point and field."""
        if isinstance(declaration, cls):
            return declaration
        if not isinstance(declaration, Mapping):
            raise TypeError(f"{where}: PLUGIN must be a mapping, got {type(declaration).__name__}")
        known = [f.name for f in fields(cls)]
        missing = [k for k in REQUIRED_FIELDS if k not in declaration]
        unknown = sorted(set(declaration) - set(known))
        if missing or unknown:
            raise ValueError(
                f"{where}: PLUGIN missing fields {missing}, unknown fields {unknown}; "
                f"expected {known} (docs/simulator_plugins.md)"
            )
        try:
            return cls(**declaration)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{where}: {error}") from None

    # ------------------------------------------------------------------ words
    @property
    def sensor_units(self) -> dict[str, str]:
        """Sensor name -> unit, in declared order (what a dataset records)."""
        return {name: spec.unit for name, spec in self.sensors.items()}

    def groups(self) -> dict[str, tuple[str, ...]]:
        """The declared condition groups plus ``all`` (every condition not held out)."""
        held_out = set(self.condition_groups.get(HELD_OUT_GROUP, ()))
        everyday = tuple(c for c in self.conditions if c not in held_out)
        return {**self.condition_groups, ALL_CONDITIONS: everyday}

    def resolve_conditions(self, names: Sequence[str], *, where: str) -> tuple[str, ...]:
        """Condition and group names -> condition names, groups expanded in their declared
        order, each condition once; an unknown name fails listing the known ones."""
        groups = self.groups()
        resolved: list[str] = []
        for name in names:
            if name in self.conditions:
                members: Sequence[str] = (name,)
            elif name in groups:
                members = groups[name]
            else:
                raise ValueError(
                    f"{where}: unknown condition {name!r} (no condition or group of simulator "
                    f"{self.name!r}); conditions {list(self.conditions)}, groups {list(groups)}"
                )
            resolved.extend(m for m in members if m not in resolved)
        return tuple(resolved)

    def resolve_mixture(self, weights: Mapping[str, float], *, where: str) -> dict[str, float]:
        """A mixture {condition or group: weight} -> {condition: weight}: each member of a
        group gets the group's weight; a condition named twice fails."""
        mixture: dict[str, float] = {}
        for name, weight in weights.items():
            for condition in self.resolve_conditions([name], where=where):
                if condition in mixture:
                    raise ValueError(f"{where}: condition {condition!r} is weighted twice")
                mixture[condition] = weight
        return mixture

    def pooled_groups(self) -> dict[str, tuple[str, ...]]:
        """Default evaluation groups: each declared group but ``held_out``, then each
        condition in no group on its own (the pile loader: ``winter`` = A-D, then
        ``summer``)."""
        grouped = {c for members in self.condition_groups.values() for c in members}
        return {
            **{g: m for g, m in self.condition_groups.items() if g != HELD_OUT_GROUP},
            **{c: (c,) for c in self.conditions if c not in grouped},
        }

    def score(self, info: Mapping[str, Any]) -> tuple[bool, float]:
        """(success, fill) of an episode's last ``info``; fill is the success as 0/1 when
        the simulator declares no fill key."""
        success = bool(info[self.success_key])
        fill = float(info[self.fill_key]) if self.fill_key else float(success)
        return success, fill

    def info_flags(self) -> tuple[str, ...]:
        """The declared ``episode_info`` entries that are flags (unit ``bool``)."""
        return tuple(k for k, unit in self.episode_info.items() if unit == "bool")

    # ------------------------------------------------------------------ evaluation
    def episode_outcome(
        self,
        *,
        info: Mapping[str, Any],
        sensors: Mapping[str, Any],
        controls: Mapping[str, Any],
        success: bool,
        where: str = "episode",
    ) -> dict[str, Any]:
        """The simulator's columns of an evaluated episode's record, ``failure_mode`` last
        unless its ``episode_columns`` orders it elsewhere.

        ``info``: each ``episode_info`` entry, float64 [T + 1] (at reset, then after each
        step; NaN where not reported); ``sensors``: each sensor's readings [T + 1];
        ``controls``: each control's commands [T]; ``success``: the episode's success.
        A failure mode the simulator did not declare fails naming ``where``.
        """
        if self.episode_columns is None:
            columns: dict[str, Any] = {}
            for key, values in info.items():
                value = float(values[-1])
                columns[key] = bool(value) if key in self.info_flags() else value
            columns["failure_mode"] = SUCCESS if success else FAILED
            return columns
        columns = dict(
            resolve(self.episode_columns)(
                info=info, sensors=sensors, controls=controls, success=success
            )
        )
        mode = columns.get("failure_mode")
        if mode not in (SUCCESS, *self.failure_modes) or (mode == SUCCESS) != success:
            raise ValueError(
                f"{where}: simulator {self.name!r}'s episode_columns named the failure mode "
                f"{mode!r} of an episode with success={success}; expected {SUCCESS!r} for a "
                f"success, else one of its failure_modes {list(self.failure_modes)}"
            )
        return columns

    def summary_numbers(self, records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
        """The simulator's numbers of a summary of ``records`` (``summary_columns``)."""
        if self.summary_columns is None:
            return {}
        return dict(resolve(self.summary_columns)(records))

    # ------------------------------------------------------------------ options
    def options_class(self) -> type:
        """The plugin's options dataclass (imported now)."""
        cls = resolve(self.options)
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"simulator {self.name!r}: options {self.options!r} is no dataclass")
        return cls

    def option_names(self) -> list[str]:
        """The constructor options this simulator declares."""
        return [f.name for f in fields(self.options_class())]

    def check_options(self, options: Mapping[str, Any], *, where: str = "env") -> None:
        """Raise ``ValueError`` naming any option this simulator does not declare, with the
        list of the ones it does."""
        known = self.option_names()
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise ValueError(
                f"{where}: simulator {self.name!r} has no option(s) {unknown}; its options: {known}"
            )

    # ------------------------------------------------------------------ expert
    def check_expert_options(self, options: Mapping[str, Any], *, where: str, drawn: bool) -> None:
        """Build the expert once (nominal, or ``drawn`` from a seeded generator) so that
        bad options fail now, naming ``where``."""
        import numpy as np

        rng = np.random.default_rng(0) if drawn else None
        try:
            self.make_expert(dt=CHECK_PERIOD_S, rng=rng, **dict(options))
        except (TypeError, ValueError) as error:
            raise ValueError(f"{where}: {error}") from None

    def expert_phases(self) -> tuple[str, ...]:
        """The phase names of the scripted expert (its ``PHASES``): what the ``phase``
        index recorded with its demonstrations points into; ``()`` without an expert."""
        if self.scripted_expert is None:
            return ()
        return tuple(getattr(self.make_expert(dt=CHECK_PERIOD_S), "PHASES", ()))

    def make_expert(self, *, dt: float, rng=None, **options):
        """The simulator's scripted expert (``make_expert`` of the plugin); ``rng=None``:
        the nominal, deterministic one."""
        if self.scripted_expert is None:
            raise ValueError(
                f"simulator {self.name!r} declares no scripted_expert: nothing can record "
                "scripted demonstrations or run the scripted baseline in it"
            )
        return resolve(self.scripted_expert)(dt=dt, rng=rng, **options)


def _names(values: object, where: str) -> tuple[str, ...]:
    if isinstance(values, str) or not isinstance(values, Sequence):
        raise ValueError(f"{where}: expected a list of names, got {values!r}")
    names = tuple(str(v) for v in values)
    bad = [n for n in names if not _NAME.match(n)]
    if bad or len(set(names)) != len(names):
        raise ValueError(f"{where}: names must be unique identifiers, got {list(names)}")
    return names


def _sensor_specs(sensors: object, where: str) -> dict[str, SensorSpec]:
    if not isinstance(sensors, Mapping) or not sensors:
        raise ValueError(f"{where}: expected a mapping name -> {{unit, low, high}}")
    specs = {}
    for name, spec in sensors.items():
        _names([name], where)
        if isinstance(spec, Mapping):
            try:
                spec = SensorSpec(str(spec["unit"]), float(spec["low"]), float(spec["high"]))
            except (KeyError, TypeError, ValueError) as error:
                raise ValueError(f"{where}.{name}: needs unit, low, high ({error!r})") from None
        if not isinstance(spec, SensorSpec):
            raise ValueError(f"{where}.{name}: expected {{unit, low, high}}, got {spec!r}")
        if not (math.isfinite(spec.low) and math.isfinite(spec.high) and spec.low < spec.high):
            raise ValueError(f"{where}.{name}: needs finite low < high, got {spec}")
        specs[str(name)] = spec
    return specs
