"""Crash consistency: SIGKILL at seeded random moments, then the next run succeeds and the
data are consistent (no duplicates, no lost committed episodes, no leftover temporary
files); concurrent writers; pickle-free, schema-checked loading.

The kill tests run real subprocesses, a bounded number of kills each. Every kill is one
case of a small harness (``KillTally``); ``python -m pytest tests/data/test_store_crash.py -s -n 0``
prints the table test | cases | clean | defects.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import torch

from pilerl.data import EpisodeMeta, EpisodeStore, SchemaError, build_dataset, make_episode

REPO = Path(__file__).resolve().parents[2]
SENSORS = {"boom_angle": "rad", "drive_pressure": "MPa"}
CONTROLS = ["boom", "bucket", "throttle"]
WAIT_S = 120.0  # bound on any one subprocess


def episode(n: int, seed: int):
    rows = torch.arange(n, dtype=torch.float32) + seed
    return make_episode(
        sensors={"boom_angle": rows / 100, "drive_pressure": rows},
        next_sensors={"boom_angle": (rows + 1) / 100, "drive_pressure": rows + 1},
        actions=torch.stack([torch.sin(rows), torch.cos(rows), rows * 0 + 0.5], -1),
        time_s=torch.arange(n, dtype=torch.float64) / 20.0,
        rewards=torch.ones(n),
        terminated=True,
    )


def new_store(path: Path, n_episodes: int = 0) -> EpisodeStore:
    store = EpisodeStore.create(path, sensors=SENSORS, controls=CONTROLS)
    for seed in range(n_episodes):
        store.append(episode(12, seed), EpisodeMeta(rate_hz=20.0, seed=seed, success=seed % 2 == 0))
    return store


def leftovers(root: Path) -> list[str]:
    """Temporary files or directories anywhere under ``root``."""
    return sorted(str(p.relative_to(root)) for p in root.rglob(".*") if p.name != ".lock")


def consistency_problems(root: Path, committed: list[int], *, synthetic: bool = True) -> list[str]:
    """What is wrong with the dataset at ``root`` after a kill (empty: consistent)."""
    problems = []
    store = EpisodeStore.open(root)
    seeds = [m.seed for m in store.episodes]
    if len(seeds) != len(set(seeds)):
        problems.append(f"duplicated seeds {seeds}")
    lost = sorted(set(committed) - set(seeds))
    if lost:
        problems.append(f"lost committed episodes {lost}")
    for i, meta in enumerate(store.episodes):
        data = store.load(i)  # every episode loads and passes the schema checks
        if synthetic and data["drive_pressure"][0, 0] != float(meta.seed):
            problems.append(f"episode {i} holds other data than seed {meta.seed}")
    return problems


@dataclass
class KillTally:
    """Cases (kills) of one kill test and those whose aftermath was inconsistent."""

    name: str
    cases: int = 0
    defects: list[str] = field(default_factory=list)

    def record(self, problems: list[str]) -> None:
        self.cases += 1
        if problems:
            self.defects.append(f"case {self.cases}: {problems}")

    def row(self) -> str:
        clean = self.cases - len(self.defects)
        return f"| {self.name} | {self.cases} | {clean} | {len(self.defects)} |"


TALLIES: list[KillTally] = []


def teardown_module() -> None:
    if TALLIES:
        print("\n| test | cases | clean | defects |\n|---|---|---|---|")
        for tally in TALLIES:
            print(tally.row())


def python(script: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": f"{REPO}:{REPO / 'envs'}", "OMP_NUM_THREADS": "1"}
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def kill_after(process: subprocess.Popen, delay_s: float) -> str:
    """Wait for the 'ready' line, SIGKILL ``delay_s`` later; returns the rest of stdout."""
    assert process.stdout.readline().strip() == "ready", process.stderr.read()
    time.sleep(delay_s)
    process.send_signal(signal.SIGKILL)
    out, _ = process.communicate(timeout=WAIT_S)
    return out


APPEND_LOOP = """
    import sys
    sys.path.insert(0, {tests!r})
    from test_store_crash import episode
    from pilerl.data import EpisodeMeta, EpisodeStore
    store = EpisodeStore.create({root!r}, sensors={sensors!r}, controls={controls!r},
                                exist_ok=True)
    print("ready", flush=True)
    for seed in range({first}, {first} + {count}):
        {append}
        print("committed", seed, flush=True)
"""


def append_loop(root: Path, first: int, count: int, *, skip_stored: bool = False):
    """A process appending episodes of seeds ``first ..``; ``skip_stored``: each seed once
    even if another writer stored it (``extend(identity=...)``)."""
    new = "(episode(12, seed), EpisodeMeta(rate_hz=20.0, seed=seed))"
    append = (
        f"store.extend([{new}], identity=lambda m: m.seed)"
        if skip_stored
        else f"store.append(*{new})"
    )
    return python(
        APPEND_LOOP.format(
            tests=str(REPO / "tests" / "data"),
            root=str(root),
            sensors=SENSORS,
            controls=CONTROLS,
            first=first,
            count=count,
            append=append,
        )
    )


def committed_seeds(stdout: str) -> list[int]:
    return [int(line.split()[1]) for line in stdout.splitlines() if line.startswith("committed")]


# ---------------------------------------------------------------------- kill tests
def test_kill_an_appending_loop_at_random_moments(tmp_path):
    tally = KillTally("store: appending loop, SIGKILL")
    TALLIES.append(tally)
    rng = random.Random(13)
    root = tmp_path / "ds"
    committed: list[int] = []
    killed_writers_commits = 0
    for kill in range(6):
        out = kill_after(append_loop(root, first=kill * 1000, count=400), rng.uniform(0.0, 0.6))
        committed += committed_seeds(out)
        killed_writers_commits += len(committed_seeds(out))
        problems = consistency_problems(root, committed)
        # the next writer succeeds and clears what the killed one left
        next_seed = kill * 1000 + 500
        try:
            EpisodeStore.open(root).append(
                episode(12, next_seed), EpisodeMeta(20.0, seed=next_seed)
            )
            committed.append(next_seed)
        except Exception as error:  # noqa: BLE001 - counted as a defect
            problems.append(f"next append failed: {error}")
        problems += consistency_problems(root, committed)
        if leftovers(root):
            problems.append(f"leftovers {leftovers(root)}")
        tally.record(problems)
    assert killed_writers_commits, "no kill came after a commit: the test did not test"
    assert not tally.defects, tally.defects


def test_two_writers_append_to_one_dataset_at_once(tmp_path):
    """Two processes racing on overlapping work: both succeed, each episode stored once."""
    root = tmp_path / "ds"
    writers = [
        append_loop(root, first=0, count=30, skip_stored=True),
        append_loop(root, first=15, count=30, skip_stored=True),
    ]
    outputs = [w.communicate(timeout=WAIT_S) for w in writers]
    assert [w.returncode for w in writers] == [0, 0], [err for _, err in outputs]
    store = EpisodeStore.open(root)
    assert sorted(m.seed for m in store.episodes) == list(range(45))
    assert not consistency_problems(root, list(range(45)))
    assert [m.id for m in store.episodes] == list(range(45))


BUILD = """
    from pilerl.data import EpisodeStore, build_dataset
    source = EpisodeStore.open({source!r})
    print("ready", flush=True)
    build_dataset(source, {out!r}, successful_only=True, rate_hz=10.0, progress=False)
    print("built", flush=True)
"""


def test_kill_build_dataset_at_random_moments(tmp_path):
    tally = KillTally("build_dataset, SIGKILL")
    TALLIES.append(tally)
    rng = random.Random(5)
    source = new_store(tmp_path / "source", n_episodes=60)
    out = tmp_path / "datasets" / "d_ii"
    script = BUILD.format(source=str(source.root), out=str(out))
    for _ in range(3):
        shutil.rmtree(out, ignore_errors=True)
        stdout = kill_after(python(script), rng.uniform(0.0, 1.2))
        problems = []
        if out.exists():  # a dataset at out_dir is always complete
            built = EpisodeStore.open(out)
            if built.stats is None or len(built) != 30 or "built" not in stdout:
                problems.append(f"half-built dataset at {out}: {len(built)} episodes")
        try:  # the same call again, in this process
            build_dataset(source, out, successful_only=True, rate_hz=10.0, progress=False)
        except Exception as error:  # noqa: BLE001 - counted as a defect
            problems.append(f"re-run failed: {error}")
        built = EpisodeStore.open(out)
        if len(built) != 30 or built.stats is None:
            problems.append(f"re-run built {len(built)} episodes, stats {built.stats is not None}")
        stray = [p.name for p in out.parent.iterdir() if p.name != out.name]
        if stray or leftovers(out):
            problems.append(f"leftovers {stray + leftovers(out)}")
        tally.record(problems)
    assert not tally.defects, tally.defects


def test_kill_record_py_at_random_moments(tmp_path):
    """The recipe itself, killed while recording with 2 workers, then run again."""
    tally = KillTally("record.py, SIGKILL")
    TALLIES.append(tally)
    rng = random.Random(2)
    out = tmp_path / "demos"
    command = [
        sys.executable,
        str(REPO / "recipes" / "record.py"),
        "n_episodes=4",
        "record_hz=20",
        "workers=2",
        f"out_dir={out}",
        f"hydra.run.dir={tmp_path / 'run'}",
        "hydra/job_logging=disabled",
    ]
    env = {**os.environ, "PYTHONPATH": f"{REPO}:{REPO / 'envs'}", "OMP_NUM_THREADS": "1"}
    for _ in range(1):
        job = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(rng.uniform(3.0, 9.0))  # imports, then recording
        job.send_signal(signal.SIGKILL)
        job.wait(timeout=WAIT_S)
        exists = (out / "index.json").exists()
        problems = consistency_problems(out, [], synthetic=False) if exists else []
        tally.record(problems)
    finished = subprocess.run(command, env=env, capture_output=True, text=True, timeout=WAIT_S)
    assert finished.returncode == 0, finished.stderr[-2000:]
    store = EpisodeStore.open(out)
    assert sorted(m.seed for m in store.episodes) == [0, 1, 2, 3]
    assert not leftovers(out)
    assert not tally.defects, tally.defects


# ---------------------------------------------------------------------- in-process
def test_an_episode_renamed_but_never_indexed_is_cleared_by_the_next_writer(tmp_path):
    """The state a kill between rename and index update leaves (issue 13): not an error."""
    store = new_store(tmp_path / "ds", n_episodes=2)
    episodes = tmp_path / "ds" / "episodes"
    shutil.copytree(episodes / "ep_000001", episodes / "ep_000002")  # renamed, not listed
    (episodes / ".tmp-killed").mkdir()  # and a half-written temporary directory
    assert len(EpisodeStore.open(tmp_path / "ds")) == 2  # readers ignore both
    store.append(episode(7, 99), EpisodeMeta(rate_hz=20.0, seed=99))
    reopened = EpisodeStore.open(tmp_path / "ds")
    assert [m.seed for m in reopened.episodes] == [0, 1, 99]
    assert reopened.load(2).batch_size == (7,)
    assert not leftovers(tmp_path / "ds")


def test_a_stale_store_object_appends_after_another_writer(tmp_path):
    first = new_store(tmp_path / "ds", n_episodes=1)
    second = EpisodeStore.open(tmp_path / "ds")
    first.append(episode(5, 10), EpisodeMeta(rate_hz=20.0, seed=10))
    second.append(episode(5, 11), EpisodeMeta(rate_hz=20.0, seed=11))  # ids re-read
    assert [m.seed for m in EpisodeStore.open(tmp_path / "ds").episodes] == [0, 10, 11]


class Payload:
    """Unpickling this runs code: the attack the store must never execute."""

    def __reduce__(self):
        return (Path.touch, (Path(os.environ["PILERL_PWNED"]),))


def test_a_pickled_leaf_is_refused_without_running_it(tmp_path, monkeypatch):
    """Issue 13: an episode folder with a pickled leaf ran its payload on load."""
    marker = tmp_path / "pwned"
    monkeypatch.setenv("PILERL_PWNED", str(marker))
    store = new_store(tmp_path / "ds", n_episodes=1)
    folder = tmp_path / "ds" / "episodes" / "ep_000000"
    evil = store.load(0).to_tensordict()
    evil["evil"] = Payload()  # tensordict pickles what it cannot store as a tensor
    shutil.rmtree(folder)
    evil.memmap_(prefix=folder)
    assert (folder / "evil" / "other.pickle").is_file()
    with pytest.raises(SchemaError, match=r"ep_000000: 'evil' is not a tensor leaf"):
        store.load(0)
    with pytest.raises(SchemaError, match="ep_000000"):
        build_dataset(store, tmp_path / "out", successful_only=False, rate_hz=None)
    with pytest.raises(SchemaError, match="ep_000000"):
        store.to_tensordict()
    assert not marker.exists()
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "tamper, message",
    [
        (lambda f: (f / "stray.pkl").write_bytes(b"x"), "stray.pkl"),
        (lambda f: (f / "next" / "x.pt").write_bytes(b"x"), "x.pt"),
        (lambda f: (f / "action.memmap").write_bytes(b"\0" * 8), "action"),
        (lambda f: _edit_meta(f, "time_s", dtype="torch.float32"), "time_s"),
        (lambda f: _edit_meta(f, "action", shape=[12, 4]), "action"),
        (lambda f: _edit_meta(f, "step", dtype="torch.complex64"), "complex64"),
        (lambda f: _edit_meta(f, "_type", value="<class 'os.system'>"), "not a plain TensorDict"),
        (lambda f: _nan_reading(f), "non-finite value in 'drive_pressure' at row 3"),
    ],
    ids=[
        "stray-file",
        "stray-next-file",
        "truncated",
        "dtype",
        "shape",
        "odd-dtype",
        "type",
        "nan",
    ],
)
def test_tampered_episodes_are_refused_naming_the_folder(tmp_path, tamper, message):
    store = new_store(tmp_path / "ds", n_episodes=1)
    folder = tmp_path / "ds" / "episodes" / "ep_000000"
    tamper(folder)
    with pytest.raises(SchemaError, match="ep_000000") as caught:
        store.load(0)
    assert message in str(caught.value)


def test_non_tensor_leaves_are_never_written(tmp_path):
    store = new_store(tmp_path / "ds")
    bad = episode(6, 0)
    bad["note"] = "hello"
    with pytest.raises(SchemaError, match="'note' is not a tensor"):
        store.append(bad, EpisodeMeta(rate_hz=20.0))
    assert len(EpisodeStore.open(tmp_path / "ds")) == 0


def test_build_dataset_with_a_bad_rate_leaves_nothing(tmp_path):
    source = new_store(tmp_path / "source", n_episodes=2)
    for rate in (0.0, -5.0, float("nan"), 7.0):  # 7 Hz does not divide 20 Hz
        with pytest.raises(ValueError, match="rate"):
            build_dataset(source, tmp_path / "out" / "d", successful_only=False, rate_hz=rate)
        assert not (tmp_path / "out" / "d").exists()
        assert not list((tmp_path / "out").glob("*")) if (tmp_path / "out").exists() else True


def test_build_dataset_is_resumable_and_refuses_another_rule(tmp_path):
    source = new_store(tmp_path / "source", n_episodes=4)
    out = tmp_path / "d_ii"
    first = build_dataset(source, out, successful_only=True, rate_hz=None, progress=False)
    again = build_dataset(source, out, successful_only=True, rate_hz=None, progress=False)
    assert len(first) == len(again) == 2 and again.stats == first.stats
    with pytest.raises(FileExistsError, match="a dataset already exists here"):
        build_dataset(source, out, successful_only=False, rate_hz=None, progress=False)


def test_a_dataset_built_from_an_earlier_recording_at_the_same_path_is_not_reused(tmp_path):
    """Re-recorded demonstrations (another expert, say) in a fresh store at the old
    store's path: the dataset built from the old one is refused, not handed back."""
    source = new_store(tmp_path / "source", n_episodes=4)
    out = tmp_path / "d_i"
    build_dataset(source, out, successful_only=False, rate_hz=None, progress=False)
    shutil.rmtree(tmp_path / "source")
    rerecorded = EpisodeStore.create(tmp_path / "source", sensors=SENSORS, controls=CONTROLS)
    for seed in range(4):  # the same seeds, lengths and successes, by another operator
        meta = EpisodeMeta(rate_hz=20.0, seed=seed, success=seed % 2 == 0, operator={"id": 1})
        rerecorded.append(episode(12, seed), meta)
    with pytest.raises(FileExistsError, match="a dataset already exists here"):
        build_dataset(rerecorded, out, successful_only=False, rate_hz=None, progress=False)


def _edit_meta(folder: Path, key: str, value=None, **changes) -> None:
    meta = json.loads((folder / "meta.json").read_text())
    if value is not None:
        meta[key] = value
    else:
        meta[key].update(changes)
    (folder / "meta.json").write_text(json.dumps(meta))


def _nan_reading(folder: Path) -> None:
    values = torch.from_file(str(folder / "drive_pressure.memmap"), shared=True, size=12)
    values[3] = float("nan")
