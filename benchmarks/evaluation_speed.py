"""Closed-loop evaluation and recording speed: episodes per second, against a hand loop.

In one run, with one intra-op thread per process, on the same seeded episodes:

- ``hand loop``: the baseline, a plain Gymnasium loop (``operator.act`` then ``env.step``
  until the episode ends), what the evaluator ran before the one rollout.
- ``evaluate scripted``: ``pilerl.evaluation.evaluate`` of the scripted operator, on 1
  and on 2 worker processes.
- ``evaluate saved actor``: a saved NNetV2 (``ActorController``), 1 and 2 workers.
- ``record``: ``record_demonstrations`` of the same number of episodes, 1 and 2 workers.

Each row is the best of ``--repeats`` runs: wall seconds, and CPU seconds of this process
and its worker processes together (on a shared, oversubscribed machine the CPU time still
measures the work; the wall time of 2 workers shows the parallel speed-up only on idle
cores). The ratio is the hand loop's CPU time over the row's. Only the public calls are
timed, so the same script measures any version of pilerl (``PYTHONPATH`` pointing at
another checkout).

    python benchmarks/evaluation_speed.py
    python benchmarks/evaluation_speed.py --episodes 8 --repeats 3
    python benchmarks/evaluation_speed.py --episodes 1 \
        --conditions summer,winter_a,winter_b,winter_c,winter_d   # a train_bc job's test
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402

from pilerl.data import EpisodeStore, RecordingPlan, record_demonstrations  # noqa: E402
from pilerl.evaluation.evaluator import (  # noqa: E402
    ActorController,
    EvaluationPlan,
    ScriptedController,
    evaluate,
)
from pilerl.policies import make_actor, save_actor  # noqa: E402
from pilerl.sim import get_simulator, make_gym_env  # noqa: E402

CONDITIONS = ("summer", "winter_c")
SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
STATS = {
    "sensors": {name: {"mean": 0.0, "std": 1.0} for name in SENSORS},
    "action": {"mean": [0.0, 0.0, 0.0], "std": [1.0, 1.0, 1.0]},
}


def hand_loop(plan: EvaluationPlan) -> None:
    """The scripted operator in a plain Gymnasium loop, episode after episode."""
    for condition in plan.conditions:
        env = make_gym_env(plan.simulator, **plan.env_kwargs, condition=condition)
        operator = get_simulator(plan.simulator).make_expert(dt=float(env.unwrapped.dt))
        for index in range(plan.episodes):
            operator.reset()
            obs, _ = env.reset(seed=plan.seed * 100_000 + index)
            while True:
                obs, _, terminated, truncated, _ = env.step(operator.act(obs))
                if terminated or truncated:
                    break
        env.close()


def saved_actor(root: Path) -> str:
    """A small NNetV2 that drives into the pile (mostly throttle, a little of the sensors)."""
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=SENSORS, stats=STATS)
    output = actor.module.controller.output
    with torch.no_grad():
        output.weight.mul_(0.1)
        output.bias.copy_(torch.tensor([0.0, 0.0, 2.0]))
    return str(save_actor(root / "actor.pt", actor))


def record(root: Path, episodes: int, workers: int) -> None:
    env = make_gym_env("pile_loader").unwrapped
    store = EpisodeStore.create(
        Path(tempfile.mkdtemp(dir=root)) / "demos",
        sensors=env.sensor_units,
        controls=list(env.control_names),
    )
    plan = RecordingPlan("pile_loader", {"condition": "summer"}, n_episodes=episodes, seed=3)
    record_demonstrations(store, plan, workers=workers, progress=False)


def cpu_seconds() -> float:
    """CPU time of this process and of its finished children [s]."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def best_of(repeats: int, run) -> tuple[float, float]:
    """(best wall seconds, best CPU seconds) of ``repeats`` runs."""
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), cpu_seconds()
        run()
        walls.append(time.perf_counter() - wall)
        cpus.append(cpu_seconds() - cpu)
    return min(walls), min(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=4, help="episodes per condition")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--conditions", default=",".join(CONDITIONS), help="comma-separated condition names"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    conditions = tuple(args.conditions.split(","))
    plan = EvaluationPlan("pile_loader", {}, conditions, episodes=args.episodes, seed=1)
    episodes = args.episodes * len(conditions)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        actor = ActorController(saved_actor(root))
        hand_loop(plan)  # warm up: imports, compiled models
        rows = [("hand loop (baseline)", best_of(args.repeats, lambda: hand_loop(plan)))]
        for workers in (1, 2):
            rows.append(
                (
                    f"evaluate scripted, {workers} worker(s)",
                    best_of(
                        args.repeats,
                        lambda w=workers: evaluate(
                            ScriptedController(), plan, workers=w, progress=False
                        ),
                    ),
                )
            )
        for workers in (1, 2):
            rows.append(
                (
                    f"evaluate saved actor, {workers} worker(s)",
                    best_of(
                        args.repeats,
                        lambda w=workers: evaluate(actor, plan, workers=w, progress=False),
                    ),
                )
            )
        for workers in (1, 2):
            rows.append(
                (
                    f"record, {workers} worker(s)",
                    best_of(args.repeats, lambda w=workers: record(root, episodes, w)),
                )
            )
    baseline = rows[0][1][1]
    print(
        f"{episodes} episodes ({args.episodes} per condition of {conditions}), best of "
        f"{args.repeats}"
    )
    print(f"| {'case':<36} | wall s | CPU s | episodes/CPU s | CPU vs hand loop |")
    print(f"|{'-' * 38}|--------|-------|----------------|------------------|")
    for name, (wall, cpu) in rows:
        print(
            f"| {name:<36} | {wall:6.2f} | {cpu:5.2f} | {episodes / cpu:14.2f} | "
            f"{baseline / cpu:15.2f}x |"
        )


if __name__ == "__main__":
    main()
