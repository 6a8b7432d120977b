"""No process outlives a job killed with SIGKILL: pool workers die with their parent.

Each test starts a real job in a subprocess, waits until its workers run, SIGKILLs the
job and checks that every process it had started is gone (bounded wait, not a timing
claim: the workers are killed by the kernel when their parent dies).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from pilerl.runtime import die_with_parent

REPO = Path(__file__).resolve().parents[2]
GONE_WITHIN_S = 30.0  # upper bound of the wait; the kernel usually needs milliseconds

pytestmark = pytest.mark.skipif(
    not Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").exists(),
    reason="needs Linux /proc/<pid>/task/<pid>/children",
)


def children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except FileNotFoundError:
        return []
    return [int(p) for p in text.split()]


def descendants(pid: int) -> list[int]:
    found = []
    for child in children(pid):
        found += [child, *descendants(child)]
    return found


def alive(pid: int) -> bool:
    """Running (a zombie waiting for its reaper counts as dead)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "State:\tZ" not in status


def start_job(script: str, env_extra: dict | None = None) -> subprocess.Popen:
    env = {
        **os.environ,
        "PYTHONPATH": f"{REPO}:{REPO / 'envs'}",
        "OMP_NUM_THREADS": "1",
        **(env_extra or {}),
    }
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script)],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def kill_and_check_no_orphans(job: subprocess.Popen, *, workers: int) -> None:
    """Wait for the job's 'ready' line, SIGKILL it, assert its descendants die."""
    spawned: list[int] = []
    try:
        assert job.stdout.readline().strip() == "ready"
        spawned = descendants(job.pid)
        assert len(spawned) >= workers, f"expected >= {workers} workers, found {spawned}"
        os.kill(job.pid, signal.SIGKILL)
        job.wait(timeout=GONE_WITHIN_S)
        deadline = time.monotonic() + GONE_WITHIN_S
        while any(alive(p) for p in spawned) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [p for p in spawned if alive(p)], "orphans survived their parent"
    finally:
        for pid in [job.pid, *descendants(job.pid), *spawned]:  # never leave orphans behind
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        job.stdout.close()


def test_pool_workers_die_when_their_parent_is_killed():
    job = start_job(
        """
        import time
        from pilerl.runtime import process_pool
        pool = process_pool(2)
        futures = [pool.submit(time.sleep, 600) for _ in range(2)]
        time.sleep(0.5)  # both workers busy sleeping
        print("ready", flush=True)
        time.sleep(600)
        """
    )
    kill_and_check_no_orphans(job, workers=2)


def test_recording_workers_die_when_record_py_is_killed(tmp_path):
    """The real recording path: ``record_demonstrations`` with 2 worker processes."""
    job = start_job(
        f"""
        import os, threading, time
        from pathlib import Path
        from pilerl.data import EpisodeStore, RecordingPlan, record_demonstrations
        from pilerl.sim import make_gym_env
        env = make_gym_env("pile_loader").unwrapped
        store = EpisodeStore.create(
            {str(tmp_path / "demos")!r}, sensors=env.sensor_units,
            controls=list(env.control_names),
        )
        plan = RecordingPlan("pile_loader", {{"control_hz": 20.0}}, n_episodes=40, seed=3)
        def announce():  # once both recording workers run
            me = os.getpid()
            while len(Path(f"/proc/{{me}}/task/{{me}}/children").read_text().split()) < 2:
                time.sleep(0.05)
            print("ready", flush=True)
        threading.Thread(target=announce, daemon=True).start()
        record_demonstrations(store, plan, workers=2, progress=False)
        print("finished too early", flush=True)
        """
    )
    kill_and_check_no_orphans(job, workers=2)


def test_die_with_parent_refuses_a_parent_that_is_already_gone():
    """The worker initializer exits at once if the parent died before it ran."""
    reader, writer = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: pretend the parent is someone else
        os.close(reader)
        try:
            die_with_parent(os.getppid() + 1_000_000)
        finally:
            os.write(writer, b"survived")
            os._exit(0)
    os.close(writer)
    _, status = os.waitpid(pid, 0)
    assert os.read(reader, 100) == b""  # exited inside die_with_parent
    os.close(reader)
    assert os.waitstatus_to_exitcode(status) == 1
