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

from pilerl.config import register_configs
from pilerl.data import EpisodeMeta, EpisodeStore, record_episode
from pilerl.data.recorder import recorded_info
from pilerl.data.settings import TeleopConfig
from pilerl.operators.keyboard import KeyboardOperator, close_viewer, key_bindings_text
from pilerl.recipe import recipe
from pilerl.sim.rollout import make_rollout_env

log = logging.getLogger(__name__)
register_configs()


@recipe("teleop")
def main(config: TeleopConfig) -> None:
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise SystemExit(
            "teleop needs a display (no DISPLAY or WAYLAND_DISPLAY is set); "
            "record scripted demonstrations with recipes/record.py instead"
        )
    import mujoco.viewer  # imported here: it opens a window

    env = make_rollout_env(
        config.env.simulator,
        config.env.make_kwargs(),
        info_keys=recorded_info(config.env.simulator),
    )
    sim = env.simulators[0].unwrapped
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

        class Paced:  # the keyboard, paced to real time, the viewer refreshed every step
            def reset(self):
                operator.reset()

            def act(self, sensors):
                viewer.sync()
                time.sleep(sim.dt)
                return operator.act(sensors)

        for index in range(config.episodes):
            episode, start, final = record_episode(env, Paced(), seed=config.seed + index)
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
