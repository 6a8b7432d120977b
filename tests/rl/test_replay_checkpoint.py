"""The online replay buffer's checkpoint entry, shared by TD3+BC and RLPD
(``pilerl.rl.off_policy.replay_state`` / ``restore_replay``): an exact round trip, and a
damaged entry refused naming the leaf, with nothing written into the buffer."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from tensordict import TensorDict
from test_sample_efficient import cloned, online_batch, tiny_rlpd  # noqa: F401 (fixture)
from torchrl.data import LazyTensorStorage, ReplayBuffer, TensorDictReplayBuffer

from pilerl.policies import load_actor
from pilerl.policies.checkpoint_file import CheckpointError
from pilerl.rl.off_policy import layout_of, replay_state, restore_replay
from pilerl.rl.rlpd import RLPDLearner

CAPACITY = 8
PATH = Path("runs/x/last.ckpt")


def transitions(n: int, offset: float = 0.0) -> TensorDict:
    return TensorDict(
        {
            "boom_angle": torch.arange(n, dtype=torch.float32).reshape(n, 1) + offset,
            "action": torch.full((n, 3), offset),
            "next": {
                "reward": torch.linspace(-1, 1, n).reshape(n, 1),
                "done": torch.arange(n).reshape(n, 1) % 2 == 0,
            },
        },
        batch_size=[n],
    )


def filled_buffer() -> ReplayBuffer:
    buffer = ReplayBuffer(storage=LazyTensorStorage(CAPACITY), batch_size=4)
    buffer.extend(transitions(6))
    buffer.extend(transitions(5, offset=10.0))  # wraps around: the cursor is not the size
    return buffer


def test_a_replay_buffer_round_trips_with_its_writer_position():
    buffer = filled_buffer()
    state = replay_state(buffer)
    assert state["size"] == CAPACITY and state["writer"]["_cursor"] == 3
    restored = ReplayBuffer(storage=LazyTensorStorage(CAPACITY), batch_size=4)
    restore_replay(restored, state, path=PATH, capacity=CAPACITY, layout=layout_of(transitions(1)))
    original, resumed = buffer.storage[:CAPACITY], restored.storage[:CAPACITY]
    for key in original.keys(True, True):
        assert torch.equal(resumed[key], original[key]), key
    assert dict(restored._writer.state_dict()) == dict(buffer._writer.state_dict())
    restored.extend(transitions(1, offset=99.0))  # the next write lands where it would have
    assert restored.storage[3]["boom_angle"].item() == 99.0


def test_a_tensordict_buffer_s_own_index_is_checked_not_passed_back():
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(CAPACITY), batch_size=2)
    buffer.extend(transitions(3))
    state = replay_state(buffer)
    assert "index" in state["data"]
    layout = layout_of(buffer.storage[:3])
    restored = TensorDictReplayBuffer(storage=LazyTensorStorage(CAPACITY), batch_size=2)
    restore_replay(
        restored, state, path=PATH, capacity=CAPACITY, layout=layout, written_by_buffer=("index",)
    )
    assert torch.equal(restored.storage[:3]["next", "reward"], buffer.storage[:3]["next", "reward"])


def damage(state: dict, how: str) -> None:
    data = state["data"]
    if how == "dtype":
        data["next/reward"] = data["next/reward"].double()
    elif how == "shape":
        data["action"] = data["action"][:, :2]
    elif how == "rows":
        data["boom_angle"] = data["boom_angle"][:-1]
    elif how == "missing":
        del data["next/done"]
    elif how == "not a tensor":
        data["boom_angle"] = data["boom_angle"].tolist()
    elif how == "size":
        state["size"] = CAPACITY + 1
    elif how == "cursor":
        state["writer"]["_cursor"] = CAPACITY
    elif how == "write count":
        state["writer"]["_write_count"] = -1
    elif how == "writer elsewhere":
        state["writer"]["_cursor"] = 5  # 11 writes into 8 slots leave the cursor at 3


@pytest.mark.parametrize(
    ("how", "message"),
    [
        (
            "dtype",
            r"learner\.replay/next/reward is torch\.float64\(8, 1\), expected torch\.float32",
        ),
        (
            "shape",
            r"learner\.replay/action is torch\.float32\(8, 2\), expected torch\.float32\(8, 3\)",
        ),
        ("rows", r"learner\.replay/boom_angle is torch\.float32\(7, 1\)"),
        ("missing", r"learner\.replay holds .*expected .*next/done"),
        ("not a tensor", r"learner\.replay/boom_angle is not a tensor"),
        ("size", r"learner\.replay holds 9 transitions \(buffer size 8\)"),
        ("cursor", r"no valid writer position"),
        ("write count", r"no valid writer position"),
        ("writer elsewhere", r"writer \(cursor 5, 11 writes\) does not fit its 8 transitions"),
    ],
)
def test_a_damaged_replay_entry_is_refused_naming_the_leaf_and_nothing_is_written(how, message):
    state = replay_state(filled_buffer())
    damage(state, how)
    restored = ReplayBuffer(storage=LazyTensorStorage(CAPACITY), batch_size=4)
    with pytest.raises(CheckpointError, match=message) as refused:
        restore_replay(
            restored, state, path=PATH, capacity=CAPACITY, layout=layout_of(transitions(1))
        )
    assert str(PATH) in str(refused.value)
    assert len(restored) == 0


def test_rlpd_refuses_a_replay_leaf_of_the_wrong_dtype(cloned):  # noqa: F811
    """RLPD's restore checks dtypes and trailing shapes too (it once checked only rows)."""
    checkpoint, _, demos = cloned
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(), demos=demos)
    learner.update(online_batch(learner, demos))
    state = learner.state_dict()
    state["replay"]["data"]["next/reward"] = state["replay"]["data"]["next/reward"].double()
    fresh = RLPDLearner(load_actor(checkpoint), tiny_rlpd(), demos=demos)
    with pytest.raises(CheckpointError, match=r"learner\.replay/next/reward is torch\.float64"):
        fresh.load_state_dict(state, path=PATH)
    assert len(fresh.replay.online_buffer) == 0


def test_a_replay_state_is_restored_only_into_an_empty_buffer():
    state = replay_state(filled_buffer())
    with pytest.raises(ValueError, match="already holds 8 transitions"):
        restore_replay(
            filled_buffer(), state, path=PATH, capacity=CAPACITY, layout=layout_of(transitions(1))
        )
