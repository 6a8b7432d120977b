"""The main job: demonstrations → D_II → behaviour cloning → closed-loop evaluation →
RL fine-tuning → evaluation again → a report with plots and videos.

    python recipes/pipeline.py                      # built-in defaults, ~3.5 min on 2 cores
    python recipes/pipeline.py policy=nnetv2 sensors=s_pt finetune.time_budget_minutes=10

Everything goes under the run directory (``outputs/pipeline/<time>/``): ``demos/``,
``datasets/d_ii``, ``bc/`` (``final.pt``, ``best.pt``, ``losses.png``), ``evaluation/cloned`` and
``evaluation/finetuned`` (episodes, success and fill plots, videos), ``finetune/``
(``best.pt``, success-vs-frames curve), ``figures/`` and ``report.md`` / ``report.html``.
Each stage skips what an interrupted run already finished, so running the same command
with ``hydra.run.dir=<that run>`` resumes it (``run.json`` records the settings; another
config in the same directory is refused). ``evaluation.videos=auto`` renders when this
machine can, and otherwise warns once and writes the report without videos.

The paper's experiment: it speaks the pile loader's words on purpose (summer and winter_c
demonstrations, their cue sensors, the winter group); the single-job recipes take any
simulator.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

from pilerl.config import register_configs
from pilerl.config.pipeline import PipelineConfig
from pilerl.data import EpisodeStore, RecordingPlan, build_dataset
from pilerl.data.recording import record
from pilerl.evaluation.evaluator import ActorController, success_metrics
from pilerl.evaluation.stage import closed_loop_plan, evaluate_controller
from pilerl.layout import RunLayout
from pilerl.recipe import Run, recipe
from pilerl.rendering import resolve_videos
from pilerl.reports.pipeline import write_pipeline_report
from pilerl.rl import finetune
from pilerl.sweeps import is_done, mark_done
from pilerl.training import BCSettings, epochs_for_steps
from pilerl.training.clone import clone, cloning_actor

log = logging.getLogger(__name__)
register_configs()


@recipe("pipeline")
def main(config: PipelineConfig, run: Run) -> dict[str, float]:
    rl_config = dataclasses.replace(config.finetune, env=config.env)  # checked: fails now
    plan = closed_loop_plan(config.evaluation, config.env)  # so does a bad condition
    videos = resolve_videos(
        config.evaluation.videos, where="evaluation.videos", renders=config.env.plugin().renders
    )
    out, bc, rl = run.layout, RunLayout(Path(rl_config.checkpoint).parent), rl_config.output_dir
    name, demos, sensors = config.policy.name, config.demos, config.sensors
    run.begin(
        control_hz=config.env.control_hz,
        demonstrations_hz=demos.record_hz,
        sensors=sensors.s,
        attention_sensors=sensors.s_prime,
    )

    # --- 1. demonstrations: summer (training) and winter_c (validation, figures)
    def demonstrations(condition: str, episodes: int) -> EpisodeStore:
        env_kwargs = config.env.make_kwargs(condition=condition, control_hz=demos.record_hz)
        recording = RecordingPlan(
            config.env.simulator, env_kwargs, n_episodes=episodes, seed=demos.seed,
            expert=demos.expert_options(condition),  # summer: drive-pressure cue; winter_c: p_t
        )  # fmt: skip
        description = f"scripted demonstrations, {condition}, {demos.record_hz:g} Hz"
        where = out.sub("demos", condition).root
        return record(where, recording, workers=demos.workers, description=description)

    summer = demonstrations("summer", demos.episodes)
    winter = demonstrations("winter_c", demos.validation_episodes)

    # --- 2. D_II: the successful summer demonstrations at the recorded rate
    dataset = build_dataset(summer, rl_config.demos, successful_only=True, rate_hz=None)

    # --- 3. behaviour cloning (resumes from bc/last.pt; a finished run returns at once)
    bc_config, train = config.bc, dataset.to_tensordict()
    actor = cloning_actor(
        name, sensors.s, sensors.s_prime, dataset.stats,
        options=config.policy.options, seed=bc_config.seed,
    )  # fmt: skip
    settings = BCSettings(
        epochs=epochs_for_steps(len(train), bc_config.batch_size, bc_config.gradient_steps),
        batch_size=bc_config.batch_size,
        learning_rate=bc_config.learning_rate,
        seed=bc_config.seed,
    )
    clone(
        actor, train, winter.to_tensordict(), settings, bc.root,
        logger_backend=config.logger.backend, title=f"{name} on D_II",
    )  # fmt: skip

    # --- 4. the cloned controller in closed loop
    def closed_loop(actor_file: Path, label: str, where: str, videos: bool = False) -> dict:
        controller = ActorController(str(actor_file), name=f"{name} ({label})")
        where = out.sub("evaluation", where).root
        return evaluate_controller(controller, plan, config.evaluation, where, videos=videos)

    cloned = closed_loop(Path(rl_config.checkpoint), "cloned", "cloned")  # bc.selection

    # --- 5. RL fine-tuning (resumes from its own checkpoint)
    if not is_done(rl):
        mark_done(rl, {"frames": finetune(rl_config, rl)["frames"]})

    # --- 6. the fine-tuned controller on the same starts, with videos
    finetuned = closed_loop(RunLayout(rl).best_actor, "RL", "finetuned", videos=videos)

    # --- 7. the report
    stores = {"summer": summer, "winter": winter, "dataset": dataset}
    report = write_pipeline_report(config, out.root, **stores, before=cloned, after=finetuned)
    log.info("report: %s", report)
    return success_metrics(cloned, "cloned_") | success_metrics(finetuned, "finetuned_")


if __name__ == "__main__":
    main()
