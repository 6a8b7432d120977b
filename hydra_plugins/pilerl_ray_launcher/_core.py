"""Ray side of the launcher: start or join Ray, submit one task per job, collect returns."""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import ray
from hydra.core.hydra_config import HydraConfig
from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, configure_log, filter_overrides, run_job, setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, open_dict

from .config import RayLauncherConf
from .ray_launcher import RayLauncher

log = logging.getLogger(__name__)


def start_ray(settings: RayLauncherConf) -> None:
    """Start a local Ray instance or join a cluster, unless this process already has Ray."""
    if ray.is_initialized():
        return
    if settings.address is None:
        # a local instance would otherwise send usage statistics to Ray's servers
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    log.info("ray.init(%s)", settings.init_kwargs())
    ray.init(**settings.init_kwargs())


def check_resources(settings: RayLauncherConf) -> None:
    """Fail at once if the whole cluster has less of a resource than one job asks for."""
    total = ray.cluster_resources()
    memory_gb = total.get("memory", 0.0) / 1024**3
    for needed, available, field, unit in (
        (settings.cpus_per_job, total.get("CPU", 0.0), "cpus_per_job", "CPUs"),
        (settings.gpus_per_job, total.get("GPU", 0.0), "gpus_per_job", "GPUs"),
        (settings.memory_gb_per_job or 0.0, memory_gb, "memory_gb_per_job", "GiB of memory"),
    ):
        if needed > available:
            raise ValueError(
                f"hydra.launcher.{field}={needed:g} but the Ray cluster has "
                f"{available:.3g} {unit}: no job could start"
            )


def run_job_in_worker(
    *,
    hydra_context: HydraContext,
    sweep_config: DictConfig,
    task_function: TaskFunction,
    singleton_state: dict[Any, Any],
    launch_dir: str | None,
) -> JobReturn:
    """Run one Hydra job inside a Ray worker, as Hydra's own launchers do in theirs."""
    if launch_dir is not None:
        if not Path(launch_dir).is_dir():
            raise RuntimeError(
                f"the sweep was launched from {launch_dir}, which does not exist on Ray node "
                f"{ray.util.get_node_ip_address()}: put the project on a filesystem shared "
                "by every node, or set hydra.launcher.runtime_env.working_dir"
            )
        os.chdir(launch_dir)  # relative paths in configs mean what they mean at launch
    setup_globals()
    Singleton.set_state(singleton_state)
    HydraConfig.instance().set_config(sweep_config)
    return run_job(
        hydra_context=hydra_context,
        task_function=task_function,
        config=sweep_config,
        job_dir_key="hydra.sweep.dir",
        job_subdir_key="hydra.sweep.subdir",
    )


def launch(
    launcher: RayLauncher, *, job_overrides: Sequence[Sequence[str]], initial_job_idx: int
) -> list[JobReturn]:
    """Submit every job, then wait for all; returns are in the order of ``job_overrides``."""
    setup_globals()
    assert launcher.config is not None, "RayLauncher.launch called before setup"
    assert launcher.hydra_context is not None and launcher.task_function is not None
    settings = launcher.settings
    configure_log(launcher.config.hydra.hydra_logging, launcher.config.hydra.verbose)
    sweep_dir = Path(str(launcher.config.hydra.sweep.dir))
    sweep_dir.mkdir(parents=True, exist_ok=True)

    start_ray(settings)
    check_resources(settings)
    remote_job = ray.remote(**settings.remote_options())(run_job_in_worker)
    launch_dir = None if "working_dir" in settings.runtime_env else os.getcwd()
    singleton_state = Singleton.get_state()
    log.info(f"Ray launcher is launching {len(job_overrides)} jobs, sweep dir: {sweep_dir}")

    pending = []
    for offset, overrides in enumerate(job_overrides):
        idx = initial_job_idx + offset
        log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
        sweep_config = launcher.hydra_context.config_loader.load_sweep_config(
            launcher.config, list(overrides)
        )
        with open_dict(sweep_config):
            sweep_config.hydra.job.id = f"{sweep_config.hydra.job.name}_{idx}"
            sweep_config.hydra.job.num = idx
        pending.append(
            remote_job.remote(
                hydra_context=launcher.hydra_context,
                sweep_config=sweep_config,
                task_function=launcher.task_function,
                singleton_state=singleton_state,
                launch_dir=launch_dir,
            )
        )
    return ray.get(pending)
