"""Simulator speed: control steps/s and simulated seconds per wall second, per soil model.

For each soil model, in one run and with one intra-op thread per process:

- ``raw mj_step``: ``mujoco.mj_step`` alone on the same compiled model, the same number of
  physics steps (no soil, no Python per step), from the same reset state every round with
  the loop's command held: the ceiling.
- ``simulator loop``: the env's own ``step`` (physics + soil model + sensors), no wrappers.
- ``gymnasium``: ``gymnasium.make`` with its default wrappers.
- ``torchrl x1``: ``make_torchrl_env(...)`` (one simulator, batch ``[]``) driven by
  ``rollout`` with a plain callable fixed-action policy.
- ``torchrl one process xN``: N simulators in one TorchRL env (``num_envs=N``).
- ``ParallelEnv P procs xK``: TorchRL's ``ParallelEnv``, P worker processes with K
  simulators each (``make_torchrl_env(workers=P)``): with TorchRL's shared-memory buffers
  (its default: the parent process spin-polls the workers' done flags) and with
  ``use_buffers=False`` (the parent blocks on the workers' pipes and unpickles each
  step's tensordicts).

The driving is the same for every row: throttle 0.5 with a slow boom/bucket sweep;
episodes reset when they end. From the rounds' seeded start (``reset(seed=0)``, then the
env's own draws) the episodes of a 30 s row last 97, 97, 97 and 108 control steps, and
a fifth runs on to the row's end: the bucket curls and rises as it drives, so it meets
the pile only in some of them and most soil updates find it outside (docs/performance.md,
"The control step's Python"). The loop rows also run each reset's 0.6 s of settling
physics (300 ``mj_step``, five resets: ~10% on top of the row's 15,000), which the raw
row does not: a loop without any Python would time about 0.91x raw. The rows are
timed in turn, ``--repeats`` rounds, and each row reports its median: on a shared machine
the load drifts, and rounds spread it over the rows alike. The multi-process rows measure
scaling only where the machine has idle cores: the script prints the cores and the load
average so a reader can tell (rerun it on a quiet machine for the scaling figures).

``--cpu`` times the one-process rows with this process's CPU time instead of the wall
clock (on a machine loaded by other jobs the wall clock also counts their time) and
leaves out the ``ParallelEnv`` rows, whose work is in the workers.

    python benchmarks/sim_speed.py --soil heightfield          # the default soil model
    python benchmarks/sim_speed.py --soil heightfield --seconds 60 --repeats 5
    python benchmarks/sim_speed.py                              # all soil models
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from pilerl_pile_loader.soil import SOIL_MODELS  # noqa: E402

import pilerl  # noqa: E402,F401
from pilerl.sim import make_torchrl_env  # noqa: E402

ACTION = np.array([0.15, 0.1, 0.5], dtype=np.float32)
CONTROL_DT_S = 0.05  # the default 20 Hz control


def fixed_policy():
    """A plain callable policy writing ``ACTION``: measures the env, not a policy module."""
    action = torch.as_tensor(ACTION)

    def policy(tensordict):
        return tensordict.set("action", action.expand(*tensordict.batch_size, 3))

    return policy


class Row:
    """One measured path: ``run()`` advances ``simulated_s`` simulated seconds."""

    clock: Callable[[], float] = time.perf_counter  # ``time.process_time`` with ``--cpu``

    def __init__(self, name: str, run: Callable[[], None], simulated_s: float, close=None):
        self.name, self.run, self.simulated_s = name, run, simulated_s
        self.close = close or (lambda: None)
        self.times: list[float] = []

    def time_once(self) -> None:
        start = self.clock()
        self.run()
        self.times.append(self.clock() - start)

    @property
    def elapsed_s(self) -> float:
        return statistics.median(self.times)

    @property
    def real_time_factor(self) -> float:
        return self.simulated_s / self.elapsed_s


def rows_for(soil: str, steps: int, batch: int, workers: int, *, processes: bool) -> list[Row]:
    """The rows of one soil model, built and warmed up (start-up is not timed);
    ``processes``: with the ``ParallelEnv`` rows."""
    env = gym.make("pilerl/PileLoading-v0", soil=soil, sensor_noise=0.0)
    raw = env.unwrapped
    dt = raw.dt

    def loop(stepper) -> None:
        env.reset(seed=0)
        for _ in range(steps):
            *_, terminated, truncated, _ = stepper(ACTION)
            if terminated or truncated:
                env.reset()

    loop(env.step)  # warm up
    model, data = raw.model, raw.data
    n_physics = steps * raw.frame_skip

    def raw_steps() -> None:
        # the same start every round (mj_step's cost depends on the state: measured up to
        # 1.5x between the states other rows left behind), driven by the loop's command
        env.reset(seed=0)
        raw.machine.command(*ACTION.tolist())
        mujoco.mj_step(model, data, nstep=n_physics)

    rows = [
        Row("raw mj_step", raw_steps, steps * dt),
        Row("simulator loop", lambda: loop(raw.step), steps * dt),
        Row("gymnasium", lambda: loop(env.step), steps * dt, close=env.close),
    ]
    policy = fixed_policy()

    def torchrl_row(name: str, tenv, n_envs: int) -> Row:
        tenv.set_seed(0)
        tenv.rollout(3, policy)  # warm up (and, for worker processes, wait until started)
        steps_each = max(steps // n_envs, 1)
        return Row(
            name,
            lambda: tenv.rollout(steps_each, policy, break_when_any_done=False),
            steps_each * dt * n_envs,
            close=tenv.close,
        )

    common = {"soil": soil, "sensor_noise": 0.0}
    rows.append(torchrl_row("torchrl x1", make_torchrl_env(**common), 1))
    rows.append(
        torchrl_row(
            f"torchrl one process x{batch}", make_torchrl_env(**common, num_envs=batch), batch
        )
    )
    if not processes:
        return rows
    rows.append(
        torchrl_row(
            f"ParallelEnv {workers} procs x1, shared buffers (parent spins)",
            make_torchrl_env(**common, workers=workers),
            workers,
        )
    )
    rows.append(
        torchrl_row(
            f"ParallelEnv {workers} procs x1, pipes (use_buffers=False)",
            make_torchrl_env(**common, workers=workers, use_buffers=False),
            workers,
        )
    )
    per_worker = max(batch // workers, 1)
    rows.append(
        torchrl_row(
            f"ParallelEnv {workers} procs x{per_worker}, shared buffers",
            make_torchrl_env(**common, workers=workers, num_envs=per_worker),
            workers * per_worker,
        )
    )
    return rows


def print_table(soil: str, rows: list[Row]) -> None:
    by_name = {row.name: row for row in rows}
    raw, loop, one = by_name["raw mj_step"], by_name["simulator loop"], by_name["torchrl x1"]
    print(f"\n### soil = {soil}\n")
    print(
        "| path | control steps/s | sim s per s | vs raw mj_step | vs simulator loop "
        "| vs torchrl x1 |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for row in rows:
        rate = row.real_time_factor
        print(
            f"| {row.name} | {rate / CONTROL_DT_S:,.0f} | {rate:.1f} | "
            f"{rate / raw.real_time_factor:.2f} | {rate / loop.real_time_factor:.2f} | "
            f"{rate / one.real_time_factor:.2f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--soil", choices=sorted(SOIL_MODELS), action="append")
    parser.add_argument("--seconds", type=float, default=40.0, help="simulated seconds per row")
    parser.add_argument("--batch", type=int, default=4, help="simulators in the batched rows")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    parser.add_argument("--repeats", type=int, default=3, help="rounds; each row's median")
    parser.add_argument("--cpu", action="store_true", help="one-process rows in CPU time")
    args = parser.parse_args()
    if args.cpu:
        Row.clock = staticmethod(time.process_time)
    torch.set_num_threads(1)
    steps = int(args.seconds / CONTROL_DT_S)
    load_before = os.getloadavg()
    print(
        f"threads: torch={torch.get_num_threads()}, OMP={os.environ['OMP_NUM_THREADS']}; "
        f"{steps} control steps at 20 Hz (500 Hz physics) per row, median of {args.repeats} "
        f"rounds, {'CPU time' if args.cpu else 'wall clock'}; cores={os.cpu_count()}, "
        "load average before: " + ", ".join(f"{v:.1f}" for v in load_before)
    )
    for soil in args.soil or sorted(SOIL_MODELS):
        rows = rows_for(soil, steps, args.batch, args.workers, processes=not args.cpu)
        for _ in range(args.repeats):
            for row in rows:
                row.time_once()
        for row in rows:
            row.close()
        print_table(soil, rows)
    load_after = os.getloadavg()
    print("\nload average after: " + ", ".join(f"{v:.1f}" for v in load_after) + ".")
    if not args.cpu:
        print(
            f"The ParallelEnv rows show scaling only if {args.workers} cores were idle (load "
            f"average well below {os.cpu_count()} - {args.workers}); on a loaded machine they "
            "measure the share of the cores this run got."
        )


if __name__ == "__main__":
    main()
