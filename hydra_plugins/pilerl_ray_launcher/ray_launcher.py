"""``RayLauncher``: the Hydra ``Launcher`` that runs sweep jobs as Ray tasks."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hydra.core.utils import JobReturn
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, ListConfig, OmegaConf

from .config import RayLauncherConf


class RayLauncher(Launcher):
    """Launch a batch of Hydra jobs as Ray tasks and return their ``JobReturn`` in order.

    ``kwargs`` are the fields of ``RayLauncherConf`` (Hydra passes ``hydra.launcher``);
    they are checked here, so a bad value fails before any job starts.
    """

    def __init__(self, **kwargs: Any) -> None:
        plain = {
            key: OmegaConf.to_container(value, resolve=True)
            if isinstance(value, DictConfig | ListConfig)
            else value
            for key, value in kwargs.items()
        }
        self.settings = RayLauncherConf(**plain)
        self.config: DictConfig | None = None
        self.task_function: TaskFunction | None = None
        self.hydra_context: HydraContext | None = None

    def setup(
        self,
        *,
        hydra_context: HydraContext,
        task_function: TaskFunction,
        config: DictConfig,
    ) -> None:
        """Keep what each job needs: the composed config, the task and Hydra's context."""
        self.config = config
        self.task_function = task_function
        self.hydra_context = hydra_context

    def launch(
        self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int
    ) -> Sequence[JobReturn]:
        """One Ray task per entry of ``job_overrides``, numbered from ``initial_job_idx``."""
        from . import _core  # imports Ray: only when a sweep is launched

        return _core.launch(self, job_overrides=job_overrides, initial_job_idx=initial_job_idx)
