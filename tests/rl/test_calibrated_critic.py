"""The calibrated critic of RLPD (pilerl.rl.calibration): demonstrations' Monte-Carlo
returns, a TD target never below them on demonstration samples, the option off unchanged."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from tensordict import TensorDict
from test_rl import CONF
from test_sample_efficient import cloned, online_batch, tiny_rlpd  # noqa: F401 (fixture)
from torchrl.objectives.value import TD0Estimator

from pilerl.policies import load_actor
from pilerl.rl import RLPDConfig
from pilerl.rl.calibration import (
    MC_RETURN,
    MC_RETURN_KNOWN,
    DemoReturnFloor,
    monte_carlo_returns,
)
from pilerl.rl.rlpd import RLPDLearner


def episodes(rewards: list[float], episode: list[int], terminated: list[bool]) -> TensorDict:
    n = len(rewards)
    flags = torch.tensor(terminated).reshape(n, 1)
    done = flags.clone()
    done[-1] = True  # the data's last row ends its episode (truncated where not terminated)
    return TensorDict(
        {
            "episode": torch.tensor(episode),
            "next": {
                "reward": torch.tensor(rewards).reshape(n, 1),
                "terminated": flags,
                "done": done,
            },
        },
        batch_size=[n],
    )


def test_monte_carlo_returns_discount_to_each_episodes_terminal_step():
    # episode 0: three steps, terminated; episode 1: two steps, cut off (truncated)
    ends = [False, False, True, False, False]
    demos = episodes([0.0, -0.5, 1.0, 2.0, 3.0], [0, 0, 0, 1, 1], ends)
    returns, known = monte_carlo_returns(demos, gamma=0.5)
    expected = torch.tensor([-0.5 * 0.5 + 0.25 * 1.0, -0.5 + 0.5 * 1.0, 1.0, 0.0, 0.0])
    torch.testing.assert_close(returns, expected, rtol=0, atol=1e-7)
    assert known.tolist() == [True, True, True, False, False]


def test_monte_carlo_returns_refuse_a_bad_discount_and_nan_rewards():
    demos = episodes([1.0, 1.0], [0, 0], [False, True])
    with pytest.raises(ValueError, match="gamma"):
        monte_carlo_returns(demos, gamma=0.0)
    demos["next", "reward"][0] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        monte_carlo_returns(demos, gamma=0.5)
    with pytest.raises(ValueError, match="NaN"):
        monte_carlo_returns(demos, gamma=0.9)


def targets(learner: RLPDLearner, data: TensorDict, estimator) -> torch.Tensor:
    """The TD target of ``learner``'s loss on ``data`` with ``estimator`` (same noise)."""
    learner.loss._value_estimator = estimator  # as calibrate() sets it
    torch.manual_seed(3)
    _, metadata = learner.loss.value_loss(data)
    return metadata["target_value"]


def test_calibrated_target_is_never_below_the_demonstrations_return(cloned):  # noqa: F811
    checkpoint, _, demos = cloned
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(calibrated_critic=True), demos=demos)
    floor = learner.loss.value_estimator
    assert isinstance(floor, DemoReturnFloor)
    learner.replay.extend(learner._as_stored(online_batch(learner, demos)))
    returns, known = monte_carlo_returns(demos, learner.settings.gamma)
    assert int(known.sum()) > 0
    stored = learner.replay.offline_buffer.storage[: demos.numel()]
    assert torch.equal(stored[MC_RETURN], returns) and torch.equal(stored[MC_RETURN_KNOWN], known)

    torch.manual_seed(0)
    data = learner.replay.sample()
    demo_rows = data[MC_RETURN_KNOWN]
    assert demo_rows.any() and not demo_rows.all()  # online rows carry no return
    calibrated = targets(learner, data, floor)
    plain = targets(learner, data, floor.estimator)
    mc = data[MC_RETURN]
    assert (calibrated[demo_rows] >= mc[demo_rows]).all()
    assert torch.equal(calibrated[demo_rows], torch.maximum(plain, mc)[demo_rows])
    assert torch.equal(calibrated[~demo_rows], plain[~demo_rows])
    assert (calibrated > plain).any()  # the untrained critic undervalues some demo steps


def test_calibrated_learner_updates_and_its_replay_survives_a_checkpoint(cloned):  # noqa: F811
    checkpoint, _, demos = cloned
    settings = tiny_rlpd(calibrated_critic=True)
    learner = RLPDLearner(load_actor(checkpoint), settings, demos=demos)
    metrics = learner.update(online_batch(learner, demos))
    assert 0 < metrics["calibration_raised_share"] <= settings.demo_fraction
    state = learner.state_dict()
    assert {MC_RETURN, MC_RETURN_KNOWN} <= set(state["replay"]["data"])
    assert not state["replay"]["data"][MC_RETURN_KNOWN].any()  # online: no returns
    restored = RLPDLearner(load_actor(checkpoint), settings, demos=demos)
    restored.load_state_dict(state, path=Path("last.ckpt"))
    size = state["replay"]["size"]
    original = learner.replay.online_buffer.storage[:size]
    resumed = restored.replay.online_buffer.storage[:size]
    for key in original.keys(True, True):
        assert torch.equal(resumed[key], original[key]), key


def test_option_off_keeps_plain_rlpd(cloned):  # noqa: F811
    checkpoint, _, demos = cloned
    assert RLPDConfig().calibrated_critic is False
    learners = []
    for settings in (tiny_rlpd(), tiny_rlpd(calibrated_critic=False)):
        torch.manual_seed(0)
        learners.append(RLPDLearner(load_actor(checkpoint), settings, demos=demos))
    plain, off = learners
    assert type(off.loss.value_estimator) is TD0Estimator  # TorchRL's, not wrapped
    assert off.stored_keys == off.keys  # the replay stores the loss's keys only
    for learner in learners:
        torch.manual_seed(1)
        learner.update(online_batch(learner, demos))
        learner.update(online_batch(learner, demos))
    for a, b in zip(plain.loss.state_dict().values(), off.loss.state_dict().values(), strict=True):
        assert torch.equal(a, b)


def test_calibrated_critic_setting_is_checked_and_composed():
    with pytest.raises(ValueError, match="algorithm.calibrated_critic: must be true or false"):
        RLPDConfig(calibrated_critic="yes")
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(
            config_name="finetune",
            overrides=["algorithm=rlpd_calibrated", "output_dir=/x", "checkpoint=/x/b.pt"]
            + ["demos=/x/d"],
        )
    config = OmegaConf.to_object(cfg)
    assert isinstance(config.algorithm, RLPDConfig)
    assert config.algorithm.calibrated_critic is True and config.algorithm.residual is False


def test_calibrated_critic_needs_episode_ids(cloned):  # noqa: F811
    checkpoint, _, demos = cloned
    without = demos.exclude("episode")
    with pytest.raises(KeyError, match="episode"):
        RLPDLearner(load_actor(checkpoint), tiny_rlpd(calibrated_critic=True), demos=without)
