"""TorchRL collectors for fine-tuning: in this process, across processes, or on Ray.

| backend | collector | batch shape |
|---|---|---|
| ``single`` | ``Collector``: the env steps in this process | ``[frames_per_batch]`` |
| ``multiprocess`` | ``MultiSyncCollector``: one env per worker process | ``[workers, T]`` |
| ``ray`` | ``pilerl.rl.ray_collection.make_ray_collector`` (TorchRL, Ray) | per that module |

Time is the last batch dimension in every case. The policy runs with
``ExplorationType.RANDOM`` (the learner's exploration). After every update call
``sync_weights(collector)`` so worker processes act with the new weights.

Seeding: the simulators are seeded when they are built (``TrainingEnvFactory.seeded``;
worker ``k`` gets ``seed + k * envs_per_worker``): a TorchRL collector resets its env
once while it is built, before any ``set_seed`` can act, and that first reset decides
the first episodes. ``restart_collection`` reseeds and resets a running collector. With
``single``, the same seeds and the same torch RNG state give bit-identical batches.

``single`` leaves out TorchRL's trajectory ids (``("collector", "traj_ids")``, updated at
every step: ~2% of its collection time, measured in docs/performance.md): fine-tuning
reads episode ends from the ``done`` flags, nothing reads the ids.
"""

from __future__ import annotations

from collections.abc import Callable

from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.envs.utils import ExplorationType

from .config import BACKENDS


def make_collector(
    create_env_fn: Callable,
    policy: TensorDictModule,
    *,
    frames_per_batch: int,
    total_frames: int,
    backend: str = "single",
    workers: int = 1,
    seed: int = 0,
    ray_init_kwargs: dict | None = None,
):
    """A seeded collector yielding ``frames_per_batch`` transitions per iteration.

    Args:
        create_env_fn: a ``TrainingEnvFactory`` (or any picklable callable returning a
            TorchRL env with a ``seeded(seed)`` method giving a seeded copy).
        policy: the learner's collection policy (weights shared in ``single``, copied to
            the workers otherwise).
        total_frames: frames to collect before the iterator ends.
        backend: ``single``, ``multiprocess`` or ``ray``.
        workers: processes (``multiprocess``) or remote collectors (``ray``).
    """
    if backend not in BACKENDS:
        raise ValueError(f"collection backend: unknown {backend!r}; known: {list(BACKENDS)}")
    if workers < 1:
        raise ValueError(f"collection workers: must be >= 1, got {workers}")
    if backend == "single":
        return Collector(
            create_env_fn.seeded(seed),
            policy,
            frames_per_batch=frames_per_batch,
            total_frames=total_frames,
            exploration_type=ExplorationType.RANDOM,
            auto_register_policy_transforms=False,
            track_traj_ids=False,  # ("collector", "traj_ids"): nothing reads them
        )
    if backend == "multiprocess":
        stride = getattr(create_env_fn, "num_envs", 1)
        return MultiSyncCollector(
            [create_env_fn.seeded(seed + k * stride) for k in range(workers)],
            policy,
            frames_per_batch=frames_per_batch,
            total_frames=total_frames,
            exploration_type=ExplorationType.RANDOM,
            cat_results="stack",
        )
    from .ray_collection import make_ray_collector  # needs ray: imported on demand

    return make_ray_collector(  # sync: on-policy batches, [workers, ..., T]
        create_env_fn.seeded(seed),
        policy,
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        num_collectors=workers,
        ray_init_kwargs=ray_init_kwargs or None,
        sync=True,
        seed=seed,
    )


def sync_weights(collector) -> None:
    """Send the policy's current weights to the collector's workers (no-op in-process)."""
    if not isinstance(collector, Collector):
        collector.update_policy_weights_()


def restart_collection(collector, seed: int) -> None:
    """Restart every simulator of ``collector`` from ``seed``: a segment's start.

    ``set_seed`` then ``reset``: afterwards the collector's state depends on ``seed`` only
    (not on what it collected before), so a collector reused across segments and one
    built fresh at a segment's start (a resumed run) yield the same batches. Ray's
    collector has no ``reset``: its simulators take the seeds at their next reset.
    """
    collector.set_seed(seed)
    if hasattr(collector, "reset"):
        collector.reset()
