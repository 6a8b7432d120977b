"""Drive the loader from the keyboard in MuJoCo's viewer and record the episodes.

    python recipes/teleop.py                           # summer, records to data/demos/teleop
    python recipes/teleop.py env.condition=winter_c episodes=5

Keys: Up/Down boom, Right/Left bucket, W/S throttle (each press steps the level by 0.25),
Space stops all. Needs a display (the viewer is an interactive window).
"""

from __future__ import annotations

import logging
import os
import time

import hydra
from omegaconf import DictConfig, OmegaConf

from pilerl.config import TeleopConfig, register_configs
from pilerl.data import EpisodeMeta, EpisodeStore, record_episode
from pilerl.operators.keyboard import KeyboardOperator, close_viewer, key_bindings_text
from pilerl.runtime import limit_threads
from pilerl.sim import make_gym_env

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="teleop", version_base="1.3")
def main(cfg: DictConfig) -> None:
    limit_threads()
    config: TeleopConfig = OmegaConf.to_object(cfg)
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise SystemExit(
            "teleop needs a display (no DISPLAY or WAYLAND_DISPLAY is set); "
            "record scripted demonstrations with recipes/record.py instead"
        )
    import mujoco.viewer  # imported here: it opens a window

    env = make_gym_env(config.env.simulator, **config.env.make_kwargs())
    sim = env.unwrapped
    store = EpisodeStore.create(
        config.out_dir,
        sensors=config.env.plugin().sensor_units,
        controls=list(config.env.plugin().controls),
        exist_ok=True,
        description="keyboard teleoperation",
    )
    operator = KeyboardOperator()
    print(key_bindings_text(), flush=True)
    viewer = mujoco.viewer.launch_passive(sim.model, sim.data, key_callback=operator.on_key)
    try:

        def act(sensors):  # paced to real time, the viewer refreshed every step
            viewer.sync()
            time.sleep(sim.dt)
            return operator.act(sensors)

        for index in range(config.episodes):
            operator.reset()
            episode, start, final = record_episode(env, act, seed=config.seed + index)
            success, fill = config.env.plugin().score(final)
            meta = store.append(
                episode,
                EpisodeMeta(
                    rate_hz=1.0 / sim.dt,
                    source="teleop",
                    condition=config.env.condition,
                    soil=config.env.soil,
                    operator={"id": config.operator_id, "kind": "teleop"},
                    fill_fraction=fill,
                    success=success,
                    seed=config.seed + index,
                    start={k: float(v) for k, v in start.items() if k.startswith("start_")},
                ),
            )
            log.info("episode %d: fill %.2f, success %s", meta.id, meta.fill_fraction, meta.success)
    finally:
        close_viewer(viewer)  # before the process exits: see close_viewer
        env.close()


if __name__ == "__main__":
    main()
