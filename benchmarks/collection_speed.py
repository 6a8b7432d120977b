"""Frames per second of fine-tuning's collection vs raw simulator stepping.

    python benchmarks/collection_speed.py
    python benchmarks/collection_speed.py --checkpoint data/checkpoints/dannet_d_ii/best.pt \
        --frames 8192 --workers 2 --envs 8

Rows (same conditions mixture, same actor, measured in this run):

| row | what |
|---|---|
| raw env (fixed action) | ``ConditionMixtureEnv.step``, one simulator, action [0.2, 0.1, 0.6] |
| raw env + actor | the same, the cloned actor choosing each action (no TorchRL) |
| Collector, 1 env | TorchRL ``Collector`` over ``GymWrapper``, fine-tuning's PPO policy |
| Collector, E envs | the same over E simulators batched in one ``SimulatorBatchEnv`` |
| MultiSyncCollector | TorchRL multi-process collector, W workers x E envs each |
| replay: ... | the simulators a collector row stepped, rebuilt with the same seeds and |
| | stepped in this process with the actions that collector took (no actor, no |
| | TorchRL): what the simulators alone cost on those trajectories |

The policy is what PPO fine-tuning collects with: ``PPOLearner.collection_policy``, the
fused sampler around ``make_stochastic_actor(actor)``
(``pilerl.policies.collection_policy``); ``--policy probabilistic`` collects with the
``ProbabilisticActor`` itself (what main collected with; bit-identical batches).

Two ratios. ``x fixed`` is against the first row, the baseline the issue's figures used:
one simulator driven by a fixed action. It mixes two things: what collection adds, and what
the simulator costs on other trajectories (the actor's actions drive the machine into
other states than the fixed action's, at another cost per step). ``x replay`` is each
collector row against the replay of its own simulators and actions: only what collection
adds (the actor, TorchRL, the batched env) counts. The replay checks that it reproduced
the collector's trajectories (equal rewards, observations and episode ends, else it stops
with an error). Issue #18's rows 4-5 are read against ``x replay`` (docs/performance.md
says why); ``x fixed`` is printed beside it.

The collector and its replay are timed alternately, batch by batch over the same frames
(a multi-process collector's workers wait while the replay runs), so that a change in the
machine's load hits both. The first batch (start-up; for the multi-process row the
workers' spawn and imports) is left out of both. Without ``--checkpoint`` an untrained
DANNet with unit statistics stands in (same network size).

``--cpu`` times the one-process rows with this process's CPU time instead of the wall
clock: on a machine loaded by other jobs the wall clock counts the time the scheduler gave
them; the multi-process row is then left out (its work is in the workers).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase

from pilerl.policies import load_actor, make_actor, make_stochastic_actor
from pilerl.rl.collection import make_collector
from pilerl.rl.envs import ConditionMixtureEnv, TrainingEnvFactory
from pilerl.runtime import limit_threads

CONDITIONS = {"summer": 1.0, "winter_a": 1.0, "winter_b": 1.0, "winter_c": 1.0, "winter_d": 1.0}
REWARDS = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}
SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ATTENTION = [*SENSORS, "boom_pressure", "bucket_pressure", "pump_angle"]
FIXED_ACTION = [0.2, 0.1, 0.6]
CHECKED_SENSOR = "boom_angle"  # the observation the replay compares (besides the reward)
POLICIES = ("fused", "probabilistic")


def cloned_actor(checkpoint: str | None):
    if checkpoint:
        return load_actor(checkpoint)
    stats = {"sensors": {name: {"mean": 0.0, "std": 1.0} for name in ATTENTION}}
    return make_actor("dannet", sensors=SENSORS, stats=stats, attention_sensors=ATTENTION).eval()


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def raw_fps(frames: int, actor=None, *, clock=time.perf_counter) -> float:
    env = ConditionMixtureEnv("pile_loader", {}, CONDITIONS, REWARDS)
    obs, _ = env.reset(seed=0)
    action = np.array(FIXED_ACTION, dtype=np.float32)
    started = clock()
    for _ in range(frames):
        if actor is not None:
            with torch.no_grad():
                td = TensorDict({k: torch.as_tensor(v) for k, v in obs.items()}, [])
                action = actor(td)["action"].numpy()
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset()
    elapsed = clock() - started
    env.close()
    return frames / elapsed


class Replay:
    """A collector's simulators rebuilt and stepped with the actions it took, in this process.

    Simulator ``i`` is built with seed ``i`` (``make_collector``'s seeds with ``seed=0``:
    worker ``k``'s sub-env ``j`` is ``k * envs + j``) and reset once, as the collector
    resets its env once when it is built. ``step`` takes one collected batch and steps
    every simulator through it, all simulators at each time step (the batched env's
    order), resetting those whose episode ended.
    """

    def __init__(self, simulators: int) -> None:
        self.envs = [
            ConditionMixtureEnv("pile_loader", {}, CONDITIONS, REWARDS, seed=i)
            for i in range(simulators)
        ]
        for env in self.envs:
            env.reset()

    def step(self, batch: TensorDictBase) -> None:
        """Replay ``batch`` (time last, any leading dims: ``[..., T]``).

        Raises:
            RuntimeError: a reward, the checked sensor or an episode end differs from what
                the collector recorded (then this is not the same work).
        """
        rows = batch.reshape(-1, batch.shape[-1]) if batch.ndim > 1 else batch.unsqueeze(0)
        if rows.shape[0] != len(self.envs):
            raise RuntimeError(f"replay: {rows.shape[0]} simulators for {len(self.envs)}")
        actions = rows["action"].numpy()
        n, steps = rows.shape
        rewards = np.zeros((n, steps), dtype=np.float32)
        sensor = np.zeros((n, steps), dtype=np.float32)
        done = np.zeros((n, steps), dtype=bool)
        for t in range(steps):
            for i, env in enumerate(self.envs):
                obs, rewards[i, t], terminated, truncated, _ = env.step(actions[i, t])
                sensor[i, t] = obs[CHECKED_SENSOR][0]
                done[i, t] = terminated or truncated
                if done[i, t]:
                    env.reset()
        for name, got, want in (
            ("reward", rewards, rows["next", "reward"]),
            (CHECKED_SENSOR, sensor, rows["next", CHECKED_SENSOR]),
            ("done", done, rows["next", "done"]),
        ):
            want = want.reshape(n, steps).numpy()
            if not np.array_equal(got, want):
                where = np.argwhere(got != want)[0]
                raise RuntimeError(
                    f"replay: {name} differs from the collector's at simulator {where[0]}, "
                    f"step {where[1]} of a batch: not the same trajectories"
                )

    def close(self) -> None:
        for env in self.envs:
            env.close()


def collection_policy(actor, policy: str):
    """PPO's collection policy around ``actor`` (``fused``) or its ``ProbabilisticActor``."""
    stochastic = make_stochastic_actor(actor)
    if policy == "probabilistic":
        return stochastic
    # imported here: ``--policy probabilistic`` also runs on versions without it
    from pilerl.policies.collection_policy import make_collection_policy

    return make_collection_policy(stochastic)


def collector_fps(
    frames: int,
    frames_per_batch: int,
    actor,
    *,
    backend: str,
    policy: str = "fused",
    workers: int = 1,
    envs: int = 1,
    clock=time.perf_counter,
) -> tuple[float, float]:
    """(collector, replay) frames/s, batch by batch alternately over the same frames.

    After each batch the collector's simulators are replayed through it (a multi-process
    collector's workers wait meanwhile: they collect when the next batch is asked for),
    so both meet the same machine load. The first batch (start-up) is replayed untimed.
    """
    factory = TrainingEnvFactory("pile_loader", {}, CONDITIONS, REWARDS, num_envs=envs)
    collector = make_collector(
        factory,
        collection_policy(actor, policy),
        frames_per_batch=frames_per_batch,
        total_frames=frames + frames_per_batch,
        backend=backend,
        workers=workers,
    )
    replay = Replay(workers * envs)
    kept = ("action", ("next", "reward"), ("next", "done"), ("next", CHECKED_SENSOR))
    batches = iter(collector)
    replay.step(next(batches).select(*kept))  # start-up: untimed
    counted, collect_s, replay_s = 0, 0.0, 0.0
    while True:
        started = clock()
        batch = next(batches, None)
        collect_s += clock() - started
        if batch is None:
            break
        batch = batch.select(*kept).clone()
        started = clock()
        replay.step(batch)
        replay_s += clock() - started
        counted += batch.numel()
    collector.shutdown()
    replay.close()
    return counted / collect_s, counted / replay_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", default=None, help="a cloned actor (best.pt)")
    parser.add_argument("--frames", type=int, default=8192, help="frames timed per row")
    parser.add_argument("--frames-per-batch", type=int, default=1024)
    parser.add_argument("--workers", type=int, default=2, help="multi-process collector size")
    parser.add_argument("--envs", type=int, default=8, help="simulators batched per collector")
    parser.add_argument(
        "--policy",
        choices=POLICIES,
        default="fused",
        help="the collection policy: PPO's fused sampler or its ProbabilisticActor",
    )
    parser.add_argument("--cpu", action="store_true", help="one-process rows in CPU time")
    args = parser.parse_args()
    clock = CLOCKS["cpu" if args.cpu else "wall"]
    limit_threads()
    torch.manual_seed(0)
    actor = cloned_actor(args.checkpoint)
    frames, per_batch = args.frames, args.frames_per_batch
    rows: list[tuple[str, float, float | None]] = [
        ("raw env (fixed action)", raw_fps(frames, clock=clock), None),
        ("raw env + actor", raw_fps(frames, actor, clock=clock), None),
    ]
    collectors = [
        ("Collector, 1 env", "single", 1, 1),
        (f"Collector, {args.envs} envs", "single", 1, args.envs),
    ]
    if not args.cpu:
        collectors.append(
            (
                f"MultiSyncCollector, {args.workers}x{args.envs}",
                "multiprocess",
                args.workers,
                args.envs,
            )
        )
    for name, backend, workers, envs in collectors:
        fps, replay = collector_fps(
            frames,
            per_batch,
            actor,
            backend=backend,
            policy=args.policy,
            workers=workers,
            envs=envs,
            clock=clock,
        )
        rows.append((f"replay: {workers * envs} simulators", replay, None))
        rows.append((name, fps, replay))
    baseline = rows[0][1]
    unit = "frames/CPU s" if args.cpu else "frames/s"
    print(f"{'row':<30} {unit:>12} {'x fixed':>8} {'x replay':>9}")
    for name, fps, replay in rows:
        versus_replay = f"{fps / replay:>9.2f}" if replay else f"{'':>9}"
        print(f"{name:<30} {fps:>12.0f} {fps / baseline:>8.2f} {versus_replay}")


if __name__ == "__main__":
    main()
