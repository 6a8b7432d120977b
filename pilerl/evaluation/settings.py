"""The evaluation room's settings: closed-loop tests, the evaluate and scoop recipes.

``ClosedLoopConfig`` is the ``evaluation`` node of the evaluate, train_bc and pipeline
configs; ``EvaluateConfig`` and ``ScoopConfig`` are the primary schemas of
``recipes/evaluate.py`` and ``recipes/scoop.py``. Every field is checked in
``__post_init__``: a bad value fails when the config is built, naming the field.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from pilerl import checks
from pilerl.sim.settings import EnvConfig


@dataclass
class ClosedLoopConfig:
    """Closed-loop evaluation: N seeded episodes per condition (``pilerl.evaluation``).

    Attributes:
        conditions: conditions and condition groups of the simulator to test in (``all``:
            every condition; the pile loader's ``winter``: A-D); a declared group with two
            or more tested conditions is also pooled.
        episodes: episodes per condition (0 = no closed-loop evaluation).
        seed: base seed; episode i starts from the same pose in every condition
            (demonstrations use seed 0: test starts differ from training ones).
        workers: episode processes (``None`` = one per core).
        videos: render the median-fill episode and the first failure of each condition:
            ``auto`` (when this machine can render, else one warning), ``true`` (refuse
            before any work if it cannot) or ``false``.
        video_conditions: only these conditions' (``None``: every condition's); offscreen
            rendering runs in software here (~0.05-0.2 s a frame).
        render_width, render_height: video frame size [px].
    """

    conditions: list[str] = field(default_factory=lambda: ["all"])
    episodes: int = 10
    seed: int = 1
    workers: int | None = None
    videos: str = "false"
    video_conditions: list[str] | None = None
    render_width: int = 640
    render_height: int = 360

    def __post_init__(self) -> None:
        checks.names("evaluation.conditions", self.conditions)
        checks.non_negative_int("evaluation.episodes", self.episodes)
        checks.non_negative_int("evaluation.seed", self.seed)
        if self.workers is not None:
            checks.positive_int("evaluation.workers", self.workers)
        if self.video_conditions is not None:
            checks.names("evaluation.video_conditions", self.video_conditions)
        checks.render_size("evaluation.", self.render_width, self.render_height)
        checks.video_choice("evaluation.videos", self.videos)

    def condition_names(self, env: EnvConfig) -> tuple[str, ...]:
        """The conditions tested in ``env``'s simulator (groups expanded); checks that
        ``video_conditions`` are among them."""
        conditions = env.plugin().resolve_conditions(self.conditions, where="evaluation.conditions")
        unknown = [c for c in self.video_conditions or () if c not in conditions]
        if unknown:
            raise ValueError(
                f"evaluation.video_conditions: {unknown} are not evaluated; "
                f"evaluation.conditions are {list(conditions)}"
            )
        return conditions

    def plan(self, env: EnvConfig):
        """The ``EvaluationPlan`` of this config in ``env`` (its condition is replaced)."""
        from .evaluator import EvaluationPlan

        kwargs = env.make_kwargs()
        kwargs.pop("condition")
        conditions = self.condition_names(env)
        return EvaluationPlan(env.simulator, kwargs, conditions, self.episodes, seed=self.seed)


@dataclass
class EvaluateConfig:
    """The evaluate recipe: a controller tested in closed loop.

    Attributes:
        env: simulator arguments (``env.condition`` is replaced by each evaluated one).
        checkpoint: a saved actor (``best.pt`` of train_bc or finetune); ``None`` evaluates
            the simulator's nominal scripted expert.
        name: the controller's name in plots and tables (default: from the checkpoint's
            run directory).
        expert: options of the nominal scripted expert (used when ``checkpoint`` is
            ``None``; the pile loader's: ``OperatorStyle`` fields); ``{}``: its defaults.
        evaluation: conditions, episodes, seed, workers, videos.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    checkpoint: str | None = None
    name: str | None = None
    expert: dict[str, Any] = field(default_factory=dict)
    evaluation: ClosedLoopConfig = field(default_factory=ClosedLoopConfig)
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        if self.checkpoint is not None:
            checks.path("checkpoint", self.checkpoint)
        if self.name is not None:
            checks.name("name", self.name)
        self.evaluation.condition_names(self.env)
        if self.checkpoint is None:
            self.env.plugin().check_expert_options(self.expert, where="expert", drawn=False)


@dataclass
class ScoopConfig:
    """The scoop recipe: scripted scoops recorded, rendered and reported per condition.

    Attributes:
        env: simulator arguments; ``env.condition`` is replaced by each of ``conditions``.
        expert: options of the simulator's nominal scripted expert (the pile loader's:
            ``trigger_sensor`` and its ``OperatorStyle`` fields); ``{}``: its defaults.
        conditions: conditions (or groups) to scoop in, one episode each; ``None``: the
            simulator's declared ``example_conditions`` (the pile loader's: summer and
            winter_c).
        seed: episode seed (start distance and approach angle follow from it).
        video: write an mp4 per condition: ``auto`` (when this machine can render, else
            one warning), ``true`` (refuse before any work if it cannot) or ``false``.
        render_width, render_height: video frame size [px].
        camera: MJCF camera for the video.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    expert: dict[str, Any] = field(default_factory=dict)
    conditions: list[str] | None = None
    seed: int = 0
    video: str = "auto"
    render_width: int = 640
    render_height: int = 360
    camera: str = "side"
    output_dir: str = MISSING  # set by the primary YAML to Hydra's run directory

    def __post_init__(self) -> None:
        if self.conditions is None:
            self.conditions = list(self.env.plugin().example_conditions)
        checks.names("conditions", self.conditions)
        self.env.plugin().resolve_conditions(self.conditions, where="conditions")
        self.env.plugin().check_expert_options(self.expert, where="expert", drawn=False)
        checks.non_negative_int("seed", self.seed)
        checks.render_size("", self.render_width, self.render_height)
        checks.name("camera", self.camera)
        checks.video_choice("video", self.video)
