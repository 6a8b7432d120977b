"""The Ray launcher's typed config, stored as ``hydra/launcher: ray``.

No ``from __future__ import annotations`` here: Hydra's plugin scan executes this module
before registering it in ``sys.modules``, and ``dataclass`` cannot resolve string
annotations then.
"""

from dataclasses import dataclass, field
from typing import Any

from hydra.core.config_store import ConfigStore

# one OpenMP/BLAS (so one PyTorch intra-op) thread per job, offscreen MuJoCo rendering
DEFAULT_ENV_VARS = {
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MUJOCO_GL": "egl",
}


@dataclass
class RayLauncherConf:
    """Where sweep jobs run and what each one reserves.

    Attributes:
        address: ``null`` starts a local Ray instance in the sweeping process (or joins
            the cluster named by the ``RAY_ADDRESS`` variable); ``auto`` joins the cluster
            this machine belongs to (``ray start --head`` / ``ray start --address=...``);
            ``HOST:6379`` a cluster's head node; ``ray://HOST:10001`` Ray Client.
        num_cpus: logical CPUs of the local Ray instance (``null``: all cores). Only
            for ``address: null``; a cluster declares its CPUs at ``ray start``.
        include_dashboard: start Ray's dashboard with the local instance.
        cpus_per_job: CPUs each job reserves; jobs run at once = CPUs / cpus_per_job.
        gpus_per_job: GPUs each job reserves (fractions share a GPU).
        memory_gb_per_job: memory each job reserves for scheduling [GiB]; ``null``: none.
        max_retries: times Ray re-runs a job whose worker process died (not one that
            raised); recipes skip work already done (``done.json``).
        env_vars: environment variables of every job, set before it imports anything.
        runtime_env: more of Ray's runtime environment for the jobs (``working_dir``,
            ``pip``, ...); its ``env_vars`` are merged under ``env_vars``. Without
            ``working_dir`` each job starts in the directory the sweep was launched from,
            which must then exist on every node (a shared filesystem).
    """

    _target_: str = "hydra_plugins.pilerl_ray_launcher.ray_launcher.RayLauncher"
    address: str | None = None
    num_cpus: int | None = None
    include_dashboard: bool = False
    cpus_per_job: float = 1.0
    gpus_per_job: float = 0.0
    memory_gb_per_job: float | None = None
    max_retries: int = 0
    env_vars: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_ENV_VARS))
    runtime_env: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.address is not None and not self.address.strip():
            raise ValueError("hydra.launcher.address must be null or a Ray address, got ''")
        if self.num_cpus is not None:
            if self.num_cpus < 1:
                raise ValueError(
                    f"hydra.launcher.num_cpus must be >= 1 or null, got {self.num_cpus}"
                )
            if self.address is not None:
                raise ValueError(
                    "hydra.launcher.num_cpus sizes a local Ray instance and cannot be "
                    f"combined with hydra.launcher.address={self.address!r}: a cluster "
                    "declares its CPUs at `ray start --num-cpus=...`"
                )
            if self.cpus_per_job > self.num_cpus:
                raise ValueError(
                    f"hydra.launcher.cpus_per_job ({self.cpus_per_job:g}) exceeds "
                    f"hydra.launcher.num_cpus ({self.num_cpus}): no job could start"
                )
        if self.cpus_per_job <= 0:
            raise ValueError(f"hydra.launcher.cpus_per_job must be > 0, got {self.cpus_per_job:g}")
        if self.gpus_per_job < 0:
            raise ValueError(f"hydra.launcher.gpus_per_job must be >= 0, got {self.gpus_per_job:g}")
        if self.memory_gb_per_job is not None and self.memory_gb_per_job <= 0:
            raise ValueError(
                "hydra.launcher.memory_gb_per_job must be > 0 or null, got "
                f"{self.memory_gb_per_job:g}"
            )
        if self.max_retries < 0:
            raise ValueError(f"hydra.launcher.max_retries must be >= 0, got {self.max_retries}")

    def init_kwargs(self) -> dict[str, Any]:
        """Arguments for ``ray.init``."""
        if self.address is not None:
            return {"address": self.address}
        return {"num_cpus": self.num_cpus, "include_dashboard": self.include_dashboard}

    def job_runtime_env(self) -> dict[str, Any]:
        """Each job's Ray runtime environment: ``runtime_env`` plus ``env_vars``."""
        env_vars = {**self.runtime_env.get("env_vars", {}), **self.env_vars}
        return {**self.runtime_env, "env_vars": env_vars}

    def remote_options(self) -> dict[str, Any]:
        """Options for ``ray.remote`` of each job."""
        options: dict[str, Any] = {
            "num_cpus": self.cpus_per_job,
            "num_gpus": self.gpus_per_job,
            "max_retries": self.max_retries,
            "runtime_env": self.job_runtime_env(),
        }
        if self.memory_gb_per_job is not None:
            options["memory"] = int(self.memory_gb_per_job * 1024**3)
        return options


ConfigStore.instance().store(
    group="hydra/launcher",
    name="ray",
    node=RayLauncherConf,
    provider="pilerl_ray_launcher",
)
