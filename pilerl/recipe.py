"""The prologue and epilogue every recipe shares, as one decorator.

A recipe under ``recipes/`` is a function of its typed config and its :class:`Run`::

    @recipe("evaluate", objective="success_rate")
    def main(config: EvaluateConfig, run: Run) -> dict[str, float]:
        ...                                    # checks that write nothing
        run.begin(inputs={"checkpoint": checkpoint})   # a finished run stops here
        ...                                    # the work
        return metrics                         # -> metrics.json, done.json

``recipe(config_name)`` does what each recipe used to repeat:

1. ``hydra.main`` on ``conf/<config_name>.yaml`` (``conf/`` beside ``recipes/``);
2. one intra-op thread (``pilerl.runtime.limit_threads``);
3. the config as its dataclass (``OmegaConf.to_object``; with ``schema`` given, merged
   onto that dataclass first, for configs that are not registered with Hydra);
4. ``run.begin(...)`` is ``pilerl.runs.begin_run`` on the run directory with the resolved
   settings: when the directory holds this run finished with the same settings and
   inputs, it logs ``<dir> already finished: skipping`` and the recipe returns the
   recorded objective; other settings or inputs are refused (``RunMismatch``);
5. the metrics the recipe returns are written with ``pilerl.runs.finish_run`` (which
   marks the run done), and the recipe returns ``objective`` of them: the value a Hydra
   sweeper (Optuna) minimises or maximises.
"""

from __future__ import annotations

import functools
import inspect
import json
import logging
import math
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from pilerl.layout import RunLayout
from pilerl.runs import begin_run, finish_run
from pilerl.runtime import limit_threads

log = logging.getLogger(__name__)

Metrics = Mapping[str, float | int | bool]
# the run setting that records the simulator's ``expert_revision`` (``Run.begin``)
EXPERT_REVISION = "expert_revision"
Objective = Callable[[Metrics], float]


class RunFinished(Exception):  # noqa: N818 - a signal, like StopIteration, not a failure
    """``Run.begin`` found the run finished before with the same settings and inputs."""


@dataclass
class Run:
    """The run a recipe is doing.

    Attributes:
        dir: the run directory: the config's ``output_dir`` where it has one, else Hydra's
            output directory; ``metrics.json`` and ``done.json`` go here.
        settings: the resolved config as plain data (what ``run.json`` records).
    """

    dir: Path
    settings: dict[str, Any]
    began: bool = field(default=False, init=False)

    @property
    def layout(self) -> RunLayout:
        return RunLayout(self.dir)

    def begin(
        self,
        *,
        run_dir: str | Path | None = None,
        settings: Mapping[str, Any] | None = None,
        inputs: Mapping[str, str | Path | None] | None = None,
        growable: Iterable[str] = (),
        added: Mapping[str, Any] | None = None,
        scripted_expert_revision: int | None = None,
        **facts: Any,
    ) -> None:
        """Record this run in ``run_dir`` (default ``dir``), or stop when it finished there.

        Args: as ``pilerl.runs.begin_run``; ``settings`` replaces the resolved config
        (e.g. without the keys that name the directory itself).
        ``scripted_expert_revision``: the simulator's ``expert_revision`` where the run's
        work is its scripted expert's (a scripted evaluation, scoops): recorded with the
        settings, so that a run of an earlier expert is refused instead of skipped as done
        (a run recorded before revisions existed counts as revision 0).

        Raises ``RunFinished`` (the decorator skips the recipe) or ``RunMismatch``.
        """
        where = Path(run_dir) if run_dir is not None else self.dir
        recorded = self.settings if settings is None else settings
        if scripted_expert_revision is not None:
            recorded = {**recorded, EXPERT_REVISION: scripted_expert_revision}
            added = {EXPERT_REVISION: 0, **(added or {})}
        if begin_run(where, recorded, inputs=inputs, growable=growable, added=added, **facts):
            raise RunFinished(str(where))
        self.began = True


def recipe(
    config_name: str,
    *,
    schema: type | None = None,
    objective: str | Objective | None = None,
    usage_errors: tuple[type[Exception], ...] = (),
    config_path: str = "../conf",
) -> Callable[[Callable[..., Metrics | None]], Callable[[], Any]]:
    """Make ``main(config, run)`` (or ``main(config)``) a Hydra recipe (module docstring).

    Args:
        config_name: the primary config under ``conf/``.
        schema: the config's dataclass, when it is not registered with Hydra.
        objective: a metric's name, or a function of the metrics, returned to a sweeper
            (``None``: the recipe returns nothing).
        usage_errors: errors (in the config or the recipe) that are the user's to fix:
            logged as one line and the process exits with status 2, no traceback.
        config_path: the config directory, relative to the recipe's file.
    """
    score = _objective_function(objective)

    def decorate(main: Callable[..., Metrics | None]) -> Callable[[], Any]:
        conf_dir = (Path(inspect.getfile(main)).parent / config_path).resolve()
        wants_run = len(inspect.signature(main).parameters) == 2

        @functools.wraps(main)
        def task(cfg: DictConfig) -> Any:
            limit_threads()
            run = Run(_run_dir(cfg), _plain(cfg))
            try:
                config = _to_object(cfg, schema)
                metrics = main(config, run) if wants_run else main(config)
            except usage_errors as error:
                log.error("%s", error)
                sys.exit(2)
            except RunFinished as finished:
                log.info("%s already finished: skipping (same settings and inputs)", finished)
                return None if score is None else _recorded_objective(run.layout, score)
            if metrics is not None:
                if not run.began:
                    raise RuntimeError(
                        f"{main.__name__}: returned metrics without run.begin(): a run is "
                        "recorded (run.json) before it is marked done"
                    )
                finish_run(run.dir, metrics)
            return None if score is None or metrics is None else score(metrics)

        return hydra.main(config_path=str(conf_dir), config_name=config_name, version_base="1.3")(
            task
        )

    return decorate


def _to_object(cfg: DictConfig, schema: type | None) -> Any:
    """The config as its dataclass (checked in ``__post_init__``)."""
    if schema is not None:
        cfg = OmegaConf.merge(OmegaConf.structured(schema), cfg)
    return OmegaConf.to_object(cfg)


def _run_dir(cfg: DictConfig) -> Path:
    """The config's ``output_dir`` where it has one, else Hydra's output directory."""
    if "output_dir" in cfg and not OmegaConf.is_missing(cfg, "output_dir"):
        return Path(cfg.output_dir)
    return Path(HydraConfig.get().runtime.output_dir)


def _plain(cfg: DictConfig) -> dict[str, Any]:
    settings = OmegaConf.to_container(cfg, resolve=True)
    assert isinstance(settings, dict)
    return settings


def _objective_function(objective: str | Objective | None) -> Objective | None:
    if objective is None or callable(objective):
        return objective
    return lambda metrics: float(metrics[objective])


def _recorded_objective(layout: RunLayout, score: Objective) -> float:
    """The objective of a finished run's ``metrics.json`` (NaN when it has none)."""
    try:
        return score(json.loads(layout.metrics.read_text()))
    except (OSError, ValueError, KeyError, StopIteration):
        return math.nan
