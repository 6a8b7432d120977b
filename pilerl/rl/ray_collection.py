"""Collection on Ray: TorchRL's ``RayCollector`` with pilerl's defaults.

``make_ray_collector`` starts (or joins) a Ray instance and returns TorchRL 0.14's
:class:`torchrl.collectors.distributed.RayCollector`: ``num_collectors`` Ray actors, each
running a TorchRL ``Collector`` over its own simulator, yielding batches of
``frames_per_batch`` frames until ``total_frames`` are collected. The collector is used
exactly like TorchRL documents it (iterate, ``update_policy_weights_``, ``shutdown``);
this module only fixes what pilerl needs on every machine:

- No address given: a local Ray instance with ``num_collectors`` CPUs (so the actors can
  always be placed), no dashboard, and Ray's usage statistics off.
- Each actor reserves ``CPUS_PER_COLLECTOR`` CPU and runs with ``WORKER_ENV_VARS``
  (one OpenMP / BLAS thread, so one PyTorch intra-op thread, and offscreen ``egl``
  rendering), set before the worker imports torch.
- A cluster too small for the actors fails at once with the numbers, instead of
  waiting forever for resources.
- The actors get ``WEIGHT_SYNC_TIMEOUT_S`` to join the weight-sync process group, not
  TorchRL 0.14's 60 s: joining starts a Ray worker process that imports torch, which took
  longer than 60 s on a loaded 2-core machine (a CI run failed so), as it may on a busy
  cluster node.

Ray is optional (``pip install -e '.[ray]'``; the ``dev`` extra includes it): it is
imported only when a collector is made. See docs/ray.md.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from torchrl.envs import EnvBase

if TYPE_CHECKING:
    from torchrl.collectors.distributed import RayCollector

log = logging.getLogger(__name__)

CPUS_PER_COLLECTOR = 1  # Ray CPUs each collector actor reserves (one simulator each)
WORKER_ENV_VARS = {
    "OMP_NUM_THREADS": "1",  # read by torch at import: one intra-op thread per actor
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MUJOCO_GL": "egl",  # offscreen rendering, no display on cluster nodes
}
# how long the learner waits for the actors to join torch.distributed's weight-sync group
# (TorchRL 0.14 fixes 60 s in torchrl.weight_update._ray._DIST_TIMEOUT) [s]
WEIGHT_SYNC_TIMEOUT_S = 600.0


def worker_runtime_env(env_vars: dict[str, str] | None = None) -> dict[str, Any]:
    """A Ray runtime environment with ``WORKER_ENV_VARS`` (``env_vars`` override them)."""
    return {"env_vars": {**WORKER_ENV_VARS, **(env_vars or {})}}


def local_ray_init_kwargs(num_cpus: int) -> dict[str, Any]:
    """``ray.init`` arguments for a local Ray instance of ``num_cpus`` logical CPUs."""
    return {
        "num_cpus": num_cpus,
        "include_dashboard": False,
        "runtime_env": worker_runtime_env(),
    }


def init_ray(ray_init_kwargs: dict[str, Any] | None, *, num_cpus: int) -> None:
    """Start or join Ray in this process.

    ``ray_init_kwargs=None`` starts a local instance (``local_ray_init_kwargs``); a dict is
    passed to ``ray.init`` as given (``{"address": "auto"}`` joins the cluster this machine
    belongs to). A process where Ray already runs keeps its instance, and then giving
    ``ray_init_kwargs`` is an error: they could not take effect.
    """
    ray = import_ray()
    if ray.is_initialized():
        if ray_init_kwargs is not None:
            raise ValueError(
                "make_ray_collector: Ray is already initialised in this process, so "
                f"ray_init_kwargs={ray_init_kwargs} cannot take effect; pass "
                "ray_init_kwargs=None to use the running instance"
            )
        return
    if ray_init_kwargs is None:
        # usage statistics would be sent to Ray's servers from every local instance
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        ray_init_kwargs = local_ray_init_kwargs(num_cpus)
    log.info("ray.init(%s)", ray_init_kwargs)
    ray.init(**ray_init_kwargs)


def import_ray():
    """The ``ray`` module, or an ImportError that says how to install it."""
    try:
        import ray
    except ImportError as error:
        raise ImportError(
            "pilerl's Ray support needs the ray package: pip install -e '.[ray]'"
        ) from error
    return ray


def check_cluster_cpus(num_collectors: int) -> None:
    """Fail now if the Ray cluster cannot ever place ``num_collectors`` actors."""
    needed = num_collectors * CPUS_PER_COLLECTOR
    available = import_ray().cluster_resources().get("CPU", 0.0)
    if available < needed:
        raise ValueError(
            f"make_ray_collector: {num_collectors} collectors need {needed} CPUs but the "
            f"Ray cluster has {available:g}; start Ray with more CPUs (ray start "
            "--num-cpus=...) or use fewer collectors"
        )


def make_ray_collector(
    create_env_fn: Callable[[], EnvBase],
    policy: Callable | None,
    *,
    frames_per_batch: int,
    total_frames: int,
    num_collectors: int,
    ray_init_kwargs: dict[str, Any] | None = None,
    sync: bool = False,
    seed: int | None = None,
    **collector_options: Any,
) -> RayCollector:
    """A TorchRL ``RayCollector`` running ``num_collectors`` simulators as Ray actors.

    Args:
        create_env_fn: builds one TorchRL env inside an actor; it is pickled with
            cloudpickle, so use a module-level function or ``functools.partial`` (e.g.
            ``partial(make_torchrl_env, "pile_loader", condition="winter_c")``).
        policy: a TensorDict module (e.g. from ``pilerl.policies.make_actor``); its weights
            are sent to every actor before collection. ``None``: TorchRL's
            ``RandomPolicy`` over the env's action spec.
        frames_per_batch: frames in each yielded batch.
        total_frames: frames to collect in all; iteration stops once they are reached
            (a multiple of ``frames_per_batch`` gives exactly that many).
        num_collectors: Ray actors, one simulator each.
        ray_init_kwargs: ``None`` starts a local Ray instance (or uses the one this
            process already runs); otherwise arguments for ``ray.init`` such as
            ``{"address": "auto"}`` or ``{"address": "ray://head:10001"}``.
        sync: ``False`` (TorchRL's default) yields each actor's batch as it arrives, shape
            ``[frames_per_batch]``; ``True`` waits for all actors and stacks their shares,
            shape ``[num_collectors, frames_per_batch // num_collectors]`` (time last, like
            ``MultiSyncCollector`` with ``cat_results="stack"``).
        seed: seeds the actors' envs (TorchRL's ``set_seed``: each actor its own seed).
        **collector_options: more ``RayCollector`` arguments, e.g. ``exploration_type``,
            ``max_frames_per_traj`` or ``collector_kwargs={"auto_register_policy_transforms":
            False}`` for the ``Collector`` inside each actor.

    Call ``collector.shutdown()`` when done if you stop before ``total_frames``; Ray
    itself stays up until ``ray.shutdown()`` or the end of the process.
    """
    for name, value in (
        ("frames_per_batch", frames_per_batch),
        ("total_frames", total_frames),
        ("num_collectors", num_collectors),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"make_ray_collector: {name} must be a positive int, got {value!r}")
    if sync and frames_per_batch % num_collectors:
        raise ValueError(
            f"make_ray_collector: with sync=True frames_per_batch ({frames_per_batch}) must "
            f"be a multiple of num_collectors ({num_collectors})"
        )
    init_ray(ray_init_kwargs, num_cpus=num_collectors * CPUS_PER_COLLECTOR)
    check_cluster_cpus(num_collectors)

    from torchrl.collectors.distributed import RayCollector

    allow_slow_weight_sync(WEIGHT_SYNC_TIMEOUT_S)
    collector = RayCollector(
        create_env_fn,
        policy,
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        num_collectors=num_collectors,
        remote_configs={"num_cpus": CPUS_PER_COLLECTOR, "runtime_env": worker_runtime_env()},
        sync=sync,
        **collector_options,
    )
    if seed is not None:
        collector.set_seed(seed)
    if policy is not None:
        collector.update_policy_weights_(policy)  # actors start from these weights
    return collector


def allow_slow_weight_sync(timeout_s: float) -> None:
    """Give Ray actors ``timeout_s`` to join TorchRL's weight-sync process group.

    TorchRL 0.14 reads the rendezvous timeout from a module constant at each connection
    (``torchrl.weight_update._ray._DIST_TIMEOUT``, 60 s) and offers no argument for it, so
    it is set here; a TorchRL without that constant is left as it is (its own timeout).
    """
    from datetime import timedelta

    from torchrl.weight_update import _ray as torchrl_ray_weights

    if hasattr(torchrl_ray_weights, "_DIST_TIMEOUT"):
        torchrl_ray_weights._DIST_TIMEOUT = timedelta(seconds=timeout_s)
