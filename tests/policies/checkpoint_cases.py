"""Crafted and damaged checkpoints, and the verdict on how a loader answered each one.

Shared by ``tests/policies/test_checkpoint_safety.py`` (property-based tests) and
``benchmarks/checkpoint_robustness.py`` (the case-count table). A case starts from a valid
file and applies one attack:

| attack | what |
|---|---|
| ``flip`` | 1 to 8 random bit flips anywhere in the file |
| ``truncate`` | the file cut at a random length |
| ``append`` | random bytes appended |
| ``pickle`` | a pickled object that creates a marker file when unpickled, at a random place |
| ``huge`` | a declared size far beyond the tensors present (written with a valid digest) |
| ``poison`` | NaN or inf written into a random tensor (digest kept, or a digest-less v1) |

A verdict is ``refused`` (``CheckpointError`` naming the file, never advising
``weights_only=False``) or ``identical`` (loads and equals the original), both clean; any
other outcome is a defect: ``ran code``, ``loaded different``, ``<Type> raised``,
``message without the file``, ``message advises weights_only=False``.
"""

from __future__ import annotations

import io
import json
import random
from dataclasses import dataclass
from pathlib import Path

import torch

from pilerl.policies import CheckpointError, actor_policy, load_actor, make_actor, save_actor
from pilerl.policies.checkpoint_file import write_checkpoint
from pilerl.policies.random_forest import RandomForestController

S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
STATS = {
    "sensors": {name: {"mean": 0.0, "std": 1.0} for name in S},
    "action": {"mean": [0.0, 0.0, 0.0], "std": [1.0, 1.0, 1.0]},
}
ATTACKS = ("flip", "truncate", "append", "pickle", "huge", "poison")
CLEAN = ("refused", "identical")


class RunsCodeOnLoad:
    """Unpickling this creates ``marker``: proof that a loader ran pickled code."""

    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@dataclass(frozen=True)
class Attack:
    """One attack on a file, fully determined by its fields (``seed`` draws the rest)."""

    kind: str
    seed: int

    def apply(self, original: Path, target: Path, marker: Path, huge: list[dict]) -> None:
        """Write the attacked copy of ``original`` to ``target``."""
        rng = random.Random(self.seed)
        data = original.read_bytes()
        if self.kind == "flip":
            flipped = bytearray(data)
            for _ in range(rng.randint(1, 8)):
                position = rng.randrange(len(flipped) * 8)
                flipped[position // 8] ^= 1 << (position % 8)
            target.write_bytes(bytes(flipped))
        elif self.kind == "truncate":
            target.write_bytes(data[: rng.randrange(len(data))])
        elif self.kind == "append":
            target.write_bytes(data + rng.randbytes(rng.randint(1, 4096)))
        elif self.kind == "pickle":
            payload = _load_raw(data)
            _replace_random_leaf(payload, rng, lambda old: RunsCodeOnLoad(marker))
            torch.save(payload, target)
        elif self.kind == "huge":
            payload = _load_raw(data)
            payload.pop("sha256", None)
            edit = rng.choice(huge)
            _set_path(payload, edit["path"], edit["value"])
            write_checkpoint(target, payload, allow_infinite=lambda where: True)
        elif self.kind == "poison":
            payload = _load_raw(data)
            legacy = payload.get("format") == "pilerl.actor" and rng.random() < 0.5
            if legacy:
                # a digest-less version-1 file: the content check alone must refuse it
                # (NaN: a forest's thresholds may legitimately be infinite)
                payload.pop("sha256", None)
                payload["version"] = 1
            value = float("nan") if legacy else rng.choice([float("nan"), float("inf")])
            if not _poison_random_tensor(payload, rng, value):
                target.write_bytes(data)
                return
            torch.save(payload, target)
        else:
            raise ValueError(f"unknown attack {self.kind!r}")


def verdict(load, path: Path, marker: Path, same_as_original) -> str:
    """``refused`` / ``identical`` (clean) or the defect, for ``load(path)``."""
    try:
        loaded = load(path)
    except CheckpointError as error:
        message = str(error)
        if marker.exists():
            return "ran code"
        if "weights_only=False" in message or "weights_only = False" in message:
            return "message advises weights_only=False"
        if str(path) not in message:
            return "message without the file"
        return "refused"
    except Exception as error:  # noqa: BLE001 - any other type is the defect we count
        return "ran code" if marker.exists() else f"{type(error).__name__} raised"
    if marker.exists():
        return "ran code"
    return "identical" if same_as_original(loaded) else "loaded different"


# ---------------------------------------------------------------- base files


def small_actor_file(directory: Path) -> Path:
    """A saved NNet (the smallest neural actor)."""
    torch.manual_seed(0)
    return save_actor(directory / "nnet.pt", make_actor("nnet", sensors=S, stats=STATS))


def small_forest_file(directory: Path) -> Path:
    """A saved random forest of two hand-made trees (root split, two leaves; one leaf)."""
    actor = make_actor("rf", sensors=S, stats=STATS)
    forest = actor_policy(actor).controller
    assert isinstance(forest, RandomForestController)
    forest.children_left = torch.tensor([[1, 1, 2], [0, 1, 2]], dtype=torch.int32)
    forest.children_right = torch.tensor([[2, 1, 2], [0, 1, 2]], dtype=torch.int32)
    forest.feature = torch.tensor([[2, 0, 0], [0, 0, 0]], dtype=torch.int32)
    forest.threshold = torch.tensor([[0.5, float("inf"), float("inf")]] * 2, dtype=torch.float64)
    forest.value = torch.tensor(
        [[[0.0] * 3, [-0.5, 0.2, 0.1], [0.5, -0.2, 0.9]], [[0.1, 0.1, 0.1], [0.0] * 3, [0.0] * 3]]
    )
    forest.depth = torch.tensor(1)
    return save_actor(directory / "forest.pt", actor)


def actor_huge_edits(path: Path) -> list[dict]:
    """Edits of an actor's declared sizes (config) that no tensor in the file backs."""
    config = json.loads(_load_raw(path.read_bytes())["config"])
    edits = []
    for options in (
        {"hidden": 60_000},  # within the width bound: the meta-device check must refuse
        {"hidden": 10**9},
        {"hidden": [50_000, 50_000, 50_000]},
        {"hidden": [1] * 10**5},
    ):
        edits.append({"path": ["config"], "value": json.dumps({**config, "options": options})})
    edits.append({"path": ["config"], "value": json.dumps({**config, "n_controls": 10**7})})
    many = {**config, "sensors": [f"s{i}" for i in range(100_000)]}
    edits.append({"path": ["config"], "value": json.dumps(many)})
    if config["controller"] == "rf":
        edits += [
            {"path": ["state_dict", "controller.depth"], "value": torch.tensor(10**15)},
            {"path": ["state_dict", "controller.depth"], "value": torch.tensor(3)},
            {
                "path": ["state_dict", "controller.children_left"],  # a cycle: 1 -> 0
                "value": torch.tensor([[1, 0, 2], [0, 1, 2]], dtype=torch.int32),
            },
            {
                "path": ["state_dict", "controller.children_right"],
                "value": torch.tensor([[2**30, 1, 2], [0, 1, 2]], dtype=torch.int32),
            },
            {
                "path": ["state_dict", "controller.feature"],
                "value": torch.tensor([[99, 0, 0], [0, 0, 0]], dtype=torch.int32),
            },
        ]
    return edits


def same_actor(original: Path):
    """``loaded actor -> bool``: same config and bit-identical tensors as ``original``."""
    reference = actor_policy(load_actor(original))
    state = reference.state_dict()

    def same(actor) -> bool:
        policy = actor_policy(actor)
        other = policy.state_dict()
        return (
            policy.config == reference.config
            and other.keys() == state.keys()
            and all(torch.equal(other[k], state[k]) for k in state)
        )

    return same


def same_tree(a: object, b: object) -> bool:
    """Deep equality of plain values and tensors (dtype, shape and bits)."""
    if isinstance(a, torch.Tensor) or isinstance(b, torch.Tensor):
        return (
            isinstance(a, torch.Tensor)
            and isinstance(b, torch.Tensor)
            and a.dtype == b.dtype
            and a.shape == b.shape
            and torch.equal(a, b)
        )
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(same_tree(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return type(a) is type(b) and len(a) == len(b) and all(map(same_tree, a, b))
    return type(a) is type(b) and a == b


# ---------------------------------------------------------------- payload surgery


def _load_raw(data: bytes) -> dict:
    return torch.load(io.BytesIO(data), weights_only=True)


def _leaf_paths(tree: object, prefix: tuple = ()) -> list[tuple]:
    if isinstance(tree, dict):
        return [p for k, v in tree.items() for p in _leaf_paths(v, (*prefix, k))] or [prefix]
    if isinstance(tree, list):
        return [p for i, v in enumerate(tree) for p in _leaf_paths(v, (*prefix, i))] or [prefix]
    return [prefix]


def _set_path(tree: dict, path: list | tuple, value: object) -> None:
    for key in path[:-1]:
        tree = tree[key]
    tree[path[-1]] = value


def _get_path(tree: dict, path: tuple) -> object:
    for key in path:
        tree = tree[key]
    return tree


def _replace_random_leaf(payload: dict, rng: random.Random, make) -> None:
    paths = [p for p in _leaf_paths(payload) if p]
    path = rng.choice(paths)
    _set_path(payload, path, make(_get_path(payload, path)))


def _poison_random_tensor(payload: dict, rng: random.Random, value: float) -> bool:
    paths = [
        p
        for p in _leaf_paths(payload)
        if p
        and isinstance(_get_path(payload, p), torch.Tensor)
        and _get_path(payload, p).is_floating_point()
        and _get_path(payload, p).numel() > 0
    ]
    if not paths:
        return False
    path = rng.choice(paths)
    tensor = _get_path(payload, path).clone()
    tensor.view(-1)[rng.randrange(tensor.numel())] = value
    _set_path(payload, path, tensor)
    return True


# ---------------------------------------------------------------- fine-tuning runs


def tiny_td3bc_config(checkpoint: Path, run_dir: Path):
    from pilerl.rl import (
        CollectionConfig,
        CurriculumConfig,
        CurriculumStage,
        EvaluationConfig,
        FinetuneConfig,
        TD3BCConfig,
    )

    return FinetuneConfig(
        checkpoint=str(checkpoint),
        demos=None,
        algorithm=TD3BCConfig(
            frames_per_batch=64, updates_per_batch=2, batch_size=16, demo_fraction=0.0
        ),
        curriculum=CurriculumConfig(stages=[CurriculumStage(frames=64, conditions={"summer": 1})]),
        reward_weights={"reward_fill": 1.0},
        collection=CollectionConfig(envs_per_worker=1),
        evaluation=EvaluationConfig(groups={"summer": ["summer"]}, every_frames=0),
        output_dir=str(run_dir),
    )


def small_run_file(checkpoint: Path, run_dir: Path) -> Path:
    """A TD3+BC ``last.ckpt`` with 40 transitions in its replay buffer (no simulation)."""
    from tensordict import TensorDict

    from pilerl.rl.finetuning import RUN_CHECKPOINT, _Run
    from pilerl.rl.td3bc import REPLAY_INDEX_KEY

    with torch.random.fork_rng(devices=[]):
        run = _Run(tiny_td3bc_config(checkpoint, run_dir), run_dir, progress=False)
        learner = run.learner
        columns = {}
        for name, leaf in learner._replay_layout().items():
            if name == REPLAY_INDEX_KEY:  # written by the buffer itself
                continue
            shape = (40, *leaf.per_transition)
            is_flag = leaf.dtype == torch.bool
            columns[leaf.key] = (torch.rand(shape) > 0.5) if is_flag else torch.rand(shape)
        learner.update(TensorDict(columns, batch_size=[40]))  # fills replay and optimisers
        run.state["frames"], run.state["batches"] = 40, 1
        run.save()
    return run_dir / RUN_CHECKPOINT


def resumed_state(checkpoint: Path):
    """``run_dir -> (progress, learner state, torch RNG)`` after ``_Run.resume()``."""
    from pilerl.rl.finetuning import _Run

    def load(path: Path):
        run_dir = path.parent
        with torch.random.fork_rng(devices=[]):
            run = _Run(tiny_td3bc_config(checkpoint, run_dir), run_dir, progress=False)
            if not run.resume():
                raise AssertionError("no last.ckpt resumed")
            return run.state, run.learner.state_dict(), torch.get_rng_state()

    return load


def run_huge_edits(path: Path) -> list[dict]:
    """Declared sizes of a run checkpoint that no tensor backs, or that do not fit."""
    first_moment = next(iter(_load_raw(path.read_bytes())["learner"]["actor_optimizer"]["state"]))
    return [
        {"path": ["learner", "replay", "size"], "value": 10**12},
        {"path": ["learner", "replay", "size"], "value": 41},
        {"path": ["learner", "replay", "writer", "_cursor"], "value": 10**9},
        {"path": ["learner", "updates"], "value": -1},
        {"path": ["learner", "replay", "data", "action"], "value": torch.zeros(40, 10**4)},
        {
            "path": ["learner", "actor_optimizer", "state", first_moment, "exp_avg"],
            "value": torch.zeros(3, 3),
        },
        {"path": ["rng", "torch"], "value": torch.zeros(10**6, dtype=torch.uint8)},
        {"path": ["progress"], "value": json.dumps({"frames": 10**30})},
    ]
