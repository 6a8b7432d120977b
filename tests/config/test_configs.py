"""Every config under conf/ composes; wrong types and unknown keys fail at composition."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf
from omegaconf.errors import ConfigKeyError, ValidationError

from pilerl.config import register_configs
from pilerl.evaluation.settings import ScoopConfig

CONF = Path(__file__).resolve().parents[2] / "conf"
PRIMARY = sorted(p.stem for p in CONF.glob("*.yaml"))

register_configs()


def compose_config(name: str, overrides: list[str] | None = None):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose(config_name=name, overrides=overrides or [], return_hydra_config=True)


def typed_config(name: str, overrides: list[str]):
    """The recipe's typed config (without Hydra's node, whose keys are set at launch)."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        directory = (
            "out_dir=/x" if name in ("record", "build_dataset", "teleop") else "output_dir=/x"
        )
        cfg = compose(config_name=name, overrides=[directory, *overrides])
    return OmegaConf.to_object(cfg)


def _leaves(node, prefix=""):
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _leaves(value, f"{prefix}{key}.")
    else:
        yield prefix.rstrip("."), node


@pytest.mark.parametrize("name", PRIMARY)
def test_every_primary_config_composes(name):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name=name)  # without Hydra's node: its keys are set at launch
    unset = [
        key for key, value in _leaves(OmegaConf.to_container(cfg, resolve=False)) if value == "???"
    ]
    assert not unset, f"{name}: mandatory values left unset: {unset}"
    if "env" in cfg:
        assert cfg.env.simulator == "pile_loader"


@pytest.mark.parametrize("choice", ["d_i", "d_ii"])
def test_dataset_group_choices_compose(choice):
    cfg = compose_config("build_dataset", [f"dataset={choice}"])
    assert cfg.dataset.name == choice
    assert cfg.dataset.successful_only == (choice == "d_ii")


def test_scoop_config_becomes_the_typed_schema():
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="scoop", overrides=["output_dir=/tmp/unused"])
    config = OmegaConf.to_object(cfg)
    assert isinstance(config, ScoopConfig)
    assert config.env.make_kwargs()["start_distance_range_m"] == (1.0, 5.0)


@pytest.mark.parametrize(
    "override",
    ["env.control_hz=fast", "seed=zero"],
)
def test_wrong_types_fail_at_composition(override):
    with pytest.raises((ConfigCompositionException, ValidationError)):
        compose_config("scoop", [override])


def test_a_video_choice_other_than_auto_true_false_fails_when_the_config_is_built():
    """``video`` is auto | true | false (a str: Hydra hands ``video=true`` over as a bool)."""
    with pytest.raises(ValueError, match="video: must be one of"):
        typed_config("scoop", ["video=maybe"])
    for choice in ("auto", "true", "false"):
        assert str(typed_config("scoop", [f"video={choice}"]).video).lower() == choice


@pytest.mark.parametrize("override", ["env.colour=red", "operator.speed=1"])
def test_unknown_keys_fail_at_composition(override):
    with pytest.raises((ConfigCompositionException, ConfigKeyError)):
        compose_config("scoop", [override])


def test_impossible_operator_style_fails_when_the_config_is_built():
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(
            config_name="scoop",
            overrides=["output_dir=/tmp/unused", "+expert.trigger_sensor=wheel_speed"],
        )
    with pytest.raises(ValueError, match="trigger_sensor"):
        OmegaConf.to_object(cfg)


@pytest.mark.parametrize("policy", ["nnet", "nnetv2", "annet", "dannet", "rf"])
@pytest.mark.parametrize("sensors", ["s", "s_pt", "s_pt_sprime"])
def test_every_policy_and_sensor_set_composes(policy, sensors):
    cfg = compose_config("train_bc", [f"policy={policy}", f"sensors={sensors}"])
    assert cfg.policy.name == policy
    assert "boom_angle" in cfg.sensors.s
    assert (cfg.sensors.s_prime is None) == (sensors != "s_pt_sprime")


def test_experiment_overlay_sets_the_paper_experiment_and_its_sweep():
    cfg = compose_config("train_bc", ["+experiment=exp4_offline_validation"])
    assert cfg.ensemble_seeds == 100 and cfg.gradient_steps == 5000
    assert cfg.sensors.s[-1] == "telescope_pressure"
    assert cfg.hydra.sweeper.params.policy == "nnetv2,annet,dannet"
    assert "d_ii_summer" in cfg.hydra.sweeper.params.train_data


@pytest.mark.parametrize("experiment", sorted(p.stem for p in (CONF / "experiment").glob("*.yaml")))
def test_every_experiment_overlay_composes_with_its_sweep(experiment):
    cfg = compose_config("train_bc", [f"+experiment={experiment}"])
    assert cfg.hydra.sweep.dir == f"multirun/{experiment}"
    assert "policy" in cfg.hydra.sweeper.params
    if not experiment.startswith("exp4"):  # the closed-loop experiments test in winter
        assert cfg.evaluation.episodes > 0 and "winter_c" in cfg.evaluation.conditions


@pytest.mark.parametrize("group", ["condition", "soil", "logger"])
def test_every_condition_soil_and_logger_choice_composes(group):
    for choice in sorted(p.stem for p in (CONF / group).glob("*.yaml")):
        primary = "train_bc" if group == "logger" else "record"
        config = typed_config(primary, [f"{group}={choice}"])
        if group == "condition":
            assert config.env.condition == choice
        elif group == "soil":
            assert config.env.soil == choice.split("_")[0]
        else:
            assert config.logger.backend == choice


def test_condition_overrides_reach_the_simulator_and_bad_ones_fail():
    from pilerl.sim import make_gym_env

    config = typed_config(
        "record", ["condition=winter_c", "+env.condition_overrides.ground.tyre_friction=0.05"]
    )
    env = make_gym_env("pile_loader", **config.env.make_kwargs()).unwrapped
    assert env.condition.name == "winter_c" and env.condition.ground.tyre_friction == 0.05
    config = typed_config("record", ["+env.condition_overrides.ground.tyre_friction=-1"])
    with pytest.raises(ValueError, match="tyre_friction"):
        make_gym_env("pile_loader", **config.env.make_kwargs())


def test_an_unknown_logger_fails_when_the_config_is_built():
    with pytest.raises(ValueError, match="logger.backend"):
        typed_config("train_bc", ["logger.backend=comet"])
