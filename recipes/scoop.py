"""Record, render and report scripted scoops, one per condition (the main job for now).

    python recipes/scoop.py                     # the simulator's example conditions
    python recipes/scoop.py env=toy_cart        # any installed simulator
    python recipes/scoop.py conditions=[summer,winter_b] env.soil=particles video=false

``video=auto`` (default) renders when this machine can; ``video=true`` refuses before any
work if it cannot.

Writes to the Hydra run directory: ``scoop_<condition>.mp4``, ``trace_<condition>.csv``,
``scoop_signals.png``, ``summary.json`` and ``report.md``.
"""

from __future__ import annotations

import logging
import math

from pilerl.config import register_configs
from pilerl.evaluation import plot_scoop, run_episode, write_mp4
from pilerl.evaluation.episode import make_episode_env
from pilerl.evaluation.scoop_report import summarize, write_scoop_report, write_trace_csv
from pilerl.evaluation.settings import ScoopConfig
from pilerl.evaluation.video import annotate_frames, sensor_ranges
from pilerl.operators import OperatorModule
from pilerl.recipe import Run, recipe
from pilerl.rendering import resolve_videos
from pilerl.sim.rollout import control_period_s

log = logging.getLogger(__name__)
register_configs()


@recipe("scoop")
def main(config: ScoopConfig, run: Run) -> dict[str, float]:
    out_dir = config.output_dir
    video = resolve_videos(config.video, where="video", renders=config.env.plugin().renders)
    episodes, summaries, videos = {}, {}, []

    # --- build every env first: a bad condition or parameter fails before any work
    envs = {
        condition: make_episode_env(
            config.env.simulator,
            {
                **config.env.make_kwargs(condition=condition),
                **(
                    {
                        "render_mode": "rgb_array",
                        "render_size": (config.render_height, config.render_width),
                        "camera": config.camera,
                    }
                    if video
                    else {}
                ),
            },
        )
        for condition in config.env.plugin().resolve_conditions(
            config.conditions, where="conditions"
        )
    }
    run.begin(scripted_expert_revision=config.env.plugin().expert_revision)

    # --- one scripted scoop per condition
    for condition, env in envs.items():
        operator = config.env.plugin().make_expert(dt=control_period_s(env), **config.expert)
        policy = OperatorModule.for_env([operator], env)
        episode = run_episode(
            env, policy, seed=config.seed, render=video, progress=f"scoop {condition}"
        )
        ranges = sensor_ranges(env.simulators[0])
        env.close()
        episodes[condition] = episode
        summaries[condition] = summarize(episode, simulator=config.env.simulator)
        log.info("%s: %s", condition, summaries[condition])

        # --- artefacts a person can look at
        write_trace_csv(episode, f"{out_dir}/trace_{condition}.csv", simulator=config.env.simulator)
        if video:
            frames = annotate_frames(
                episode, condition=condition, sensor_ranges=ranges, simulator=config.env.simulator
            )
            write_mp4(frames, f"{out_dir}/scoop_{condition}.mp4", fps=episode.frame_hz)
            videos.append(f"scoop_{condition}.mp4")

    # --- report
    plot_scoop(episodes, f"{out_dir}/scoop_signals.png", simulator=config.env.simulator)
    report = write_scoop_report(
        summaries,
        out_dir,
        seed=config.seed,
        figures=["scoop_signals.png"],
        videos=videos,
        simulator=config.env.simulator,
    )
    log.info("report: %s", report)
    return {  # every finite number of the summaries (a simulator may not report some)
        f"{condition}_{key}": float(value)
        for condition, summary in summaries.items()
        for key, value in summary.items()
        if isinstance(value, int | float) and math.isfinite(float(value))
    }


if __name__ == "__main__":
    main()
