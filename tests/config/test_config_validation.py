"""Bad Hydra overrides fail when the typed config is built, before any recipe work.

Table- and property-driven: for every primary config under conf/, many bad overrides
(negative numbers, zero, NaN, infinity, wrong types, unknown names, impossible
combinations) are composed with Hydra's compose API and turned into the recipe's typed
config (``OmegaConf.to_object``, as the recipes do). Each must raise an error whose
message names the field. No recipe runs, nothing is written.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from pilerl.config import register_configs

CONF = Path(__file__).resolve().parents[2] / "conf"
PRIMARY = sorted(p.stem for p in CONF.glob("*.yaml"))
OUT_DIR = {"record": "out_dir", "build_dataset": "out_dir", "teleop": "out_dir"}
# values a recipe's command line must give (never read here: no recipe runs)
REQUIRED = {"finetune": ["checkpoint=/tmp/never-read/best.pt"]}
# primary configs of other rooms whose settings are checked there (their own tests)
CHECKED_ELSEWHERE = {"deploy"}

register_configs()


def build_typed_config(name: str, overrides: list[str]):
    """What a recipe does first: compose, then build the typed config."""
    directory = f"{OUT_DIR.get(name, 'output_dir')}=/tmp/never-written"
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name=name, overrides=[directory, *REQUIRED.get(name, []), *overrides])
    return OmegaConf.to_object(cfg)


def error_text(error: BaseException) -> str:
    """The message with its causes (Hydra wraps OmegaConf's type errors)."""
    parts = []
    while error is not None:
        parts.append(str(error))
        error = error.__cause__ or error.__context__
    return " | ".join(parts)


# --- generated: each numeric field of a kind gets every bad value of that kind
POSITIVE_INT = ["0", "-1", "abc", "1.5", "nan"]
NON_NEGATIVE_INT = ["-1", "abc", "2.5"]
POSITIVE = ["0", "-1", "nan", "inf", "-inf", "fast"]
NON_NEGATIVE = ["-0.5", "nan", "inf", "x"]
FRACTION = ["-0.1", "1.5", "nan", "x"]
ENV_FIELDS = {
    "env.control_hz": POSITIVE,
    "env.physics_hz": POSITIVE,
    "env.sensor_noise": NON_NEGATIVE,
}
FIELDS = {
    "record": {
        "n_episodes": POSITIVE_INT,
        "record_hz": POSITIVE,
        "workers": POSITIVE_INT,
        "seed": NON_NEGATIVE_INT,
        **ENV_FIELDS,
    },
    "build_dataset": {"dataset.rate_hz": POSITIVE},
    "train_bc": {
        "epochs": POSITIVE_INT,
        "batch_size": POSITIVE_INT,
        "gradient_steps": POSITIVE_INT,
        "ensemble_seeds": POSITIVE_INT,
        "learning_rate": POSITIVE,
        "seed": NON_NEGATIVE_INT,
        "evaluation.episodes": NON_NEGATIVE_INT,
        "evaluation.workers": POSITIVE_INT,
        "evaluation.render_width": POSITIVE_INT,
        **ENV_FIELDS,
    },
    "evaluate": {
        "evaluation.episodes": NON_NEGATIVE_INT,
        "evaluation.workers": POSITIVE_INT,
        "evaluation.seed": NON_NEGATIVE_INT,
        "evaluation.render_height": POSITIVE_INT,
        **ENV_FIELDS,
    },
    "finetune": {
        "algorithm.frames_per_batch": POSITIVE_INT,
        "algorithm.epochs": POSITIVE_INT,
        "algorithm.minibatch_size": POSITIVE_INT,
        "algorithm.actor_lr": POSITIVE,
        "algorithm.critic_lr": POSITIVE,
        "algorithm.entropy_coeff": NON_NEGATIVE,
        "algorithm.regularizer_weight": NON_NEGATIVE,
        "algorithm.init_scale": POSITIVE,
        "collection.workers": POSITIVE_INT,
        "collection.envs_per_worker": POSITIVE_INT,
        "evaluation.episodes": POSITIVE_INT,
        "evaluation.final_episodes": POSITIVE_INT,
        "evaluation.every_frames": NON_NEGATIVE_INT,
        "checkpoint_every_frames": POSITIVE_INT,
        "time_budget_minutes": NON_NEGATIVE,
        "seed": NON_NEGATIVE_INT,
        **ENV_FIELDS,
    },
    "pipeline": {
        "demos.episodes": POSITIVE_INT,
        "demos.validation_episodes": POSITIVE_INT,
        "demos.record_hz": POSITIVE,
        "demos.mistake_rate": FRACTION,
        "demos.workers": POSITIVE_INT,
        "bc.gradient_steps": POSITIVE_INT,
        "bc.batch_size": POSITIVE_INT,
        "bc.learning_rate": POSITIVE,
        "evaluation.episodes": NON_NEGATIVE_INT,
        "finetune.algorithm.gamma": ["0", "1.5", "nan"],
        "finetune.time_budget_minutes": NON_NEGATIVE,
        **ENV_FIELDS,
    },
    "scoop": {
        "seed": NON_NEGATIVE_INT,
        "render_width": POSITIVE_INT,
        "render_height": POSITIVE_INT,
        **ENV_FIELDS,
    },
    "teleop": {"episodes": POSITIVE_INT, "seed": NON_NEGATIVE_INT, **ENV_FIELDS},
}

# --- written out: unknown names, empty lists, impossible combinations
# (config, overrides, text the error must contain)
COMBINATIONS = [
    ("record", ["+expert.trigger_sensor=boom_angle"], "trigger_sensor"),
    *[("record", [f"+expert.mistake_rate={value}"], "mistake_rate") for value in FRACTION],
    ("record", ["+expert.no_such_option=1"], "no_such_option"),
    ("record", ["env=toy_cart", "record_hz=5000"], "record_hz"),
    ("record", ["env=toy_cart", "+env.soil=particles"], "soil"),
    ("record", ["env.simulator=toy_cart"], "env=toy_cart"),
    ("record", ["env=toy_cart", "env.condition=summer"], "unknown condition 'summer'"),
    ("record", ["env.simulator=no_such_sim"], "env.simulator"),
    ("record", ["env.physics_hz=100", "record_hz=500"], "record_hz"),
    ("record", ["env.start_distance_range_m=[5.0,1.0]"], "env.start_distance_range_m"),
    ("record", ["env.start_distance_range_m=[-1.0,1.0]"], "env.start_distance_range_m"),
    ("record", ["env.start_distance_range_m=[1.0]"], "env.start_distance_range_m"),
    ("record", ["env.approach_angle_range_deg=[-400,10]"], "env.approach_angle_range_deg"),
    ("record", ["env.approach_angle_range_deg=[0,nan]"], "env.approach_angle_range_deg"),
    ("record", ["env.control_hz=1000", "env.physics_hz=500"], "env.physics_hz"),
    ("record", ["+env.condition_overrides={ground: {tyre_friction: nan}}"], "tyre_friction"),
    ("record", ["env.condition="], "env.condition"),
    ("record", ["out_dir="], "out_dir"),
    ("build_dataset", ["source=/data/x", "out_dir=/data/x"], "out_dir"),
    ("build_dataset", ["dataset.name="], "dataset.name"),
    ("build_dataset", ["dataset=no_such_rule"], "dataset"),
    ("train_bc", ["trainer=adamw"], "trainer"),
    ("train_bc", ["trainer=levenberg_marquardt"], "Levenberg-Marquardt"),  # DANNet: GBs
    ("train_bc", ["policy=nnetv2", "trainer=levenberg_marquardt"], "Levenberg-Marquardt"),
    ("train_bc", ["policy=nnet", "+policy.options.hidden=4000"], "Levenberg-Marquardt"),
    ("train_bc", ["trainer=fit"], "trainer"),
    ("train_bc", ["ensemble_seeds=3", "evaluation.episodes=2"], "evaluation.episodes"),
    ("train_bc", ["dropout_masks=fast"], "dropout_masks"),
    ("train_bc", ["dropout_masks=packed", "draw_ahead=true"], "draw_ahead"),
    ("train_bc", ["draw_ahead=sometimes"], "draw_ahead"),
    ("train_bc", ["draw_packed_ahead=sometimes"], "draw_packed_ahead"),
    ("train_bc", ["draw_packed_ahead=true"], "draw_packed_ahead"),  # needs packed masks
    ("train_bc", ["policy=no_such_policy"], "policy"),
    ("train_bc", ["policy.name=no_such_policy"], "policy.name"),
    ("train_bc", ["+policy.options.hidden=-4"], "policy.options"),
    ("train_bc", ["policy=nnetv2", "+policy.options.dropout=2.0"], "policy.options"),
    ("train_bc", ["policy=nnetv2", "+policy.options.hidden=[100000,100000]"], "parameters"),
    ("train_bc", ["policy=nnetv2", "+policy.options.no_such_option=1"], "policy.options"),
    ("train_bc", ["sensors.s=[]"], "sensors.s"),
    ("train_bc", ["sensors.s=[boom_angle,boom_angle]"], "sensors.s"),
    ("train_bc", ["train_data="], "train_data"),
    ("train_bc", ["logger=no_such_logger"], "logger"),
    ("train_bc", ["learning_rate=1e-3x"], "learning_rate"),
    ("evaluate", ["evaluation.conditions=[]"], "evaluation.conditions"),
    ("evaluate", ["evaluation.conditions=[summer,summer]"], "evaluation.conditions"),
    ("evaluate", ["evaluation.video_conditions=[winter_q]"], "evaluation.video_conditions"),
    ("evaluate", ["evaluation.render_width=100000"], "evaluation.render_width"),
    ("evaluate", ["checkpoint="], "checkpoint"),
    ("finetune", ["algorithm=no_such_algorithm"], "algorithm"),
    ("finetune", ["algorithm.gamma=0"], "algorithm.gamma"),
    ("finetune", ["algorithm.gamma=1.01"], "algorithm.gamma"),
    ("finetune", ["algorithm.lmbda=1.5"], "algorithm.lmbda"),
    ("finetune", ["algorithm.clip_epsilon=1.5"], "algorithm.clip_epsilon"),
    ("finetune", ["algorithm.critic_hidden=[]"], "algorithm.critic_hidden"),
    ("finetune", ["algorithm.critic_hidden=[64,0]"], "algorithm.critic_hidden"),
    ("finetune", ["algorithm.regularizer=magic"], "algorithm.regularizer"),
    ("finetune", ["algorithm.regularizer=bc_demo", "demos=null"], "bc_demo"),
    ("finetune", ["algorithm=td3bc", "algorithm.demo_fraction=1.5"], "demo_fraction"),
    ("finetune", ["algorithm=td3bc", "demos=null"], "demo_fraction"),
    ("finetune", ["algorithm=td3bc", "algorithm.tau=2"], "algorithm.tau"),
    ("finetune", ["algorithm=td3bc", "algorithm.buffer_size=10"], "algorithm.batch_size"),
    (
        "finetune",
        ["algorithm=td3bc", "demos=/tmp/never-read", "+reward_weights.reward_time=2.0"],
        "reward_weights",
    ),
    ("finetune", ["collection.backend=mpi"], "collection.backend"),
    (
        "finetune",
        ["collection.backend=ray", "collection.workers=3"],
        "collection.workers",
    ),
    ("finetune", ["evaluation.confidence=1.5"], "evaluation.confidence"),
    ("finetune", ["+evaluation.groups.winter=[]"], "evaluation.groups"),
    ("finetune", ["+evaluation.video_conditions={spring: summer}"], "video_conditions"),
    ("finetune", ["curriculum.stages=[]"], "curriculum.stages"),
    ("finetune", ["curriculum.stages=[{frames: 0, conditions: {summer: 1}}]"], "frames"),
    ("finetune", ["curriculum.stages=[{frames: 10, conditions: {summer: 0}}]"], "sum to 0"),
    ("finetune", ["+reward_weights.reward_time=inf"], "reward_weights.reward_time"),
    *[
        ("finetune", [f"+reward_weights.reward_fill={value}"], "reward_weights.reward_fill")
        for value in NON_NEGATIVE
    ],
    ("finetune", ["+reward_weights.reward_colour=1.0"], "reward_weights"),
    ("finetune", ["curriculum.stages=[{frames: 10, conditions: {spring: 1}}]"], "spring"),
    ("pipeline", ["policy=rf"], "policy"),
    ("pipeline", ["policy=nnet", "+policy.options.hidden=4000"], "Levenberg-Marquardt"),
    ("pipeline", ["demos.record_hz=1000"], "demos.record_hz"),
    ("pipeline", ["evaluation.video_conditions=[nowhere]"], "evaluation.video_conditions"),
    ("pipeline", ["finetune.collection.backend=threads"], "collection.backend"),
    ("pipeline", ["sensors=no_such_set"], "sensors"),
    ("pipeline", ["+demos.expert.crowdfill=true"], "demos.expert"),
    ("pipeline", ["+demos.expert.crowd_fill=perhaps"], "demos.expert"),
    ("pipeline", ["+demos.expert.mistake_rate=0.1"], "demos.expert.mistake_rate"),
    ("pipeline", ["+demos.expert.trigger_sensor=boom_angle"], "demos.expert.trigger_sensor"),
    ("scoop", ["conditions=[]"], "conditions"),
    ("scoop", ["camera="], "camera"),
    ("scoop", ["+expert.trigger_sensor=boom_angle"], "trigger_sensor"),
    ("teleop", ["operator_id="], "operator_id"),
]

GENERATED = [
    (config, [f"{key}={value}"], key)
    for config, fields in FIELDS.items()
    for key, values in fields.items()
    for value in values
]
CASES = GENERATED + COMBINATIONS


def case_id(case) -> str:
    return f"{case[0]}:{' '.join(case[1])}"


def test_every_primary_config_has_bad_overrides():
    assert {config for config, _, _ in CASES} == set(PRIMARY) - CHECKED_ELSEWHERE
    assert len(CASES) > 300


@pytest.mark.parametrize("name", sorted(set(PRIMARY) - CHECKED_ELSEWHERE))
def test_the_unchanged_configs_build(name):
    build_typed_config(name, [])


@pytest.mark.parametrize("config, overrides, field", CASES, ids=[case_id(c) for c in CASES])
def test_bad_override_fails_when_the_typed_config_is_built(config, overrides, field):
    with pytest.raises(
        (ValueError, TypeError, OmegaConfBaseException, ConfigCompositionException)
    ) as caught:
        build_typed_config(config, overrides)
    # the pipeline's finetune section is a FinetuneConfig, whose messages name its fields
    assert field.removeprefix("finetune.") in error_text(caught.value), error_text(caught.value)


def test_the_pipeline_takes_options_for_its_scripted_expert():
    overrides = ["+env.soil_options.intake=mouth", "+demos.expert.crowd_fill=true"]
    config = build_typed_config("pipeline", overrides)  # docs/finetuning.md's mouth world
    assert config.demos.expert == {"crowd_fill": True}
    assert config.env.soil_options == {"intake": "mouth"}
    assert config.demos.expert_options("winter_c") == {
        "crowd_fill": True,
        "trigger_sensor": "telescope_pressure",
        "mistake_rate": config.demos.mistake_rate,
    }
    assert config.demos.expert_options("summer")["trigger_sensor"] == "drive_pressure"
