"""The one rollout: batched seeds, operators as TensorDict modules, recorded rollouts as
schema episodes, actors sent to evaluation workers as weights."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from pilerl_pile_loader.operator import PHASES
from pilerl_pile_loader.operator import make_expert as make_scripted_expert
from tensordict import TensorDict
from tensordict.nn import TensorDictModuleBase

from pilerl.data import EpisodeStore, RecordingPlan, record_demonstrations
from pilerl.data.recorder import (
    EXECUTED_KEY,
    episode_from_rollout,
    record_episode,
    recorded_info,
)
from pilerl.data.schema import validate_episode
from pilerl.evaluation.evaluator import (
    ActorController,
    ActorWeights,
    EvaluationPlan,
    evaluate,
)
from pilerl.operators import OperatorModule
from pilerl.policies import make_actor, save_actor
from pilerl.sim.rollout import (
    RowByRow,
    control_period_s,
    make_rollout_env,
    rollout,
    sensor_names,
)

ENV = {"condition": "summer", "control_hz": 20.0}
S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
STATS = {
    "sensors": {name: {"mean": 0.0, "std": 1.0} for name in S},
    "action": {"mean": [0.0, 0.0, 0.0], "std": [1.0, 1.0, 1.0]},
}


def scripted(env, n: int, first: int = 0) -> OperatorModule:
    """``n`` operators, each with the style drawn for its episode index."""
    dt = control_period_s(env)
    rngs = [np.random.default_rng([1, first + i]) for i in range(n)]
    return OperatorModule.for_env([make_scripted_expert(dt=dt, rng=rng) for rng in rngs], env)


def test_a_batched_rollout_is_the_single_rollouts_of_consecutive_seeds():
    batched_env = make_rollout_env(
        "pile_loader", ENV, num_envs=3, info_keys=recorded_info("pile_loader")
    )
    batch = rollout(batched_env, scripted(batched_env, 3), seed=40)
    assert batch.seeds == [40, 41, 42]
    assert len(set(batch.lengths)) > 1  # episodes of different lengths share the batch
    single_env = make_rollout_env(
        "pile_loader", ENV, num_envs=1, info_keys=recorded_info("pile_loader")
    )
    for i in range(3):
        alone = rollout(single_env, scripted(single_env, 1, first=i), seed=40 + i)
        mine, theirs = batch.episode(i), alone.episode(0)
        assert batch.lengths[i] == alone.lengths[0]
        for key in mine.keys(include_nested=True, leaves_only=True):
            assert torch.equal(mine.get(key), theirs.get(key)), key
    # each episode starts from its own seeded pose; ended rows repeat the episode's last row
    starts = [batch.info(i, "start_distance_m")[0] for i in range(3)]
    assert len(set(starts)) == 3
    shortest = int(np.argmin(batch.lengths))
    tail = batch.data[shortest, batch.lengths[shortest] - 1 :]
    assert (tail.get(("next", "done")) == True).all()  # noqa: E712
    assert torch.equal(tail.get("action")[-1], tail.get("action")[0])


def test_a_recorded_rollout_is_the_schema_episode_the_recorder_stores(tmp_path):
    env = make_rollout_env("pile_loader", ENV, num_envs=2, info_keys=recorded_info("pile_loader"))
    run = rollout(env, scripted(env, 2), seed=100_000)  # RecordingPlan(seed=1): 100_000 + i
    sim = env.simulators[0].unwrapped
    store = EpisodeStore.create(tmp_path, sensors=sim.sensor_units, controls=sim.control_names)
    plan = RecordingPlan("pile_loader", ENV, n_episodes=2, seed=1)
    record_demonstrations(store, plan, workers=1, progress=False)
    for i in range(2):
        rows = run.episode(i)
        episode = episode_from_rollout(rows, sensors=sensor_names(env), dt=0.05)
        validate_episode(episode, sensor_names(env), action_dim=3)
        assert EXECUTED_KEY not in episode  # the scripted operator is its own label
        # the rollout's rows are the episode: readings before and after each action
        assert torch.equal(episode["boom_angle"][1:], episode["next", "boom_angle"][:-1])
        assert torch.equal(episode["action"], rows.get("action"))
        assert episode["next", "done"].sum() == 1 and bool(episode["next", "done"][-1])
        assert episode["time_s"][1] == pytest.approx(0.05)
        stored = store.load(i).to_tensordict()
        assert set(stored.keys(True, True)) == set(episode.keys(True, True))
        for key in episode.keys(include_nested=True, leaves_only=True):
            if key != "episode":  # the store numbers its episodes
                assert torch.equal(stored[key], episode[key]), key
        assert store.episodes[i].seed == run.seeds[i]


def test_the_operator_module_labels_phases_and_records_labels_apart_from_commands():
    env = make_rollout_env("pile_loader", ENV, info_keys=recorded_info("pile_loader"))
    nominal = make_scripted_expert(dt=control_period_s(env))
    rows = rollout(env, OperatorModule.for_env([nominal], env), seed=3).episode(0)
    phases = rows.get("phase").tolist()
    assert phases[0] == PHASES.index("approach") and len(set(phases)) > 1
    assert phases == sorted(phases)  # approach -> fill -> finish, never back
    replay = make_scripted_expert(dt=control_period_s(env))  # the same operator, by hand
    for t, phase in enumerate(phases):
        command = replay.act({name: rows.get(name)[t].numpy() for name in sensor_names(env)})
        assert np.array_equal(command, rows.get("action")[t].numpy())
        assert phase == PHASES.index(replay.phase)

    class Nudged:
        """Executes its scripted twin's command plus a fixed nudge; labels the clean one."""

        PHASES = PHASES

        def __init__(self) -> None:
            self.inner = make_scripted_expert(dt=control_period_s(env))

        @property
        def phase(self) -> str:
            return self.inner.phase

        def reset(self) -> None:
            self.inner.reset()

        def act(self, sensors):
            self.last_label = self.inner.act(sensors)
            return np.clip(self.last_label + np.float32(0.1), -1.0, 1.0).astype(np.float32)

    episode, start, final = record_episode(env, Nudged(), seed=3)
    assert EXECUTED_KEY in episode
    assert not torch.equal(episode["action"], episode[EXECUTED_KEY])
    assert torch.equal(episode[EXECUTED_KEY], (episode["action"] + 0.1).clamp(-1.0, 1.0))
    assert set(start) == {"start_distance_m", "approach_angle_rad", "fill_fraction", "success"}
    assert 0.0 <= final["fill_fraction"] <= 1.5


def test_an_operator_module_refuses_a_batch_of_another_size():
    env = make_rollout_env("pile_loader", ENV)
    module = scripted(env, 2)
    with pytest.raises(ValueError, match="holds 2 operators"):
        module(TensorDict({name: torch.zeros(3, 1) for name in module.in_keys}, [3]))


def test_row_by_row_acts_like_the_unbatched_actor():
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=S, stats=STATS).eval()
    batch = TensorDict({name: torch.randn(5, 1) * 3 for name in S}, [5])
    with torch.no_grad():
        rows = RowByRow(actor)(batch.clone())["action"]
        alone = torch.stack([actor(batch[i].clone())["action"] for i in range(5)])
    assert torch.equal(rows, alone)


def test_actor_weights_sent_to_workers_give_the_in_process_result(tmp_path):
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=S, stats=STATS)
    output = actor.module.controller.output
    with torch.no_grad():  # mostly full throttle, a little of the sensors: into the pile
        output.weight.mul_(0.01)
        output.bias.copy_(torch.tensor([0.0, 0.0, 2.0]))
    plan = EvaluationPlan("pile_loader", {"control_hz": 20.0}, ("summer",), episodes=2, seed=1)
    in_process = evaluate(actor, plan, workers=1, progress=False)
    weights = ActorWeights.of(actor)
    with torch.no_grad():
        output.bias.zero_()  # later changes to the actor do not reach the copy
    sent = evaluate(weights, plan, workers=2, progress=False)
    saved = save_actor(tmp_path / "actor.pt", ActorWeights.build(weights))
    from_disk = evaluate(ActorController(str(saved)), plan, workers=1, progress=False)
    assert same_records(in_process, sent) and same_records(in_process, from_disk)
    assert in_process[0]["fill_fraction"] > 0.0


def same_records(a: list[dict], b: list[dict]) -> bool:
    def equal(x, y):
        return x == y or (isinstance(x, float) and np.isnan(x) and np.isnan(y))

    return len(a) == len(b) and all(
        ra.keys() == rb.keys() and all(equal(ra[k], rb[k]) for k in ra)
        for ra, rb in zip(a, b, strict=True)
    )


def test_a_rollout_runs_any_simulator_that_ends_its_episodes():
    """The toy cart: no ``info`` the pile loader reports (NaN), episodes end by time."""

    class Push(TensorDictModuleBase):
        in_keys, out_keys = ["position"], ["action"]

        def forward(self, tensordict):
            return tensordict.set("action", torch.full((*tensordict.batch_size, 1), 0.5))

    env = make_rollout_env("toy_cart", {}, num_envs=2, info_keys=("fill_fraction",))
    run = rollout(env, Push(), seed=0)
    assert run.lengths == [100, 100]  # pushed past the target: truncated at 100 steps
    assert bool(run.episode(0).get(("next", "truncated"))[-1])
    assert np.isnan(run.info(0, "fill_fraction")).all()
    with pytest.raises(KeyError, match="'success' was not carried"):
        run.info(0, "success")


def test_fine_tuning_evaluates_the_actor_in_memory_as_it_is_now():
    from pilerl.rl.evaluation import evaluate_groups

    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=S, stats=STATS)
    output = actor.module.controller.output
    kwargs = {"simulator": "pile_loader", "env_kwargs": {}, "episodes": 1, "seed": 0}
    with torch.no_grad():
        output.weight.zero_()
        output.bias.zero_()  # stands still: nothing scooped
    still, *_ = evaluate_groups(actor, {"summer": ["summer"]}, **kwargs)
    with torch.no_grad():
        output.bias.copy_(torch.tensor([0.0, 0.0, 2.0]))  # full throttle into the pile
    driving, *_ = evaluate_groups(actor, {"summer": ["summer"]}, **kwargs)
    assert still["summer"]["fill_mean"] == 0.0
    assert driving["summer"]["fill_mean"] > 0.0


def test_simulators_of_one_rollout_may_differ_in_arguments_and_seeds():
    """What the evaluator batches: one episode in each of several conditions."""

    class Push(TensorDictModuleBase):
        in_keys, out_keys = ["position"], ["action"]

        def forward(self, tensordict):
            return tensordict.set("action", torch.full((*tensordict.batch_size, 1), 0.3))

    conditions = [{"condition": "heavy"}, {"condition": "nominal"}, {"condition": "heavy"}]
    mixed = make_rollout_env("toy_cart", {}, each=conditions, info_keys=("success",))
    run = rollout(mixed, Push(), seed=[7, 3, 9])
    assert run.seeds == [7, 3, 9]
    assert [sim.unwrapped.condition for sim in mixed.simulators] == ["heavy", "nominal", "heavy"]
    for i, (options, seed) in enumerate(zip(conditions, run.seeds, strict=True)):
        single = make_rollout_env("toy_cart", options, info_keys=("success",))
        alone = rollout(single, Push(), seed=seed)
        mine, theirs = run.episode(i), alone.episode(0)
        assert run.lengths[i] == alone.lengths[0]
        for key in mine.keys(include_nested=True, leaves_only=True):
            assert torch.equal(mine.get(key), theirs.get(key)), key
    assert not torch.equal(run.episode(0).get("position"), run.episode(2).get("position"))


class PushCart(TensorDictModuleBase):
    in_keys, out_keys = ["position"], ["action"]

    def forward(self, tensordict):
        return tensordict.set("action", torch.full((*tensordict.batch_size, 1), 0.3))


def test_an_episode_ending_on_the_last_step_of_a_cut_rollout_keeps_its_end_flags():
    """``max_steps`` equal to the shortest episode: that episode ends on the rollout's last
    row while the others still run; its end flags must still be written there."""
    env = make_rollout_env("pile_loader", ENV, num_envs=3)
    full = rollout(env, scripted(env, 3), seed=40)
    shortest = int(np.argmin(full.lengths))
    assert full.lengths[shortest] < max(full.lengths)
    cut = rollout(env, scripted(env, 3), seed=40, max_steps=full.lengths[shortest])
    for i in range(3):
        done = bool(cut.episode(i).get(("next", "done"))[-1])
        assert done == (i == shortest), i
    assert torch.equal(
        cut.episode(shortest).get(("next", "terminated")),
        full.episode(shortest).get(("next", "terminated")),
    )


def test_per_simulator_arguments_replace_the_shared_ones():
    both = make_rollout_env("toy_cart", {"condition": "heavy"}, each=[{"condition": "nominal"}])
    assert [sim.unwrapped.condition for sim in both.simulators] == ["nominal"]
    with pytest.raises(ValueError, match="num_envs=3 but 2 per-simulator"):
        make_rollout_env("toy_cart", {}, num_envs=3, each=[{}, {}])


def test_sub_env_seeds_are_checked_and_a_reset_starts_every_episode_running():
    """What the rollout reads between steps: one seed per sub-env, and after a reset every
    sub-env running with no end flags (the held-back ends are covered by the cut rollout
    above and the batched-rollout test)."""
    env = make_rollout_env("toy_cart", {}, each=[{"condition": "heavy"}, {}])
    with pytest.raises(ValueError, match="3 seeds for 2 sub-envs"):
        env.seed_episodes([1, 2, 3])
    env.seed_episodes([7, 3])
    env.reset()
    assert env.running.tolist() == [True, True]
    assert not env.end_flags[0].any() and not env.end_flags[1].any()


def test_a_filmed_rollout_has_a_frame_at_reset_and_every_stride_steps():
    env = make_rollout_env(
        "pile_loader",
        {**ENV, "render_mode": "rgb_array", "render_size": (32, 48)},
        num_envs=2,
        info_keys=recorded_info("pile_loader"),
    )
    run = rollout(env, scripted(env, 2), seed=7, frame_stride=10)
    for i in range(2):  # frame k shows the state after 10 k steps, up to the episode's end
        assert len(run.frames[i]) == 1 + run.lengths[i] // 10
        assert run.frames[i][0].shape == (32, 48, 3)
