"""An 8-job sweep's wall time: Hydra's sequential launcher vs the local parallel launcher.

Both sweeps run the same 8 jobs in the same run, so the ratio is measured on the same
machine state. A job records 40 scripted demonstrations at 100 Hz (~10 s of work,
like a small real job; each worker first spends ~5 s importing torch, TorchRL and
MuJoCo, so jobs of a few seconds measure mostly start-up). The parallel launcher
(``hydra/launcher=local_parallel``: joblib, 2 processes, one thread each) should approach
the number of cores on this 2-core machine, less process start-up.

    python benchmarks/sweep_speed.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
JOBS = 8
JOB = [
    "recipes/record.py",
    "--multirun",
    "n_episodes=40",
    "record_hz=100",
    "workers=1",
    "out_dir=${hydra:runtime.output_dir}/demos",
    f"seed={','.join(str(s) for s in range(JOBS))}",
]


def sweep(launcher: str | None, sweep_dir: str) -> float:
    args = [sys.executable, *JOB, f"hydra.sweep.dir={sweep_dir}"]
    if launcher:
        args.append(f"hydra/launcher={launcher}")
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    subprocess.run(args, check=True, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    finished = len(list(Path(sweep_dir).glob("*/done.json")))
    if finished != JOBS:
        raise RuntimeError(f"{sweep_dir}: {finished} of {JOBS} jobs finished")
    return wall


def main() -> None:
    print(f"{JOBS} record jobs (40 episodes at 100 Hz each), cores={os.cpu_count()}\n")
    print("| launcher | wall s | jobs/min | speed-up vs sequential |")
    print("|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        sequential = sweep(None, f"{tmp}/sequential")
        parallel = sweep("local_parallel", f"{tmp}/parallel")
    for name, wall in (
        ("basic (sequential)", sequential),
        ("local_parallel (joblib x2)", parallel),
    ):
        print(f"| {name} | {wall:.1f} | {JOBS / wall * 60:.1f} | {sequential / wall:.2f} |")


if __name__ == "__main__":
    main()
