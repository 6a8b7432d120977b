"""Controllers, actors, Levenberg-Marquardt and checkpoints (pilerl.policies)."""

from __future__ import annotations

import copy
import json
import pathlib

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from pilerl.data.curation import compute_stats
from pilerl.data.schema import make_episode
from pilerl.data.store import EpisodeStore
from pilerl.policies import (
    ACTION_LOC_KEY,
    BC_ACTION_KEY,
    CONTROLLERS,
    INPUT_MASK_KEY,
    NEURAL_CONTROLLERS,
    OUTPUT_MASK_KEY,
    ActorConfig,
    CheckpointError,
    InputNormalizer,
    NNet,
    RandomForestActor,
    UnknownControllerError,
    fit_lm,
    load_actor,
    make_actor,
    make_controller,
    make_stochastic_actor,
    save_actor,
)
from pilerl.policies.actors import inference_actor
from pilerl.policies.checkpoint import CHECKPOINT_FORMAT, CHECKPOINT_VERSION
from pilerl.policies.checkpoint_file import write_checkpoint

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
EXTRA_ATTENTION = ["boom_pressure", "bucket_pressure", "pump_angle"]
ALL_SENSORS = SENSORS + EXTRA_ATTENTION
UNITS = {name: "rad" if "angle" in name else "Pa" for name in ALL_SENSORS}
N_CONTROLS = 3
BATCH = 16

# (controller, attention sensors): every neural controller, attention ones also with s' != s
NEURAL_CASES = [
    *[(name, None) for name in NEURAL_CONTROLLERS],
    ("annet", SENSORS + EXTRA_ATTENTION),
    ("dannet", SENSORS + EXTRA_ATTENTION),
]
CASE_IDS = [f"{name}-{'s_prime' if att else 's'}" for name, att in NEURAL_CASES]

# torch's own forward-mode decompositions (first jacfwd in fit_lm) still use torch.jit.script
pytestmark = pytest.mark.filterwarnings(
    "ignore:`torch.jit.script` is deprecated:DeprecationWarning"
)


@pytest.fixture(autouse=True)
def _seed() -> None:
    torch.manual_seed(0)


def make_stats() -> dict:
    """Statistics shaped like ``compute_stats`` output, far from zero-mean / unit-std."""
    return {
        "n_samples": 100,
        "sensors": {
            name: {"mean": 10.0 * (i + 1), "std": 0.5 * (i + 1), "min": 0.0, "max": 100.0}
            for i, name in enumerate(ALL_SENSORS)
        },
        "action": {
            "mean": [0.0] * N_CONTROLS,
            "std": [0.5] * N_CONTROLS,
            "min": [-1.0] * N_CONTROLS,
            "max": [1.0] * N_CONTROLS,
        },
    }


def make_observations(batch_size: tuple[int, ...] = (BATCH,)) -> TensorDict:
    """Sensor readings around the stats' means (physical units), one [.., 1] key each."""
    stats = make_stats()["sensors"]
    return TensorDict(
        {
            name: stats[name]["mean"] + stats[name]["std"] * torch.randn(*batch_size, 1)
            for name in ALL_SENSORS
        },
        batch_size=batch_size,
    )


def make_neural_actor(name: str, attention_sensors: list[str] | None):
    return make_actor(
        name, sensors=SENSORS, attention_sensors=attention_sensors, stats=make_stats()
    )


# ---------------------------------------------------------------------- registry / config


def test_registry_names_and_unknown_name_lists_known_ones() -> None:
    assert set(CONTROLLERS) == {"nnet", "nnetv2", "annet", "dannet", "rf"}
    assert set(NEURAL_CONTROLLERS) == {"nnet", "nnetv2", "annet", "dannet"}
    assert CONTROLLERS["nnet"].trainer == "levenberg_marquardt"
    with pytest.raises(UnknownControllerError) as error:
        make_controller("transformer", sensors=SENSORS, stats=make_stats())
    for known in CONTROLLERS:
        assert repr(known) in str(error.value)
    with pytest.raises(UnknownControllerError, match="known controllers"):
        make_actor("nnet3", sensors=SENSORS, stats=make_stats())


def test_config_checks_sensors_and_round_trips_through_json() -> None:
    with pytest.raises(ValueError, match="no statistics for sensors"):
        make_controller("nnet", sensors=[*SENSORS, "wheel_speed"], stats=make_stats())
    with pytest.raises(ValueError, match="more than once"):
        make_controller("nnet", sensors=["boom_angle", "boom_angle"], stats=make_stats())
    with pytest.raises(ValueError, match="no attention network"):
        make_controller("nnetv2", sensors=SENSORS, attention_sensors=SENSORS, stats=make_stats())
    config = make_controller(
        "dannet", sensors=SENSORS, attention_sensors=ALL_SENSORS, stats=make_stats()
    ).config
    assert config.input_keys == ALL_SENSORS
    assert config.n_controls == N_CONTROLS
    assert ActorConfig.from_json(json.loads(json.dumps(config.to_json()))) == config
    narrow = make_controller("nnet", sensors=SENSORS[:3], stats=make_stats()).config
    assert set(narrow.stats["sensors"]) == set(SENSORS[:3])  # only what is used is kept


def test_normalizer_matches_stats() -> None:
    stats = make_stats()
    normalizer = InputNormalizer.from_stats(SENSORS, stats)
    x = torch.randn(5, len(SENSORS))
    mean = torch.tensor([stats["sensors"][n]["mean"] for n in SENSORS])
    std = torch.tensor([stats["sensors"][n]["std"] for n in SENSORS])
    torch.testing.assert_close(normalizer(x), (x - mean) / std)
    torch.testing.assert_close(normalizer.inverse(normalizer(x)), x)
    assert set(normalizer.state_dict()) == {"mean", "std"}
    with pytest.raises(KeyError, match="no stats"):
        InputNormalizer.from_stats(["wheel_speed"], stats)


# ---------------------------------------------------------------------- neural actors


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
@pytest.mark.parametrize("batch_size", [(), (BATCH,), (2, 5)], ids=["unbatched", "B", "2x5"])
def test_actor_shapes_range_and_masks(
    name: str, attention_sensors: list[str] | None, batch_size: tuple[int, ...]
) -> None:
    actor = make_neural_actor(name, attention_sensors).eval()
    td = actor(make_observations(batch_size))
    action = td["action"]
    assert action.shape == (*batch_size, N_CONTROLS)
    assert action.dtype == torch.float32
    assert torch.isfinite(action).all() and (action.abs() <= 1.0).all()
    torch.testing.assert_close(action, torch.tanh(td[ACTION_LOC_KEY]))
    spec = CONTROLLERS[name]
    has_input_mask = spec.uses_attention
    has_output_mask = name == "dannet"
    assert (INPUT_MASK_KEY in td) == has_input_mask
    assert (OUTPUT_MASK_KEY in td) == has_output_mask
    for key, size in ((INPUT_MASK_KEY, len(SENSORS)), (OUTPUT_MASK_KEY, N_CONTROLS)):
        if key in td:
            mask = td[key]
            assert mask.shape == (*batch_size, size)
            assert (mask >= 0).all()
            torch.testing.assert_close(mask.sum(-1), torch.ones(batch_size))


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
def test_unbatched_equals_batched_rows(name: str, attention_sensors: list[str] | None) -> None:
    actor = make_neural_actor(name, attention_sensors).eval()
    observations = make_observations()
    batched = actor(observations.clone())["action"]
    single = torch.stack([actor(observations[i].clone())["action"] for i in range(3)])
    torch.testing.assert_close(single, batched[:3])


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
@pytest.mark.parametrize("batch_size", [(), (1,), (BATCH,), (2, 5)], ids=["0", "1", "B", "2x5"])
def test_inference_actor_writes_the_same_outputs(
    name: str, attention_sensors: list[str] | None, batch_size: tuple[int, ...]
) -> None:
    actor = make_neural_actor(name, attention_sensors).eval()
    fast = inference_actor(actor)
    observations = make_observations(batch_size)
    expected = actor(observations.clone())
    got = fast(observations.clone())
    assert sorted(got.keys()) == sorted(expected.keys())
    for key in actor.out_keys:
        assert torch.equal(got[key], expected[key]), key


def test_inference_actor_is_a_snapshot_and_checks_its_inputs() -> None:
    actor = make_neural_actor("dannet", None).train()  # tracing must not change the actor
    fast = inference_actor(actor)
    assert actor.training
    observations = make_observations()
    before = fast(observations.clone())["action"]
    with torch.no_grad():
        for parameter in actor.parameters():
            parameter.add_(0.1)
    assert torch.equal(fast(observations.clone())["action"], before)
    assert not torch.equal(actor.eval()(observations.clone())["action"], before)
    wrong = make_observations()
    wrong["boom_angle"] = torch.zeros(BATCH, 2)
    with pytest.raises(ValueError, match="'boom_angle' must have shape"):
        fast(wrong)
    forest = make_actor("rf", sensors=SENSORS, stats=make_stats())
    with pytest.raises(ValueError, match="random forest"):
        inference_actor(forest)


@pytest.mark.parametrize("name", ["nnetv2", "dannet"])
def test_a_diverged_actor_is_traced_with_the_module_s_nan_outputs(name: str) -> None:
    """A NaN weight (a diverged fine-tune) is no trace defect: the trace gives the module's
    NaN, and acting fails later where the simulator checks its actions."""
    actor = make_neural_actor(name, None).eval()
    with torch.no_grad():
        next(actor.parameters()).view(-1)[0] = float("nan")
    fast = inference_actor(actor)
    observations = make_observations()
    expected = actor(observations.clone())["action"]
    got = fast(observations.clone())["action"]
    assert expected.isnan().any()
    assert torch.equal(got.isnan(), expected.isnan())
    assert torch.equal(got.nan_to_num(0.0), expected.nan_to_num(0.0))


def test_dannet_output_is_tanh_of_masked_pre_activation() -> None:
    policy = make_controller(
        "dannet", sensors=SENSORS, attention_sensors=ALL_SENSORS, stats=make_stats()
    ).eval()
    s, s_att = policy.controller_inputs(make_observations())
    dannet = policy.controller
    out = dannet(s, s_att)
    input_mask, output_mask = dannet.attention(s_att)
    u_prime = dannet.network(s * input_mask).pre_tanh  # F before its tanh
    torch.testing.assert_close(out.input_mask, input_mask)
    torch.testing.assert_close(out.output_mask, output_mask)
    torch.testing.assert_close(out.action, torch.tanh(output_mask * u_prime))
    # the masks are not trivial: masking changes the action
    assert not torch.allclose(out.action, torch.tanh(u_prime))


def test_annet_masks_the_inputs_of_an_nnetv2() -> None:
    policy = make_controller("annet", sensors=SENSORS, stats=make_stats()).eval()
    s, s_att = policy.controller_inputs(make_observations())
    assert s_att is None  # s' = s
    annet = policy.controller
    out = annet(s)
    mask, no_output_mask = annet.attention(s)
    assert no_output_mask is None and out.output_mask is None
    torch.testing.assert_close(out.action, annet.network(s * mask).action)


def test_attention_reads_the_extra_sensors() -> None:
    actor = make_neural_actor("dannet", ALL_SENSORS).eval()
    observations = make_observations()
    before = actor(observations.clone())
    observations["pump_angle"] = observations["pump_angle"] + 5.0
    after = actor(observations.clone())
    assert not torch.allclose(before[INPUT_MASK_KEY], after[INPUT_MASK_KEY])
    assert actor.in_keys == ALL_SENSORS


def test_layer_sizes_follow_the_papers() -> None:
    def linear_shapes(module: torch.nn.Module) -> list[tuple[int, int]]:
        layers = [m for m in module.modules() if isinstance(m, torch.nn.Linear)]
        return [(m.in_features, m.out_features) for m in layers]

    n_s = len(SENSORS)
    nnet = make_controller("nnet", sensors=SENSORS, stats=make_stats()).controller
    assert linear_shapes(nnet) == [(n_s, 5), (5, 3)]
    nnetv2 = make_controller("nnetv2", sensors=SENSORS, stats=make_stats()).controller
    assert linear_shapes(nnetv2) == [(n_s, 200), (200, 200), (200, 10), (10, 3)]
    dropouts = [m.p for m in nnetv2.modules() if isinstance(m, torch.nn.Dropout)]
    assert dropouts == [0.35, 0.35]
    dannet = make_controller(
        "dannet", sensors=SENSORS, attention_sensors=ALL_SENSORS, stats=make_stats()
    ).controller
    assert linear_shapes(dannet.attention) == [(7, 64), (64, 64), (64, n_s), (64, 3)]


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
def test_gradients_reach_every_parameter(name: str, attention_sensors: list[str] | None) -> None:
    actor = make_neural_actor(name, attention_sensors).train()
    td = make_observations()
    target = torch.rand(BATCH, N_CONTROLS) * 2 - 1
    loss = (actor(td)["action"] - target).square().mean()
    loss.backward()
    for param_name, param in actor.named_parameters():
        assert param.grad is not None, param_name
        assert param.grad.abs().sum() > 0, param_name


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
def test_save_load_round_trip(
    name: str, attention_sensors: list[str] | None, tmp_path: pathlib.Path
) -> None:
    actor = make_neural_actor(name, attention_sensors).eval()
    path = save_actor(tmp_path / "actor.pt", actor)
    loaded = load_actor(path)
    assert not loaded.training
    assert loaded.module.config == actor.module.config
    assert loaded.in_keys == actor.in_keys and loaded.out_keys == actor.out_keys
    observations = make_observations()
    expected, got = actor(observations.clone()), loaded(observations.clone())
    for key in actor.out_keys:
        assert torch.equal(expected[key], got[key]), key
    assert [p.name for p in tmp_path.iterdir()] == ["actor.pt"]  # no temporary left


@pytest.mark.parametrize(("name", "attention_sensors"), NEURAL_CASES, ids=CASE_IDS)
def test_stochastic_actor_deterministic_mode_is_the_bc_action(
    name: str, attention_sensors: list[str] | None
) -> None:
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    actor = make_neural_actor(name, attention_sensors).eval()
    stochastic = make_stochastic_actor(actor)
    observations = make_observations()
    bc_action = actor(observations.clone())["action"]
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        deterministic = stochastic(observations.clone())
    torch.testing.assert_close(deterministic["action"], bc_action, atol=1e-6, rtol=0)
    torch.testing.assert_close(deterministic[BC_ACTION_KEY], bc_action)
    # the controller is reused, not copied: its parameters are the actor's
    actor_params = {id(p) for p in actor.parameters()}
    stochastic_params = list(stochastic.parameters())
    assert actor_params <= {id(p) for p in stochastic_params}
    assert len(stochastic_params) == len(actor_params) + 1  # + the log-scale
    with set_exploration_type(ExplorationType.RANDOM):
        sampled = stochastic(observations.clone())
    assert sampled["action"].shape == (BATCH, N_CONTROLS)
    assert (sampled["action"].abs() <= 1.0).all()
    assert not torch.allclose(sampled["action"], bc_action)
    log_prob = stochastic.get_dist(sampled).log_prob(sampled["action"])
    assert log_prob.shape == (BATCH,) and torch.isfinite(log_prob).all()
    log_prob.mean().backward()  # policy gradient reaches the controller and the scale
    for param_name, param in stochastic.named_parameters():
        assert param.grad is not None and param.grad.abs().sum() > 0, param_name
    single = stochastic(observations[0].clone())
    assert single["action"].shape == (N_CONTROLS,)


# ---------------------------------------------------------------------- Levenberg-Marquardt


def test_levenberg_marquardt_beats_first_order_at_equal_iterations() -> None:
    x = torch.linspace(-3.0, 3.0, 200).unsqueeze(-1)
    y = torch.sin(x)
    iterations = 100
    network = NNet(1, 1)  # s-5-1
    adam_net, sgd_net = copy.deepcopy(network), copy.deepcopy(network)

    def mse(model: torch.nn.Module) -> float:
        with torch.no_grad():
            return float((model(x).action - y).square().mean())

    initial = mse(network)
    history = fit_lm(network, x, y, iterations=iterations)
    lm_loss = mse(network)
    for model, optimizer in (
        (adam_net, torch.optim.Adam(adam_net.parameters(), lr=1e-2)),
        (sgd_net, torch.optim.SGD(sgd_net.parameters(), lr=0.1)),
    ):
        for _ in range(iterations):
            optimizer.zero_grad()
            (model(x).action - y).square().mean().backward()
            optimizer.step()
    adam_loss, sgd_loss = mse(adam_net), mse(sgd_net)
    assert len(history) == iterations
    assert history[-1] == pytest.approx(lm_loss, rel=1e-5)
    assert all(b <= a for a, b in zip(history, history[1:], strict=False))  # steps only accepted
    assert lm_loss < 5e-3 < initial
    assert lm_loss < 0.2 * adam_loss and lm_loss < 0.2 * sgd_loss


def test_levenberg_marquardt_fits_an_nnet_actor_on_mini_batches() -> None:
    policy = make_controller("nnet", sensors=SENSORS, stats=make_stats())
    observations = make_observations((256,))
    s, _ = policy.controller_inputs(observations)
    target = torch.tanh(s[:, :3] - 0.5 * s[:, 1:])  # a smooth function of the inputs
    with torch.no_grad():
        before = float((policy.controller(s).action - target).square().mean())
    generator = torch.Generator().manual_seed(0)
    history = fit_lm(
        policy.controller, s, target, iterations=30, batch_size=64, generator=generator
    )
    with torch.no_grad():
        after = float((policy.controller(s).action - target).square().mean())
    assert len(history) == 30 and after < 0.25 * before
    with pytest.raises(ValueError, match="unknown jacobian"):
        fit_lm(policy.controller, s, target, iterations=1, jacobian="finite")


# ---------------------------------------------------------------------- random forest


def make_demonstrations(n: int = 300) -> TensorDict:
    observations = make_observations((n,))
    s = torch.cat([observations[k] for k in SENSORS], -1)
    s = (s - s.mean(0)) / s.std(0)
    observations["action"] = torch.tanh(torch.stack([s[:, 0], s[:, 1] * s[:, 2], -s[:, 3]], -1))
    return observations


def test_random_forest_acts_like_scikit_learn(tmp_path: pathlib.Path) -> None:
    from sklearn.ensemble import RandomForestRegressor

    data = make_demonstrations()
    actor = make_actor("rf", sensors=SENSORS, stats=make_stats())
    assert isinstance(actor, RandomForestActor)
    with pytest.raises(RuntimeError, match="fit"):
        actor(make_observations())
    actor.fit(data)
    forest = actor.module.controller
    assert forest.threshold.shape[0] == 20 and int(forest.depth) <= 30

    observations = make_observations()
    for batch_size in [(), (BATCH,), (2, 5)]:
        action = actor(make_observations(batch_size))["action"]
        assert action.shape == (*batch_size, N_CONTROLS)
        assert (action.abs() <= 1.0).all()
    assert set(actor(observations.clone()).keys()) == {*ALL_SENSORS, "action"}  # no masks

    s_train, _ = actor.module.controller_inputs(data)
    reference = RandomForestRegressor(n_estimators=20, max_depth=30, random_state=0)
    reference.fit(s_train.numpy().astype(np.float32), data["action"].numpy())
    s_test, _ = actor.module.controller_inputs(observations)
    np.testing.assert_allclose(
        actor(observations.clone())["action"].numpy(), reference.predict(s_test.numpy()), atol=1e-6
    )
    # seeded: a second fit gives the same forest
    again = make_actor("rf", sensors=SENSORS, stats=make_stats()).fit(data)
    assert torch.equal(again(observations.clone())["action"], actor(observations.clone())["action"])

    loaded = load_actor(save_actor(tmp_path / "rf.pt", actor))
    assert isinstance(loaded, RandomForestActor)
    assert torch.equal(
        loaded(observations.clone())["action"], actor(observations.clone())["action"]
    )
    with pytest.raises(ValueError, match="pre-tanh"):
        make_stochastic_actor(actor)


def test_actors_read_a_real_dataset(tmp_path: pathlib.Path) -> None:
    store = EpisodeStore.create(
        tmp_path / "dataset", sensors=UNITS, controls=["boom", "bucket", "throttle"]
    )
    for _ in range(2):
        n = 40
        readings = {name: torch.randn(n) + 3.0 for name in ALL_SENSORS}
        store.append(
            make_episode(
                sensors=readings,
                next_sensors=readings,
                actions=torch.rand(n, N_CONTROLS) * 2 - 1,
                time_s=torch.arange(n, dtype=torch.float64) * 0.05,
            ),
            _meta(),
        )
    stats = compute_stats(store)
    data = store.to_tensordict()
    rf = make_actor("rf", sensors=SENSORS, stats=stats).fit(data)
    dannet = make_actor("dannet", sensors=SENSORS, attention_sensors=ALL_SENSORS, stats=stats)
    for actor in (rf, dannet.eval()):
        assert actor(data.clone())["action"].shape == (80, N_CONTROLS)
    s, _ = dannet.module.controller_inputs(data)
    torch.testing.assert_close(s.mean(0), torch.zeros(len(SENSORS)), atol=1e-5, rtol=0)


def _meta():
    from pilerl.data.schema import EpisodeMeta

    return EpisodeMeta(rate_hz=20.0)


# ---------------------------------------------------------------------- checkpoint errors


class _RunsCodeOnLoad:
    """A pickle that would create a file if unpickled with code execution allowed."""

    def __init__(self, marker: pathlib.Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (pathlib.Path.touch, (self.marker,))


def test_load_refuses_corrupt_foreign_and_malicious_files(tmp_path: pathlib.Path) -> None:
    with pytest.raises(FileNotFoundError):
        load_actor(tmp_path / "missing.pt")

    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(b"not a checkpoint at all")
    with pytest.raises(CheckpointError, match="not a readable pilerl actor checkpoint"):
        load_actor(corrupt)

    truncated = tmp_path / "truncated.pt"
    save_actor(truncated, make_neural_actor("nnet", None))
    truncated.write_bytes(truncated.read_bytes()[:200])
    with pytest.raises(CheckpointError, match="not a readable"):
        load_actor(truncated)

    foreign = tmp_path / "foreign.pt"
    torch.save(NNet(4).state_dict(), foreign)  # a plain state dict: no format field
    with pytest.raises(CheckpointError, match="not a pilerl actor checkpoint"):
        load_actor(foreign)

    future = tmp_path / "future.pt"
    torch.save({"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION + 1}, future)
    with pytest.raises(CheckpointError, match="version"):
        load_actor(future)

    mismatched = tmp_path / "mismatched.pt"
    save_actor(mismatched, make_neural_actor("nnetv2", None))
    payload = torch.load(mismatched, weights_only=True)
    config = json.loads(payload["config"])
    config["controller"] = "nnet"
    payload["config"] = json.dumps(config)
    payload.pop("sha256")
    write_checkpoint(mismatched, payload)  # a consistent file whose weights do not fit
    with pytest.raises(CheckpointError, match="do not fit a 'nnet' actor"):
        load_actor(mismatched)

    marker = tmp_path / "code-ran"
    malicious = tmp_path / "malicious.pt"
    torch.save({"format": CHECKPOINT_FORMAT, "payload": _RunsCodeOnLoad(marker)}, malicious)
    with pytest.raises(CheckpointError, match="not a readable"):
        load_actor(malicious)
    assert not marker.exists()


def test_save_overwrites_atomically(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "nested" / "actor.pt"
    first, second = make_neural_actor("nnet", None), make_neural_actor("nnet", None)
    save_actor(path, first)
    save_actor(path, second)
    observations = make_observations()
    assert torch.equal(
        load_actor(path)(observations.clone())["action"],
        second.eval()(observations.clone())["action"],
    )
    assert [p.name for p in path.parent.iterdir()] == ["actor.pt"]
