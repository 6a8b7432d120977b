"""The main job: demonstrations → D_II → behaviour cloning → closed-loop evaluation →
RL fine-tuning → evaluation again → a report with plots and videos.

    python recipes/pipeline.py                      # built-in defaults, ~3.5 min on 2 cores
    python recipes/pipeline.py policy=nnetv2 sensors=s_pt finetune.time_budget_minutes=10

Everything goes under the run directory (``outputs/pipeline/<time>/``): ``demos/``,
``datasets/d_ii``, ``bc/`` (``best.pt``, ``losses.png``), ``evaluation/cloned`` and
``evaluation/finetuned`` (episodes, success and fill plots, videos), ``finetune/``
(``best.pt``, success-vs-frames curve), ``figures/`` and ``report.md`` / ``report.html``.
Each stage skips what an interrupted run already finished, so running the same command
with ``hydra.run.dir=<that run>`` resumes it (``run.json`` records the settings; another
config in the same directory is refused). ``evaluation.videos=auto`` renders when this
machine can, and otherwise warns once and writes the report without videos.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import hydra
import torch
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.config.pipeline import PipelineConfig
from pilerl.data import EpisodeStore, RecordingPlan, build_dataset, record_demonstrations
from pilerl.evaluation import ActorController, run_closed_loop
from pilerl.evaluation.evaluator import build_envs, success_metrics
from pilerl.loggers import make_logger
from pilerl.policies import NEURAL_CONTROLLERS, controller_inputs, make_actor
from pilerl.rendering import resolve_videos
from pilerl.reports.pipeline import write_pipeline_report
from pilerl.rl import finetune
from pilerl.runs import begin_run, finish_run
from pilerl.runtime import limit_threads
from pilerl.sweeps import is_done, mark_done
from pilerl.training import BCSettings, epochs_for_steps, train_bc
from pilerl.training.plots import plot_losses

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="pipeline", version_base="1.3")
def main(cfg: DictConfig) -> None:
    limit_threads()
    config: PipelineConfig = OmegaConf.to_object(cfg)
    out = Path(config.output_dir)
    if config.policy.name not in NEURAL_CONTROLLERS:
        raise ValueError(
            f"policy: {config.policy.name!r} cannot be fine-tuned by RL (not differentiable); "
            f"choose one of {list(NEURAL_CONTROLLERS)}"
        )
    rl_config = dataclasses.replace(config.finetune, env=config.env)  # checked: fails now
    plan = config.evaluation.plan(config.env)
    build_envs(plan)  # a bad condition or env setting fails before any work
    videos = resolve_videos(config.evaluation.videos, where="evaluation.videos")
    bc_dir = Path(rl_config.checkpoint).parent
    facts = {
        "control_hz": config.env.control_hz,
        "demonstrations_hz": config.demos.record_hz,
        "sensors": config.sensors.s,
        "attention_sensors": config.sensors.s_prime,
    }
    if begin_run(out, OmegaConf.to_container(cfg, resolve=True), **facts):
        log.info("%s already finished: skipping (same settings)", out)
        return

    # --- 1. demonstrations: summer (training) and winter_c (validation, figures)
    summer = record(config, "summer", "drive_pressure", config.demos.episodes, out / "demos")
    winter = record(
        config, "winter_c", "telescope_pressure", config.demos.validation_episodes, out / "demos"
    )

    # --- 2. D_II: the successful summer demonstrations at the recorded rate
    if not (Path(rl_config.demos) / "index.json").exists():
        build_dataset(summer, rl_config.demos, successful_only=True, rate_hz=None)
    dataset = EpisodeStore.open(rl_config.demos)

    # --- 3. behaviour cloning (resumes from bc/last.pt; a finished run returns at once)
    torch.manual_seed(config.bc.seed)
    sensors, attention = controller_inputs(
        config.policy.name, config.sensors.s, config.sensors.s_prime
    )
    actor = make_actor(
        config.policy.name,
        sensors=sensors,
        attention_sensors=attention,
        stats=dataset.stats,
        options=config.policy.options,
    )
    train = dataset.to_tensordict()
    settings = BCSettings(
        epochs=epochs_for_steps(len(train), config.bc.batch_size, config.bc.gradient_steps),
        batch_size=config.bc.batch_size,
        learning_rate=config.bc.learning_rate,
        seed=config.bc.seed,
    )
    logger = make_logger(config.logger.backend, bc_dir, experiment_name="bc")
    _, history = train_bc(
        actor, train, winter.to_tensordict(), settings, run_dir=bc_dir, logger=logger
    )
    plot_losses(history, bc_dir / "losses.png", title=f"{config.policy.name} on D_II")

    # --- 4. the cloned controller in closed loop
    cloned = run_closed_loop(
        ActorController(str(bc_dir / "best.pt"), name=f"{config.policy.name} (cloned)"),
        plan,
        out / "evaluation" / "cloned",
        workers=config.evaluation.workers,
    )

    # --- 5. RL fine-tuning (resumes from its own checkpoint)
    if not is_done(rl_config.output_dir):
        results = finetune(rl_config, rl_config.output_dir)
        mark_done(rl_config.output_dir, {"frames": results["frames"]})

    # --- 6. the fine-tuned controller on the same starts, with videos
    finetuned = run_closed_loop(
        ActorController(
            str(Path(rl_config.output_dir) / "best.pt"), name=f"{config.policy.name} (RL)"
        ),
        plan,
        out / "evaluation" / "finetuned",
        workers=config.evaluation.workers,
        videos=videos,
        video_conditions=config.evaluation.video_conditions,
        render_size=(config.evaluation.render_height, config.evaluation.render_width),
    )

    # --- 7. the report
    report = write_pipeline_report(
        config, out, summer=summer, winter=winter, dataset=dataset, before=cloned, after=finetuned
    )
    log.info("report: %s", report)
    finish_run(
        out,
        success_metrics(cloned, "cloned_") | success_metrics(finetuned, "finetuned_"),
    )


def record(
    config: PipelineConfig, condition: str, trigger: str, episodes: int, root: Path
) -> EpisodeStore:
    """Scripted demonstrations in ``condition`` (resumes a partly recorded store)."""
    env_kwargs = config.env.make_kwargs(condition=condition, control_hz=config.demos.record_hz)
    plugin = config.env.plugin()
    store = EpisodeStore.create(
        root / condition,
        sensors=plugin.sensor_units,
        controls=list(plugin.controls),
        description=f"scripted demonstrations, {condition}, {config.demos.record_hz:g} Hz",
        exist_ok=True,
    )
    plan = RecordingPlan(
        config.env.simulator,
        env_kwargs,
        n_episodes=episodes,
        seed=config.demos.seed,
        expert={"trigger_sensor": trigger, "mistake_rate": config.demos.mistake_rate},
    )
    record_demonstrations(store, plan, workers=config.demos.workers)
    return store


if __name__ == "__main__":
    main()
