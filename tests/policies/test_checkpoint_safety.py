"""Checkpoints cannot run code, blow up memory, loop forever or load corrupted, and a
fine-tuning run survives SIGKILL at any moment.

The attacks and verdicts are in ``tests/policies/checkpoint_cases.py``;
``benchmarks/checkpoint_robustness.py`` runs more of them and prints the case table.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import torch
from checkpoint_cases import (
    ATTACKS,
    CLEAN,
    Attack,
    RunsCodeOnLoad,
    actor_huge_edits,
    resumed_state,
    run_huge_edits,
    same_actor,
    same_tree,
    small_actor_file,
    small_forest_file,
    small_run_file,
    verdict,
)
from hydra import compose, initialize_config_dir
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from pilerl.config import register_configs
from pilerl.policies import CheckpointError, actor_policy, load_actor
from pilerl.rl import finetune
from pilerl.rl.finetuning import RUN_CHECKPOINT
from pilerl.rl.run_checkpoint import load_run

ROOT = Path(__file__).resolve().parents[2]
register_configs()


@pytest.fixture(scope="module")
def base_files(tmp_path_factory) -> dict[str, Path]:
    """A saved NNet, a saved two-tree forest and a TD3+BC ``last.ckpt`` (40 transitions)."""
    root = tmp_path_factory.mktemp("base")
    nnet = small_actor_file(root)
    (root / "run").mkdir()
    return {
        "nnet": nnet,
        "forest": small_forest_file(root),
        "run": small_run_file(nnet, root / "run"),
    }


# ---------------------------------------------------------------- one case of each defect


def test_a_pickled_leaf_in_an_actor_is_refused_without_running(base_files, tmp_path):
    payload = torch.load(base_files["nnet"], weights_only=True)
    marker = tmp_path / "code-ran"
    payload["state_dict"]["normalizer.mean"] = RunsCodeOnLoad(marker)
    torch.save(payload, tmp_path / "evil.pt")
    with pytest.raises(CheckpointError, match="pickled Python objects") as error:
        load_actor(tmp_path / "evil.pt")
    assert not marker.exists()
    assert "weights_only" not in str(error.value) and error.value.__cause__ is None


@pytest.mark.parametrize("component", [("rng", "torch"), ("learner", "loss")])
def test_a_pickled_leaf_in_last_ckpt_is_refused_on_resume(base_files, tmp_path, component):
    payload = torch.load(base_files["run"], weights_only=True)
    marker = tmp_path / "code-ran"
    payload[component[0]][component[1]] = RunsCodeOnLoad(marker)
    torch.save(payload, tmp_path / RUN_CHECKPOINT)
    with pytest.raises(CheckpointError, match="pickled Python objects"):
        resumed_state(base_files["nnet"])(tmp_path / RUN_CHECKPOINT)
    assert not marker.exists()


def test_a_bit_flip_in_best_pt_is_refused(base_files, tmp_path):
    data = bytearray(base_files["nnet"].read_bytes())
    weights = data.find(b"data/0")  # the first tensor record's name, just before its bytes
    data[weights + 200] ^= 0x10
    (tmp_path / "best.pt").write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=r"best\.pt: corrupted"):
        load_actor(tmp_path / "best.pt")


def test_a_version_1_actor_without_digest_still_loads(base_files, tmp_path):
    payload = torch.load(base_files["nnet"], weights_only=True)
    payload.pop("sha256")
    payload["version"] = 1
    torch.save(payload, tmp_path / "old.pt")
    assert same_actor(base_files["nnet"])(load_actor(tmp_path / "old.pt"))


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_weights_are_refused(base_files, tmp_path, value):
    payload = torch.load(base_files["nnet"], weights_only=True)
    payload.pop("sha256")
    payload["version"] = 1  # a digest-less file: the content check alone refuses it
    payload["state_dict"]["controller.output.weight"][0, 0] = value
    torch.save(payload, tmp_path / "poisoned.pt")
    with pytest.raises(CheckpointError, match="controller.output.weight"):
        load_actor(tmp_path / "poisoned.pt")


def test_a_forest_with_a_huge_depth_or_a_cycle_is_refused_not_looped(base_files, tmp_path):
    same = same_actor(base_files["forest"])
    assert same(load_actor(base_files["forest"]))
    for edit in actor_huge_edits(base_files["forest"])[-5:]:
        target = tmp_path / "forest.pt"
        Attack("huge", 0).apply(base_files["forest"], target, tmp_path / "m", [edit])
        with pytest.raises(CheckpointError, match="random forest"):
            load_actor(target)


def test_declared_sizes_beyond_the_tensors_present_allocate_nothing(base_files, tmp_path):
    """In a fresh process: every crafted size is refused and the peak memory barely grows
    (before: 60,000 hidden units allocated 14 GB, a forest depth of 1e15 looped)."""
    paths = []
    for name in ("nnet", "forest"):
        for i, edit in enumerate(actor_huge_edits(base_files[name])):
            paths.append(tmp_path / f"{name}_{i}.pt")
            Attack("huge", 0).apply(base_files[name], paths[-1], tmp_path / "m", [edit])
    script = (
        "import json, resource, sys\n"
        "from pilerl.policies import CheckpointError, load_actor\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "refused = 0\n"
        "for path in sys.argv[1:]:\n"
        "    try:\n"
        "        load_actor(path)\n"
        "    except CheckpointError:\n"
        "        refused += 1\n"
        "grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before\n"
        "print(json.dumps({'refused': refused, 'grown_kib': grown}))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script, *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert result.returncode == 0, result.stderr[-2000:]
    outcome = json.loads(result.stdout.strip().splitlines()[-1])
    assert outcome["refused"] == len(paths)
    assert outcome["grown_kib"] < 100 * 1024  # < 100 MiB over the imports


def test_an_old_torchrl_archive_or_another_runs_file_is_refused(base_files, tmp_path):
    (tmp_path / RUN_CHECKPOINT).write_bytes(b"\x1f\x8b old torchrl tensordict archive")
    with pytest.raises(CheckpointError, match="not a readable pilerl fine-tuning checkpoint"):
        load_run(tmp_path / RUN_CHECKPOINT)


# ---------------------------------------------------------------- properties


PROPERTY_SETTINGS = settings(
    max_examples=60,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


@PROPERTY_SETTINGS
@given(
    base=st.sampled_from(["nnet", "forest"]),
    kind=st.sampled_from(ATTACKS),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_attacked_actor_is_refused_or_loads_identically(base_files, base, kind, seed):
    original = base_files[base]
    with tempfile.TemporaryDirectory() as scratch:
        target, marker = Path(scratch) / "best.pt", Path(scratch) / "code-ran"
        Attack(kind, seed).apply(original, target, marker, actor_huge_edits(original))
        outcome = verdict(load_actor, target, marker, same_actor(original))
    assert outcome in CLEAN, f"{kind} (seed {seed}) on {base}: {outcome}"


@settings(
    max_examples=24,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(kind=st.sampled_from(ATTACKS), seed=st.integers(0, 2**32 - 1))
def test_every_attacked_run_checkpoint_is_refused_or_resumes_identically(base_files, kind, seed):
    load = resumed_state(base_files["nnet"])
    original = load(base_files["run"])
    with tempfile.TemporaryDirectory() as scratch:
        target, marker = Path(scratch) / RUN_CHECKPOINT, Path(scratch) / "code-ran"
        huge = run_huge_edits(base_files["run"])
        Attack(kind, seed).apply(base_files["run"], target, marker, huge)
        outcome = verdict(load, target, marker, lambda got: same_tree(list(got), list(original)))
    assert outcome in CLEAN, f"{kind} (seed {seed}) on last.ckpt: {outcome}"


# ---------------------------------------------------------------- kill -9 during fine-tuning

KILLS = 3  # SIGKILLs per test (benchmarks/checkpoint_robustness.py runs more)
KILL_SEED = 13
RECIPE_OVERRIDES = [
    "curriculum.stages=[{frames: 256, conditions: {winter_c: 1, summer: 1}}]",
    "algorithm.frames_per_batch=64",
    "algorithm.epochs=2",
    "algorithm.minibatch_size=32",
    "algorithm.critic_warmup_batches=1",
    "collection.envs_per_worker=2",
    "+evaluation.groups.winter=[winter_c]",
    "evaluation.every_frames=128",
    "evaluation.episodes=1",
    "evaluation.final_episodes=1",
    "checkpoint_every_frames=64",
]


def recipe_command(checkpoint: Path, run_dir: Path) -> list[str]:
    return [
        sys.executable,
        str(ROOT / "recipes" / "finetune.py"),
        f"checkpoint={checkpoint}",  # demos: the default folder, absent here (PPO needs none)
        *RECIPE_OVERRIDES,
        f"hydra.run.dir={run_dir}",
    ]


def reference_run(checkpoint: Path, run_dir: Path) -> float:
    """The same config, uninterrupted, in this process; returns its duration [s]."""
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(
            config_name="finetune",
            overrides=[f"checkpoint={checkpoint}", *RECIPE_OVERRIDES, f"output_dir={run_dir}"],
        )
    started = time.perf_counter()
    with torch.random.fork_rng(devices=[]):
        finetune(OmegaConf.to_object(cfg), run_dir, progress=False)
    return time.perf_counter() - started


def kill_recipe_at_random_moments(
    checkpoint: Path, run_dir: Path, *, kills: int, seed: int, run_s: float
) -> list[str]:
    """Start the recipe, SIGKILL it a random time after its main() began (``.hydra``
    written), ``kills`` times; after each kill ``last.ckpt`` must be absent or whole.
    Returns what each kill left: ``none`` / ``whole`` / ``finished``, with ``+temp`` when
    it interrupted a write (its temporary file left behind)."""
    rng = random.Random(seed)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MUJOCO_GL": "egl"}
    left = []
    for _ in range(kills):
        process = subprocess.Popen(
            recipe_command(checkpoint, run_dir),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        deadline = time.monotonic() + 120
        while not (run_dir / ".hydra").exists() and process.poll() is None:
            if time.monotonic() > deadline:
                process.kill()
                raise AssertionError("the recipe did not start within 120 s")
            time.sleep(0.05)
        time.sleep(rng.uniform(0.0, 1.2 * run_s))
        finished = process.poll() is not None
        if not finished:
            process.send_signal(signal.SIGKILL)
        process.wait(timeout=60)
        checkpoint_file = run_dir / RUN_CHECKPOINT
        if checkpoint_file.exists():
            load_run(checkpoint_file)  # raises CheckpointError if the kill broke it
        state = "finished" if finished else "whole" if checkpoint_file.exists() else "none"
        left.append(state + ("+temp" if any(run_dir.glob(".last.*.ckpt")) else ""))
    return left


def test_finetune_recipe_killed_at_random_moments_resumes_to_the_same_weights(base_files, tmp_path):
    run_s = reference_run(base_files["nnet"], tmp_path / "reference")
    run_dir = tmp_path / "killed"
    kill_recipe_at_random_moments(
        base_files["nnet"], run_dir, kills=KILLS, seed=KILL_SEED, run_s=run_s
    )
    plant_interrupted_writes(run_dir)
    result = subprocess.run(
        recipe_command(base_files["nnet"], run_dir),
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1", "MUJOCO_GL": "egl"},
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert_run_matches(run_dir, tmp_path / "reference")


def plant_interrupted_writes(run_dir: Path) -> None:
    """What a kill in the middle of writing leaves (a write takes about a millisecond
    here, so random kills rarely land in one): temporary files of ``atomic_path`` with
    half their bytes, and a torn last CSV row."""
    if (run_dir / RUN_CHECKPOINT).exists():
        data = (run_dir / RUN_CHECKPOINT).read_bytes()
        (run_dir / ".last.k1ll3d.ckpt").write_bytes(data[: len(data) // 2])
    (run_dir / ".best.k1ll3d.pt").write_bytes(b"PK\x03\x04 half a zip")
    for csv in (run_dir / "finetune" / "scalars").glob("*.csv"):
        with csv.open("a") as log:
            log.write("99999999,0.")  # no newline: the kill came mid-row
        break


def assert_run_matches(run_dir: Path, reference_dir: Path) -> None:
    """Same final weights, no temporary files, no duplicated log rows."""
    finished = actor_policy(load_actor(run_dir / "final.pt")).state_dict()
    reference = actor_policy(load_actor(reference_dir / "final.pt")).state_dict()
    assert all(torch.equal(finished[k], reference[k]) for k in reference)
    leftovers = [p.name for p in run_dir.rglob(".*") if p.is_file() and ".hydra" not in p.parts]
    assert not leftovers, leftovers
    for csv in (run_dir / "finetune" / "scalars").glob("*.csv"):
        steps = [line.split(",")[0] for line in csv.read_text().splitlines()]
        assert len(steps) == len(set(steps)), f"{csv.name} repeats steps"
    assert json.loads((run_dir / "results.json").read_text())["frames"] == 256


def test_resume_state_is_the_saved_state(base_files, tmp_path):
    """Sanity for the property above: an untouched last.ckpt resumes to what was saved."""
    load = resumed_state(base_files["nnet"])
    first, second = load(base_files["run"]), load(base_files["run"])
    assert same_tree(list(first), list(second))
    assert first[0]["frames"] == 40 and first[1]["replay"]["size"] == 40
