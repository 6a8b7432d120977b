"""The data room's settings: recording demonstrations and curating datasets.

``DatasetConfig`` is the ``dataset`` config group (conf/dataset/); ``RecordConfig``,
``TeleopConfig`` and ``BuildDatasetConfig`` are the primary schemas of the record, teleop
and build_dataset recipes; ``DemosConfig`` is the pipeline's recording step. Every field
is checked in ``__post_init__``: a bad value fails when the config is built, naming the
field.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import MISSING

from pilerl import checks
from pilerl.sim.settings import EnvConfig


@dataclass
class DatasetConfig:
    """A curation rule (the ``dataset`` config group).

    Attributes:
        name: ``d_i`` or ``d_ii`` (or your own).
        successful_only: keep only episodes that ended at least half full.
        rate_hz: down-sample to this rate [Hz]; ``None`` keeps the recorded rate.
    """

    name: str = MISSING
    successful_only: bool = False
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        if self.name != MISSING:
            checks.name("dataset.name", self.name)
        if self.rate_hz is not None:
            checks.positive("dataset.rate_hz", self.rate_hz)


@dataclass
class BuildDatasetConfig:
    """The build_dataset recipe: a curated dataset from recorded demonstrations."""

    dataset: DatasetConfig = field(default_factory=DatasetConfig)
    source: str = MISSING
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        if MISSING in (self.source, self.out_dir):
            return
        checks.path("source", self.source)
        checks.path("out_dir", self.out_dir)
        if Path(self.source).resolve() == Path(self.out_dir).resolve():
            raise ValueError(f"out_dir: must differ from source ({self.source!r})")


@dataclass
class RecordConfig:
    """The record recipe: scripted demonstrations into a dataset directory.

    Attributes:
        env: simulator arguments; ``env.control_hz`` is replaced by ``record_hz``.
        n_episodes: episodes to record (the paper: 72 summer demonstrations).
        seed: base seed (episode i: env seed ``seed * 100000 + i``, its own style).
        record_hz: sampling (= control) rate of the recording [Hz] (the paper recorded
            sensors at 500 Hz); it replaces ``env.control_hz`` (the simulator must declare
            that option).
        expert: options of the simulator's scripted expert for drawn operator styles
            (the pile loader's: ``trigger_sensor``, ``mistake_rate``); ``{}``: its defaults.
        workers: recording processes.
        out_dir: dataset directory; an existing one is resumed.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    n_episodes: int = 72
    seed: int = 0
    record_hz: float = 500.0
    expert: dict[str, Any] = field(default_factory=dict)
    workers: int = 2
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        checks.positive_int("n_episodes", self.n_episodes)
        checks.non_negative_int("seed", self.seed)
        checks.positive("record_hz", self.record_hz)
        try:
            self.env.make_kwargs(control_hz=self.record_hz)
        except ValueError as error:
            raise ValueError(f"record_hz ({self.record_hz}): {error}") from None
        self.env.plugin().check_expert_options(self.expert, where="expert", drawn=True)
        checks.positive_int("workers", self.workers)
        if self.out_dir != MISSING:
            checks.path("out_dir", self.out_dir)


@dataclass
class TeleopConfig:
    """The teleop recipe: keyboard-driven episodes recorded like scripted ones."""

    env: EnvConfig = field(default_factory=EnvConfig)
    episodes: int = 1
    seed: int = 0
    operator_id: str = "person-1"
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        checks.positive_int("episodes", self.episodes)
        checks.non_negative_int("seed", self.seed)
        checks.name("operator_id", self.operator_id)


# the pipeline's recordings: condition -> the sensor its operators feel the impact on
PIPELINE_TRIGGERS = {"summer": "drive_pressure", "winter_c": "telescope_pressure"}


@dataclass
class DemosConfig:
    """Scripted demonstrations recorded by the pipeline (its ``demos`` node).

    Attributes:
        episodes: summer demonstrations (the paper: 72); the successful ones become D_II.
        validation_episodes: winter_c demonstrations by operators who feel the contact
            (telescope-pressure cue): the validation loss and the Fig. 3 / Fig. 5 data.
        record_hz: recording (= control) rate [Hz]; 20 Hz is D_II's rate.
        mistake_rate: share of operators who raise the boom too early.
        expert: further options of the scripted expert for both recordings (the pile
            loader's: ``crowd_fill``, ``impact_cue``, ``push_again``, ``executed_noise``;
            docs/operators.md); its cue sensors are the pipeline's (summer: drive
            pressure, winter_c: telescope pressure) and its mistake rate is
            ``mistake_rate``.
        seed: base seed of the recordings.
        workers: recording processes.
    """

    episodes: int = 30
    validation_episodes: int = 4
    record_hz: float = 20.0
    mistake_rate: float = 0.28
    expert: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    workers: int = 2

    def __post_init__(self) -> None:
        checks.positive_int("demos.episodes", self.episodes)
        checks.positive_int("demos.validation_episodes", self.validation_episodes)
        checks.positive("demos.record_hz", self.record_hz)
        checks.fraction("demos.mistake_rate", self.mistake_rate)
        checks.non_negative_int("demos.seed", self.seed)
        checks.positive_int("demos.workers", self.workers)

    def expert_options(self, condition: str) -> dict[str, Any]:
        """The scripted expert's options for the pipeline's recording in ``condition``:
        ``expert``, with that recording's cue sensor and ``mistake_rate``."""
        trigger = PIPELINE_TRIGGERS[condition]
        return {**self.expert, "trigger_sensor": trigger, "mistake_rate": self.mistake_rate}

    def check_expert(self, env: EnvConfig) -> None:
        """``expert`` holds options ``env``'s scripted expert takes, and none the pipeline
        sets itself."""
        triggers = ", ".join(f"{c}: {t}" for c, t in PIPELINE_TRIGGERS.items())
        owned = {
            "trigger_sensor": f"the pipeline ({triggers})",
            "mistake_rate": "demos.mistake_rate",
        }
        for key in self.expert:
            if key in owned:
                raise ValueError(f"demos.expert.{key}: set by {owned[key]}, not here")
        for condition in PIPELINE_TRIGGERS:
            options = self.expert_options(condition)
            env.plugin().check_expert_options(options, where="demos.expert", drawn=True)

    def check_rate(self, env: EnvConfig) -> None:
        """``record_hz`` is a control rate ``env``'s simulator accepts (the pile loader: at
        most its physics rate)."""
        try:
            env.make_kwargs(control_hz=self.record_hz)
        except ValueError as error:
            raise ValueError(f"demos.record_hz ({self.record_hz}): {error}") from None
