"""Record scripted demonstrations into a dataset directory.

    python recipes/record.py                       # 72 summer demonstrations at 500 Hz
    python recipes/record.py n_episodes=4 record_hz=100 out_dir=/tmp/demos

An existing ``out_dir`` is resumed: episodes already recorded are kept and skipped. Its
``run.json`` records the recording plan; resuming with another plan (condition, rate,
seed, operator ...) is refused, naming what differs; only ``n_episodes`` may grow.
"""

from __future__ import annotations

import logging

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.data import EpisodeStore, RecordingPlan, record_demonstrations
from pilerl.data.settings import RecordConfig
from pilerl.runs import begin_run, finish_run
from pilerl.runtime import limit_threads
from pilerl.sim import make_gym_env

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="record", version_base="1.3")
def main(cfg: DictConfig) -> None:
    limit_threads()
    config: RecordConfig = OmegaConf.to_object(cfg)
    env_kwargs = config.env.make_kwargs(control_hz=config.record_hz)

    make_gym_env(config.env.simulator, **env_kwargs).close()  # fail early: checks every option
    plugin = config.env.plugin()
    plan = RecordingPlan(
        config.env.simulator,
        env_kwargs,
        n_episodes=config.n_episodes,
        seed=config.seed,
        expert=config.expert,
    )
    store = EpisodeStore.create(
        config.out_dir,
        sensors=plugin.sensor_units,
        controls=list(plugin.controls),
        description=f"scripted demonstrations, {env_kwargs['condition']}, {config.record_hz} Hz",
        exist_ok=True,
    )
    plan_settings = OmegaConf.to_container(cfg, resolve=True)
    plan_settings.pop("out_dir")  # the store itself
    begin_run(config.out_dir, plan_settings, growable=["n_episodes"])

    # --- record (resumes)
    record_demonstrations(store, plan, workers=config.workers)
    successes = sum(m.success for m in store.episodes)
    log.info(
        "%s: %d episodes, %d samples, %d successful",
        config.out_dir,
        len(store),
        store.n_samples,
        successes,
    )
    finish_run(
        HydraConfig.get().runtime.output_dir,
        {
            "episodes": len(store),
            "samples": store.n_samples,
            "success_rate": successes / len(store),
        },
    )


if __name__ == "__main__":
    main()
