"""Ray: TorchRL's RayCollector over the pile loader, and sweeps on the Ray launcher.

One local Ray instance (2 CPUs) serves the whole module: the collector uses it from this
process, and the recipe sweep joins it from a subprocess by address, as a sweep joins a
cluster started with ``ray start --head``.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import ray
import torch
import yaml
from hydra import compose, initialize_config_dir
from pilerl_pile_loader.sensors import SENSOR_NAMES
from test_rl import cloned, tiny_config, tiny_ppo  # noqa: F401  (cloned: a fixture)

from hydra_plugins.pilerl_ray_launcher import _core as ray_launcher_core
from hydra_plugins.pilerl_ray_launcher.config import DEFAULT_ENV_VARS, RayLauncherConf
from hydra_plugins.pilerl_ray_launcher.ray_launcher import RayLauncher
from pilerl.config import register_configs
from pilerl.data import EpisodeMeta, EpisodeStore, make_episode
from pilerl.policies import make_actor
from pilerl.rl import ray_collection
from pilerl.sim import make_torchrl_env

ROOT = Path(__file__).resolve().parents[2]

SENSORS = list(SENSOR_NAMES)  # the pile loader's seven sensors
ACTOR_SENSORS = SENSORS[:4]

# TorchRL 0.14 defines its legacy weight updaters when torchrl.collectors.distributed loads
pytestmark = pytest.mark.filterwarnings(
    "ignore:Creating .* which inherits from WeightUpdaterBase:DeprecationWarning"
)


@pytest.fixture(scope="module")
def ray_address():
    """A local Ray instance for this module; yields its address for other processes."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    ray.init(num_cpus=2, include_dashboard=False)
    yield ray.get_runtime_context().gcs_address
    ray.shutdown()


def bc_actor() -> torch.nn.Module:
    """A small untrained BC actor (NNetV2) with statistics near the sensors' ranges."""
    torch.manual_seed(0)
    stats = {
        "n_samples": 100,
        "sensors": {
            name: {"mean": 1.0, "std": 2.0, "min": -10.0, "max": 30.0} for name in ACTOR_SENSORS
        },
        "action": {"mean": [0.0] * 3, "std": [0.5] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
    }
    return make_actor("nnetv2", sensors=ACTOR_SENSORS, stats=stats).eval()


def test_ray_collector_collects_the_requested_frames_with_the_actor(ray_address):
    actor = bc_actor()
    collector = ray_collection.make_ray_collector(
        functools.partial(make_torchrl_env, "pile_loader", condition="winter_c"),
        actor,
        frames_per_batch=20,
        total_frames=60,
        num_collectors=2,
        seed=0,
        collector_kwargs={"auto_register_policy_transforms": False},
    )
    # the learner gave the actors WEIGHT_SYNC_TIMEOUT_S to join (its first weights went out)
    from torchrl.weight_update import _ray as torchrl_ray_weights

    assert torchrl_ray_weights._DIST_TIMEOUT.total_seconds() == (
        ray_collection.WEIGHT_SYNC_TIMEOUT_S
    )
    batches = [batch for batch in collector]  # the iterator shuts the actors down at the end
    assert [batch.batch_size for batch in batches] == [torch.Size([20])] * 3
    data = torch.cat(batches)
    keys = set(data.keys(True, True))
    for name in SENSORS:
        assert name in keys and ("next", name) in keys
    for key in ("action", "action_loc", ("next", "reward"), ("next", "done")):
        assert key in keys
    for key in keys:
        value = data.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    assert data["action"].shape == (60, 3)
    # the actors ran this actor's weights: its deterministic output on their observations
    assert torch.allclose(actor(data.select(*ACTOR_SENSORS))["action_loc"], data["action_loc"])


def test_ray_workers_get_one_thread_and_offscreen_rendering(ray_address):
    @ray.remote(num_cpus=1, runtime_env=ray_collection.worker_runtime_env())
    def worker_settings(names: list[str]) -> tuple[dict, int]:
        import torch

        return {name: os.environ.get(name) for name in names}, torch.get_num_threads()

    env_vars, threads = ray.get(worker_settings.remote(list(ray_collection.WORKER_ENV_VARS)))
    assert env_vars == ray_collection.WORKER_ENV_VARS and threads == 1


def test_ray_collector_rejects_bad_arguments(ray_address):
    make_env = functools.partial(make_torchrl_env, "pile_loader")
    with pytest.raises(ValueError, match="num_collectors must be a positive int, got 0"):
        ray_collection.make_ray_collector(
            make_env, None, frames_per_batch=10, total_frames=10, num_collectors=0
        )
    with pytest.raises(ValueError, match="must be a multiple of num_collectors"):
        ray_collection.make_ray_collector(
            make_env, None, frames_per_batch=15, total_frames=30, num_collectors=2, sync=True
        )
    with pytest.raises(ValueError, match="3 collectors need 3 CPUs but the Ray cluster has 2"):
        ray_collection.make_ray_collector(
            make_env, None, frames_per_batch=10, total_frames=10, num_collectors=3
        )
    with pytest.raises(ValueError, match="Ray is already initialised in this process"):
        ray_collection.make_ray_collector(
            make_env,
            None,
            frames_per_batch=10,
            total_frames=10,
            num_collectors=1,
            ray_init_kwargs={"address": "auto"},
        )


def make_demos(root: Path) -> None:
    """Two 50-row demonstrations at 100 Hz: one successful, one not."""
    store = EpisodeStore.create(
        root,
        sensors={"boom_angle": "rad", "drive_pressure": "MPa"},
        controls=["boom", "bucket", "throttle"],
    )
    rows = torch.arange(50, dtype=torch.float32)
    for success in (True, False):
        episode = make_episode(
            sensors={"boom_angle": rows / 100, "drive_pressure": rows},
            next_sensors={"boom_angle": (rows + 1) / 100, "drive_pressure": rows + 1},
            actions=torch.stack([torch.sin(rows), torch.cos(rows), rows * 0 + 0.5], -1),
            time_s=torch.arange(50, dtype=torch.float64) / 100,
            terminated=True,
        )
        store.append(episode, EpisodeMeta(rate_hz=100.0, condition="summer", success=success))


def run_recipe(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    env["RAY_USAGE_STATS_ENABLED"] = "0"
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, env=env, timeout=600, cwd=cwd
    )


def test_multirun_on_the_ray_launcher_runs_each_job_with_its_overrides(ray_address, tmp_path):
    make_demos(tmp_path / "demos")
    # relative paths: each job must run in the launch directory, wherever Ray started it
    result = run_recipe(
        str(ROOT / "recipes" / "build_dataset.py"),
        "--multirun",
        "hydra/launcher=ray_cluster",
        f"hydra.launcher.address={ray_address}",
        "hydra.launcher.memory_gb_per_job=null",
        "dataset=d_i,d_ii",
        "source=demos",
        "out_dir=datasets/${dataset.name}",
        "hydra.sweep.dir=sweep",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    expected = {"0": ("dataset=d_i", 2, 100), "1": ("dataset=d_ii", 1, 10)}  # D_II: 20 Hz
    for job, (override, episodes, samples) in expected.items():
        job_dir = tmp_path / "sweep" / job
        overrides = yaml.safe_load((job_dir / ".hydra" / "overrides.yaml").read_text())
        assert override in overrides
        assert json.loads((job_dir / "metrics.json").read_text()) == {
            "episodes": episodes,
            "samples": samples,
        }
        assert (job_dir / "done.json").exists()
    d_ii = json.loads((tmp_path / "datasets" / "d_ii" / "index.json").read_text())
    assert len(d_ii["episodes"]) == 1 and d_ii["episodes"][0]["rate_hz"] == 20.0


def test_bad_launcher_config_fails_before_any_job(tmp_path):
    result = run_recipe(
        str(ROOT / "recipes" / "build_dataset.py"),
        "--multirun",
        "hydra/launcher=ray_local",
        "hydra.launcher.num_cpus=-1",
        "dataset=d_i,d_ii",
        "source=demos",
        "hydra.sweep.dir=sweep",
        cwd=tmp_path,
    )
    assert result.returncode != 0
    assert "hydra.launcher.num_cpus must be >= 1 or null, got -1" in result.stderr
    assert not (tmp_path / "sweep" / "0").exists()


def test_launcher_rejects_jobs_larger_than_the_cluster(ray_address):
    too_many_cpus = RayLauncherConf(address=ray_address, cpus_per_job=3)
    with pytest.raises(ValueError, match="cpus_per_job=3 but the Ray cluster has 2 CPUs"):
        ray_launcher_core.check_resources(too_many_cpus)
    with pytest.raises(ValueError, match="gpus_per_job=1 but the Ray cluster has 0 GPUs"):
        ray_launcher_core.check_resources(RayLauncherConf(gpus_per_job=1))
    with pytest.raises(ValueError, match="memory_gb_per_job=1e\\+06 but the Ray cluster has"):
        ray_launcher_core.check_resources(RayLauncherConf(memory_gb_per_job=1e6))


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"cpus_per_job": 0}, "hydra.launcher.cpus_per_job must be > 0, got 0"),
        ({"num_cpus": 2, "cpus_per_job": 4}, "cpus_per_job \\(4\\) exceeds .*num_cpus \\(2\\)"),
        ({"num_cpus": 2, "address": "auto"}, "cannot be combined with hydra.launcher.address"),
        ({"gpus_per_job": -1}, "hydra.launcher.gpus_per_job must be >= 0, got -1"),
        ({"memory_gb_per_job": 0}, "hydra.launcher.memory_gb_per_job must be > 0 or null"),
        ({"max_retries": -1}, "hydra.launcher.max_retries must be >= 0, got -1"),
        ({"address": " "}, "hydra.launcher.address must be null or a Ray address"),
    ],
)
def test_launcher_settings_are_checked(settings, message):
    with pytest.raises(ValueError, match=message):
        RayLauncherConf(**settings)


@pytest.mark.parametrize("preset", ["ray_local", "ray_cluster"])
def test_launcher_presets_compose_into_launcher_settings(preset):
    register_configs()
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(
            "build_dataset",
            overrides=[f"hydra/launcher={preset}", "+hydra.launcher.env_vars.EXTRA=1"],
            return_hydra_config=True,
        )
    launcher_cfg = dict(cfg.hydra.launcher)
    assert launcher_cfg.pop("_target_").endswith("pilerl_ray_launcher.ray_launcher.RayLauncher")
    settings = RayLauncher(**launcher_cfg).settings
    options = settings.remote_options()
    assert options["num_cpus"] == 1 and options["max_retries"] == 0
    assert options["runtime_env"]["env_vars"] == {**DEFAULT_ENV_VARS, "EXTRA": "1"}
    if preset == "ray_local":
        assert settings.init_kwargs() == {"num_cpus": 2, "include_dashboard": False}
    else:
        assert settings.init_kwargs() == {"address": "auto"}
        assert options["memory"] == 4 * 1024**3


def test_ppo_fine_tuning_collects_on_ray(ray_address, cloned, tmp_path):  # noqa: F811
    from pilerl.rl import CollectionConfig, finetune

    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo(), frames=128)
    config.collection = CollectionConfig(backend="ray", workers=2, envs_per_worker=1)
    results = finetune(config, tmp_path, progress=False)
    assert results["frames"] == 128 and results["batches"] == 2
    assert (tmp_path / "final.pt").exists() and results["collection_fps"] > 0
