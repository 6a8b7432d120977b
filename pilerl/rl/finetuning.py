"""Fine-tune a cloned controller by RL in the simulator: the loop and its bookkeeping.

``finetune(config, run_dir)`` reads top to bottom:

1. check the config and the checkpoint (a neural controller) before any work;
2. build the learner (PPO, TD3+BC or RLPD, plain or residual) around the cloned actor;
3. resume from ``run_dir/last.ckpt`` if there is one;
4. evaluate the cloned actor (before), per condition group, with Wilson intervals, and
   on ``evaluation.cross_check_env``'s options if set;
5. for each curriculum stage: collect in that stage's condition mixture (the simulators
   of a batch taking ``collection.env_variants`` in turn, if set), update,
   evaluate every ``evaluation.every_frames`` and at the scoop counts ``evaluation.at_scoops``
   (keeping the best actor as ``best.pt``), checkpoint every ``checkpoint_every_frames``,
   stop after ``max_scoops`` scoops;
6. evaluate ``best.pt`` and the last actor (after) on the before-evaluation's starts,
   and ``best.pt`` on the cross-check's options; plot success vs frames, write
   ``results.json``.

Files in ``run_dir``:

| file | what |
|---|---|
| ``last.ckpt`` | verified checkpoint (``run_checkpoint``): learner, optimisers, RNG, progress |
| ``best.pt`` | actor with the best periodic evaluation (``pilerl.policies.load_actor``); |
|  | the last actor when there is no periodic evaluation (``every_frames`` 0, no ``at_scoops``) |
| ``final.pt`` | actor after the last update |
| ``success_curve.png`` | success vs frames per group with Wilson bands |
| ``evaluations.json`` | every periodic evaluation |
| ``results.json`` | before / after per group, frames, scoops (failed, tipped), wall time, |
|  | ``cross_check``: before / after on ``evaluation.cross_check_env``'s options |
| ``finetune/`` | TorchRL CSV log of every batch |
| ``videos/`` | one episode per group at each evaluation (``evaluation.video``) |

Reproducible and resumable bit for bit (``single`` collection): collection runs in
*segments* of ``checkpoint_every_frames`` (cut at curriculum stages too); each segment
restarts the simulators from a seed derived from (``seed``, batches so far) and ends with
``last.ckpt``; collectors are built without drawing from torch's global generator. An uninterrupted
run and one killed and resumed from ``last.ckpt`` therefore start every segment in the same
state (weights, optimisers, generators, TD3+BC's replay buffer, simulators) and end with
the same weights. ``last.ckpt`` is read pickle-free and verified (``run_checkpoint``); a
kill leaves the old or the new one, and the temporary file a kill may leave is removed on
the next start, as are the CSV log rows written after the checkpoint (no duplicates).

Scoops: every collected batch's ended episodes are counted (``pilerl.rl.scoops``): scoops
of experience, and of those the failed and the tipped ones, in the log (``scoops``,
``failed_scoops``, ``tipped_scoops``), in ``last.ckpt``'s progress, in every periodic
evaluation's record and in ``results.json``. Evaluation episodes are not experience: they
are counted apart (``evaluation_episodes``).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict
from pathlib import Path

import torch
from tensordict import TensorDictBase
from tqdm import tqdm

from pilerl.data import EpisodeStore
from pilerl.evaluation.closed_loop import render_rollout
from pilerl.evaluation.evaluator import EvaluationPlan
from pilerl.io import write_text_atomic
from pilerl.loggers import make_logger
from pilerl.policies import CheckpointError, actor_policy, load_actor

from .collection import make_collector, restart_collection, sync_weights
from .config import (
    FinetuneConfig,
    PPOConfig,
    RLPDConfig,
    cross_check_kwargs,
    plain_mapping,
    resolve_simulator_words,
    uses_demos,
    variant_kwargs,
)
from .envs import TrainingEnvFactory
from .evaluation import evaluate_groups, plot_success_curve, pool_groups
from .ppo import PPOLearner
from .residual import controller_for, save_any_actor
from .rlpd import RLPDLearner
from .run_checkpoint import load_run, remove_partial_writes, save_run, set_global_rng_state
from .scoops import count_scoops
from .td3bc import TD3BCLearner

log = logging.getLogger(__name__)

RUN_CHECKPOINT = "last.ckpt"
BEST_ACTOR = "best.pt"
FINAL_ACTOR = "final.pt"
RESULTS_FILE = "results.json"
EVALUATIONS_FILE = "evaluations.json"
CURVE_FILE = "success_curve.png"
LOG_NAME = "finetune"  # the CSV logger's folder
# every file written atomically in the run directory (also the recipe's sweep markers)
RUN_FILES = [
    RUN_CHECKPOINT,
    BEST_ACTOR,
    FINAL_ACTOR,
    RESULTS_FILE,
    EVALUATIONS_FILE,
    CURVE_FILE,
    "metrics.json",
    "done.json",
]
SCOOP_FIELDS = ("scoops", "failed_scoops", "tipped_scoops")  # counted from the collected batches
CROSS_CHECK_BEFORE = "cross_check_before"  # progress entry, only with a cross-check
SEGMENT_SEED_STRIDE = 1_000_003  # segment seed = seed * stride + batches so far
VIDEO_SIZE = (240, 320)  # (height, width) of evaluation videos [px]


def load_cloned_actor(checkpoint: str | Path):
    """The cloned actor, or a clear error when it cannot be fine-tuned by gradient."""
    try:
        actor = load_actor(checkpoint)
    except (FileNotFoundError, CheckpointError) as error:
        raise type(error)(f"checkpoint: {error}") from None
    policy = actor_policy(actor)
    if not getattr(policy.controller, "has_pre_tanh", False):
        raise ValueError(
            f"checkpoint {checkpoint}: controller {policy.config.controller!r} is not a neural "
            "network with a pre-tanh output; RL fine-tuning needs one (nnet, nnetv2, annet, "
            "dannet)"
        )
    return actor


def make_learner(config: FinetuneConfig, actor, demos: TensorDictBase | None):
    """``PPOLearner``, ``TD3BCLearner`` or ``RLPDLearner`` for ``config.algorithm``."""
    if isinstance(config.algorithm, PPOConfig):
        return PPOLearner(actor, config.algorithm, demos=demos, seed=config.seed)
    if isinstance(config.algorithm, RLPDConfig):  # replay sampling: torch's global generator
        return RLPDLearner(actor, config.algorithm, demos=demos)
    # replay sampling draws from torch's global generator, seeded with config.seed by the run
    return TD3BCLearner(actor, config.algorithm, demos=demos)


def _run_identity(config: FinetuneConfig) -> dict:
    """What a resumed run must share with the run that wrote ``last.ckpt``.

    The frames of the stages are left out: a run may be resumed with a larger budget.
    """
    variants = plain_mapping(config.collection.env_variants)
    return {
        "checkpoint": str(config.checkpoint),
        "algorithm": asdict(config.algorithm),
        "curriculum": [dict(s.conditions) for s in config.curriculum.stages],
        "reward_weights": dict(config.reward_weights),
        **({"env_variants": variants} if variants else {}),  # runs before them had none
    }


def _batch_stats(batch: TensorDictBase) -> dict[str, float]:
    """Episodes that ended in ``batch``, their success rate, the mean step reward."""
    done = batch["next", "done"].reshape(-1)
    stats = {
        "reward_mean": float(batch["next", "reward"].mean()),
        "episodes_ended": float(done.sum()),
    }
    if done.any() and ("next", "success") in batch.keys(True):
        stats["train_success_rate"] = float(batch["next", "success"].reshape(-1)[done].mean())
    return stats


class _Run:
    """The state of one fine-tuning run and the steps that change it."""

    def __init__(self, config: FinetuneConfig, run_dir: Path, *, progress: bool) -> None:
        self.config = config
        self.run_dir = run_dir
        self.progress = progress
        self.env_kwargs = config.env.make_kwargs()
        self.env_kwargs.pop("condition")
        self.actor = load_cloned_actor(config.checkpoint)
        self.policy = actor_policy(self.actor)
        torch.manual_seed(config.seed)
        demos = EpisodeStore.open(config.demos).to_tensordict() if uses_demos(config) else None
        self.learner = make_learner(config, self.actor, demos)
        # what is evaluated and saved: the residual actor of a residual learner, else the
        # cloned actor being fine-tuned
        self.evaluated = getattr(self.learner, "deterministic_actor", self.policy)
        self.state: dict = {
            "identity": _run_identity(config),
            "frames": 0,
            "batches": 0,
            "scoops": 0,
            "failed_scoops": 0,
            "tipped_scoops": 0,
            "evaluation_episodes": 0,
            "last_eval_frames": -1,
            "last_checkpoint_frames": 0,
            "best_score": None,
            "before": None,
            "before_conditions": None,
            "evaluations": [],
            "collection_s": 0.0,
            "update_s": 0.0,
            "evaluation_s": 0.0,
            "wall_s": 0.0,
        }
        if config.evaluation.cross_check_env:
            self.state[CROSS_CHECK_BEFORE] = None  # the cloned actor there (cross_check_before)
        self.logger = make_logger(config.logger.backend, run_dir, experiment_name=LOG_NAME)
        # the time budget: a deadline for the whole invocation, final evaluations included
        self.deadline: float | None = None
        self.final_eval_s = 0.0  # measured: one evaluation with final_episodes
        self.periodic_eval_s = 0.0  # measured: the last periodic evaluation
        # (frames, groups, per condition) of the last periodic evaluation in this
        # invocation, and (groups, per condition) of the one that saved best.pt: the final
        # evaluations reuse them when they run on the same starts
        self.last_periodic: tuple | None = None
        self.best_periodic: tuple | None = None

    # ------------------------------------------------------------------ persistence
    def resume(self) -> bool:
        """Continue from ``last.ckpt`` if there is one (refusing another run's file)."""
        path = self.run_dir / RUN_CHECKPOINT
        remove_partial_writes(self.run_dir, RUN_FILES)
        if not path.exists():
            _trim_scalar_logs(self.run_dir / LOG_NAME, after_frames=None)
            return False
        progress, learner_state, rng_state = load_run(path)
        # a cross-check may be added to, changed in or dropped from a resumed run: the
        # cloned actor's is kept only where it was made with the options asked for now
        saved_cross_check = progress.pop(CROSS_CHECK_BEFORE, None)
        if CROSS_CHECK_BEFORE in self.state:
            wanted = plain_mapping(self.config.evaluation.cross_check_env)
            same = saved_cross_check is not None and saved_cross_check.get("env") == wanted
            progress[CROSS_CHECK_BEFORE] = saved_cross_check if same else None
        progress = _checked_progress(path, progress, self.state)
        identity = self.state["identity"]
        if progress["identity"] != identity:
            raise CheckpointError(
                f"{path}: was written by a run with {progress['identity']}, not "
                f"{identity}; use a new run directory"
            )
        self.state = progress
        self.learner.load_state_dict(learner_state, path=path)
        set_global_rng_state(path, rng_state)
        _trim_scalar_logs(self.run_dir / LOG_NAME, after_frames=self.state["frames"])
        log.info("resuming %s at %d frames", path, self.state["frames"])
        return True

    def save(self) -> None:
        self.state["last_checkpoint_frames"] = self.state["frames"]
        save_run(
            self.run_dir / RUN_CHECKPOINT,
            progress=self.state,
            learner_state=self.learner.state_dict(),
        )

    # ------------------------------------------------------------------ evaluation
    def _evaluate(
        self, actor, *, episodes: int, seed: int, env_kwargs: dict | None = None
    ) -> tuple[dict, dict, list[dict], EvaluationPlan]:
        """(success per group, success per condition, episode records, plan) of an actor
        (in memory, or a saved one's path), on the training simulator's options or on
        ``env_kwargs``."""
        evaluation = self.config.evaluation
        started = time.perf_counter()
        pooled, records, plan = evaluate_groups(
            controller_for(actor),
            evaluation.groups,
            simulator=self.config.env.simulator,
            env_kwargs=self.env_kwargs if env_kwargs is None else env_kwargs,
            episodes=episodes,
            seed=seed,
            workers=evaluation.workers,
            confidence=evaluation.confidence,
        )
        self.state["evaluation_s"] += time.perf_counter() - started
        self.state["evaluation_episodes"] += len(records)
        conditions = dict.fromkeys(r["condition"] for r in records)
        per_condition = pool_groups(
            records,
            {c: [c] for c in conditions},
            confidence=evaluation.confidence,
            simulator=self.config.env.simulator,
        )
        return pooled, per_condition, records, plan

    def _same_starts(self) -> bool:
        """Whether periodic and final evaluations run the same episodes (same seed and
        count): then an evaluation of the same weights is not run twice."""
        evaluation = self.config.evaluation
        return (
            evaluation.seed == evaluation.final_seed
            and evaluation.episodes == evaluation.final_episodes
        )

    def evaluate_before(self) -> None:
        if self.state["before"] is None:
            evaluation = self.config.evaluation
            started = time.perf_counter()
            self.state["before"], self.state["before_conditions"], *_ = self._evaluate(
                self.config.checkpoint,
                episodes=evaluation.final_episodes,
                seed=evaluation.final_seed,
            )
            self.final_eval_s = time.perf_counter() - started
            log.info("before: %s", _rates(self.state["before"]))

    def evaluate_now(self) -> None:
        """Periodic evaluation of the current actor; keeps ``best.pt``."""
        evaluation = self.config.evaluation
        started = time.perf_counter()
        if self.state["frames"] == 0 and self._same_starts() and not evaluation.video:
            # the untrained actor is the clone just evaluated on these very starts
            groups, per_condition = self.state["before"], self.state["before_conditions"]
            records = plan = None
        else:
            groups, per_condition, records, plan = self._evaluate(
                self.evaluated, episodes=evaluation.episodes, seed=evaluation.seed
            )
            self.periodic_eval_s = time.perf_counter() - started
        if not self.final_eval_s and evaluation.episodes:  # resumed: scale the periodic one
            self.final_eval_s = (
                self.periodic_eval_s * evaluation.final_episodes / evaluation.episodes
            )
        frames, state = self.state["frames"], self.state
        self.state["evaluations"].append(
            {
                "frames": frames,
                "scoops": state["scoops"],
                "failed_scoops": state["failed_scoops"],
                "tipped_scoops": state["tipped_scoops"],
                "groups": groups,
            }
        )
        self.state["last_eval_frames"] = frames
        score = sum(g["success_rate"] for g in groups.values()) / len(groups)
        best = self.state["best_score"] is None or score > self.state["best_score"]
        if best:
            self.state["best_score"] = score
            save_any_actor(self.run_dir / BEST_ACTOR, self.evaluated)
        self.last_periodic = (frames, groups, per_condition)
        if best:
            self.best_periodic = (groups, per_condition)
        for group, result in groups.items():
            self._log(f"eval_{group}_success_rate", result["success_rate"])
        if evaluation.video:
            self._record_videos(frames, records, plan)
        self._write_curve()
        log.info("frames %d: %s", frames, _rates(groups))

    def _record_videos(self, frames: int, records: list[dict], plan: EvaluationPlan) -> None:
        """Episode 0 of each group's filmed condition, as just evaluated, to an mp4."""
        evaluation = self.config.evaluation
        actor = controller_for(self.evaluated)
        for group, conditions in evaluation.groups.items():
            condition = evaluation.video_conditions.get(group, conditions[0])
            record = next(r for r in records if r["condition"] == condition)
            render_rollout(
                actor,
                plan,
                record,
                self.run_dir / "videos" / f"{frames:09d}_{group}_{condition}.mp4",
                render_size=VIDEO_SIZE,
            )

    def _write_curve(self) -> None:
        boundaries, total = [], 0
        for stage in self.config.curriculum.stages[:-1]:
            total += stage.frames
            boundaries.append(total)
        plot_success_curve(
            self.state["evaluations"],
            self.run_dir / CURVE_FILE,
            title=f"{self.policy.config.controller} + {self.config.algorithm.name}",
            stage_frames=boundaries,
            confidence=self.config.evaluation.confidence,
        )
        write_text_atomic(
            self.run_dir / EVALUATIONS_FILE, json.dumps(self.state["evaluations"], indent=1)
        )

    # ------------------------------------------------------------------ training
    def _log(self, name: str, value: float) -> None:
        if self.logger is not None:
            self.logger.log_scalar(name, value, step=self.state["frames"])

    def start_clock(self) -> None:
        """Start the time budget: this invocation may take ``time_budget_minutes`` in all,
        less what earlier invocations of a resumed run already spent training."""
        budget = self.config.time_budget_minutes
        if budget > 0:
            self.deadline = time.perf_counter() + 60 * budget - self.state["wall_s"]
        if self.state["evaluation_s"] > 0:  # resumed: estimate from the evaluations so far
            evaluation = self.config.evaluation
            conditions = sum(len(c) for c in evaluation.groups.values())
            episodes = conditions * (
                (evaluation.final_episodes if self.state["before"] is not None else 0)
                + evaluation.episodes * len(self.state["evaluations"])
            )
            if episodes:
                per_episode_s = self.state["evaluation_s"] / episodes
                self.final_eval_s = per_episode_s * conditions * evaluation.final_episodes
                self.periodic_eval_s = per_episode_s * conditions * evaluation.episodes

    def reserve_s(self) -> float:
        """Time to keep for what follows training: the last periodic evaluation and the
        final evaluations of ``final.pt`` and ``best.pt`` (and the cross-check's two), as
        long as they took so far."""
        periodic = _periodic(self.config)
        cross_check = self.state.get(CROSS_CHECK_BEFORE)  # best.pt's takes about as long
        cross_check_s = cross_check["seconds"] if cross_check else 0.0
        finals = 2 if periodic else 1
        return finals * self.final_eval_s + periodic * self.periodic_eval_s + cross_check_s

    def _out_of_time(self) -> bool:
        """Whether training must stop to leave time for the evaluations that follow."""
        return self.deadline is not None and time.perf_counter() + self.reserve_s() >= (
            self.deadline
        )

    def _stage_collector(self, conditions: dict[str, float], stage_end: int):
        """A collector for the rest of a curriculum stage; building it draws nothing from
        torch's global generator (``_start_segment`` seeds it)."""
        config = self.config
        factory = TrainingEnvFactory(
            config.env.simulator,
            self.env_kwargs,
            conditions,
            config.reward_weights,
            num_envs=config.collection.envs_per_worker,
            variants=variant_kwargs(config),
        )
        with torch.random.fork_rng(devices=[]):
            return make_collector(
                factory,
                self.learner.collection_policy,
                frames_per_batch=config.algorithm.frames_per_batch,
                total_frames=stage_end - self.state["frames"],
                backend=config.collection.backend,
                workers=config.collection.workers,
                seed=self._segment_seed(),
                ray_init_kwargs=dict(config.collection.ray_init_kwargs),
            )

    def _segment_seed(self) -> int:
        return self.config.seed * SEGMENT_SEED_STRIDE + self.state["batches"]

    def _start_segment(self, collector) -> None:
        """Restart the simulators from the segment's seed (as a resumed run starts)."""
        with torch.random.fork_rng(devices=[]):
            restart_collection(collector, self._segment_seed())

    def _learn(self, batch: TensorDictBase, collector) -> None:
        """One update on a collected batch, then the bookkeeping it makes due."""
        config, state = self.config, self.state
        warmup = state["batches"] < config.algorithm.critic_warmup_batches
        started = time.perf_counter()
        scoops = count_scoops(batch)
        metrics = self.learner.update(batch, warmup=warmup)
        sync_weights(collector)
        state["update_s"] += time.perf_counter() - started
        state["frames"] += batch.numel()
        state["batches"] += 1
        state["scoops"] += scoops.scoops
        state["failed_scoops"] += scoops.failed
        state["tipped_scoops"] += scoops.tipped
        counts = {name: float(state[name]) for name in SCOOP_FIELDS}
        for name, value in {**metrics, **_batch_stats(batch), **counts}.items():
            self._log(name, value)
        every = config.evaluation.every_frames
        if (every and state["frames"] - state["last_eval_frames"] >= every) or (
            self._scoop_milestone_passed()
        ):
            self.evaluate_now()

    def _scoop_milestone_passed(self) -> bool:
        """Whether a scoop count of ``evaluation.at_scoops`` was passed since the last
        evaluation."""
        evaluations = self.state["evaluations"]
        last = evaluations[-1].get("scoops", 0) if evaluations else -1
        return any(last < m <= self.state["scoops"] for m in self.config.evaluation.at_scoops)

    def _scoop_budget_spent(self) -> bool:
        budget = self.config.max_scoops
        return bool(budget) and self.state["scoops"] >= budget

    def _pending_stages(self) -> list[tuple[dict[str, float], int, list[int]]]:
        """(conditions, stage end, segment ends still ahead) of the rest of the
        curriculum: each stage is cut every ``checkpoint_every_frames`` from its start."""
        pending, stage_start, every = [], 0, self.config.checkpoint_every_frames
        for stage in self.config.curriculum.stages:
            stage_end = stage_start + stage.frames
            ends = range(stage_start + every, stage_end, every)
            ahead = [end for end in [*ends, stage_end] if end > self.state["frames"]]
            if ahead:
                pending.append((stage.conditions, stage_end, ahead))
            stage_start = stage_end
        return pending

    def train(self) -> bool:
        """Run the remaining curriculum; ``False`` if the time budget cut it short.

        Segment by segment: restart the simulators from the segment's seed, collect and
        learn up to its end, write ``last.ckpt`` (the last segment's after the final
        evaluation). A resumed run starts at a segment start like this one did.
        """
        config, state = self.config, self.state
        started, wall_before = time.perf_counter(), state["wall_s"]
        total_frames = sum(stage.frames for stage in config.curriculum.stages)
        budgeted = self.deadline is not None  # then the bar counts the budget's seconds
        if budgeted and self.deadline - self.reserve_s() - started < 0.2 * 60 * (
            config.time_budget_minutes
        ):
            log.warning(
                "time_budget_minutes=%g: the evaluations take about %.0f s of it, leaving "
                "%.0f s to train; raise the budget or lower evaluation.episodes / "
                "evaluation.final_episodes",
                config.time_budget_minutes,
                started - (self.deadline - 60 * config.time_budget_minutes) + self.reserve_s(),
                max(0.0, self.deadline - self.reserve_s() - started),
            )
        bar = tqdm(
            total=max(1, round(self.deadline - self.reserve_s() - started))
            if budgeted
            else total_frames,
            initial=0 if budgeted else state["frames"],
            desc=f"fine-tuning ({config.algorithm.name}, time budget)"
            if budgeted
            else f"fine-tuning ({config.algorithm.name})",
            unit="s" if budgeted else "frame",
            disable=not self.progress,
        )
        in_time = True
        pending = self._pending_stages()
        for stage_index, (conditions, stage_end, segment_ends) in enumerate(pending):
            if self._scoop_budget_spent():
                break
            collector = self._stage_collector(conditions, stage_end)
            try:
                self._start_segment(collector)
                tick = time.perf_counter()
                for batch in collector:
                    state["collection_s"] += time.perf_counter() - tick
                    self._learn(batch, collector)
                    state["wall_s"] = wall_before + time.perf_counter() - started
                    if budgeted:
                        bar.n = min(bar.total, round(time.perf_counter() - started))
                        bar.set_postfix(frames=state["frames"], refresh=False)
                        bar.refresh()
                    else:
                        bar.update(batch.numel())
                    in_time = not self._out_of_time()
                    if not in_time or self._scoop_budget_spent():
                        break
                    if segment_ends and state["frames"] >= segment_ends[0]:  # a segment ends
                        while segment_ends and segment_ends[0] <= state["frames"]:
                            segment_ends.pop(0)
                        last = not segment_ends and stage_index == len(pending) - 1
                        if not last:  # the last is saved after the final evaluation
                            self.save()
                        if segment_ends:
                            self._start_segment(collector)
                    tick = time.perf_counter()
            finally:
                collector.shutdown()
            if not in_time:
                break
        bar.close()
        state["wall_s"] = wall_before + time.perf_counter() - started
        if _periodic(config) and state["last_eval_frames"] != state["frames"]:
            self.evaluate_now()
        self.save()
        return in_time

    # ------------------------------------------------------------------ results
    def results(self, finished: bool) -> dict:
        evaluation = self.config.evaluation
        save_any_actor(self.run_dir / FINAL_ACTOR, self.evaluated)
        last = self.last_periodic
        reuse = self._same_starts() and last is not None and last[0] == self.state["frames"]
        if reuse:
            after_final, final_conditions = last[1], last[2]  # these weights, these starts
        else:
            after_final, final_conditions, *_ = self._evaluate(
                self.evaluated, episodes=evaluation.final_episodes, seed=evaluation.final_seed
            )
        if _periodic(self.config) and self._same_starts() and self.best_periodic is not None:
            after_best, best_conditions = self.best_periodic  # best.pt, evaluated there
        elif _periodic(self.config):
            after_best, best_conditions, *_ = self._evaluate(
                self.run_dir / BEST_ACTOR,
                episodes=evaluation.final_episodes,
                seed=evaluation.final_seed,
            )
        else:  # no periodic evaluation to choose by: the last actor is the best one known
            save_any_actor(self.run_dir / BEST_ACTOR, self.evaluated)
            after_best, best_conditions = after_final, final_conditions
        cross_check = self.cross_check(after_best) if evaluation.cross_check_env else None
        state = self.state
        metrics = {
            "controller": self.policy.config.controller,
            "algorithm": self.config.algorithm.name,
            "checkpoint": str(self.config.checkpoint),
            "finished_curriculum": finished,
            "frames": state["frames"],
            "batches": state["batches"],
            **{name: state[name] for name in SCOOP_FIELDS},
            "evaluation_episodes": state["evaluation_episodes"],
            "wall_s": state["wall_s"],
            "collection_s": state["collection_s"],
            "update_s": state["update_s"],
            "evaluation_s": state["evaluation_s"],
            "collection_fps": state["frames"] / state["collection_s"]
            if state["collection_s"]
            else None,
            "before": state["before"],
            "after_best": after_best,
            "after_final": after_final,
            "best_periodic_score": state["best_score"],
            "conditions": {
                "before": state["before_conditions"],
                "after_best": best_conditions,
                "after_final": final_conditions,
            },
        }
        if cross_check is not None:
            metrics["cross_check"] = cross_check
        write_text_atomic(self.run_dir / RESULTS_FILE, json.dumps(metrics, indent=1))
        log.info("after (best.pt): %s", _rates(after_best))
        return metrics

    def evaluate_cross_check_before(self) -> None:
        """The cloned actor on ``evaluation.cross_check_env``'s options (same episodes and
        starts as the final evaluation), once, before training: it does not depend on
        training, and its time is what the time budget keeps for ``best.pt``'s."""
        if CROSS_CHECK_BEFORE not in self.state or self.state[CROSS_CHECK_BEFORE] is not None:
            return
        evaluation = self.config.evaluation
        started = time.perf_counter()
        groups, per_condition, *_ = self._evaluate(
            self.config.checkpoint,
            episodes=evaluation.final_episodes,
            seed=evaluation.final_seed,
            env_kwargs=cross_check_kwargs(self.config),
        )
        self.state[CROSS_CHECK_BEFORE] = {
            "env": plain_mapping(evaluation.cross_check_env),
            "groups": groups,
            "conditions": per_condition,
            "seconds": time.perf_counter() - started,
        }
        log.info("before, cross-check: %s", _rates(groups))

    def cross_check(self, after_best: dict) -> dict:
        """``best.pt`` on ``evaluation.cross_check_env``'s options beside the cloned actor's
        (``evaluate_cross_check_before``); logs each group's change of success and fill on
        both and warns where a success gain does not carry over."""
        evaluation = self.config.evaluation
        self.evaluate_cross_check_before()  # made before training (here if it was not)
        before = self.state[CROSS_CHECK_BEFORE]
        after, after_conditions, *_ = self._evaluate(
            self.run_dir / BEST_ACTOR,
            episodes=evaluation.final_episodes,
            seed=evaluation.final_seed,
            env_kwargs=cross_check_kwargs(self.config),
        )
        for group in after:
            old, new = self.state["before"][group], after_best[group]
            old_there, new_there = before["groups"][group], after[group]
            here = new["success_rate"] - old["success_rate"]
            there = new_there["success_rate"] - old_there["success_rate"]
            text = (
                f"cross-check {group}: fine-tuning changed success by {here:+.0%} (fill "
                f"{old['fill_mean']:.2f} -> {new['fill_mean']:.2f}) here and by {there:+.0%} "
                f"(fill {old_there['fill_mean']:.2f} -> {new_there['fill_mean']:.2f}) with "
                f"{before['env']}"
            )
            if here > 0 and there < here / 2:
                log.warning("%s: the success gain does not carry over (docs/finetuning.md)", text)
            else:
                log.info(text)
        return {
            "env": before["env"],
            "before": before["groups"],
            "after_best": after,
            "conditions": {"before": before["conditions"], "after_best": after_conditions},
        }


def _periodic(config: FinetuneConfig) -> bool:
    """Whether the run evaluates during training (every some frames or at scoop counts)."""
    return bool(config.evaluation.every_frames or config.evaluation.at_scoops)


def _checked_progress(path: Path, saved: dict, fresh: dict) -> dict:
    """``saved`` progress if it has the fields of ``fresh`` with sane values."""
    if set(saved) != set(fresh):
        raise CheckpointError(
            f"{path}: progress has fields {sorted(saved)}, expected {sorted(fresh)}"
        )
    for name in ("frames", "batches", "last_checkpoint_frames", "last_eval_frames", *SCOOP_FIELDS):
        value = saved[name]
        if not isinstance(value, int) or isinstance(value, bool) or value < -1:
            raise CheckpointError(f"{path}: progress.{name} is {value!r}, not a count")
    for name in ("collection_s", "update_s", "evaluation_s", "wall_s"):
        if not isinstance(saved[name], int | float) or saved[name] < 0:
            raise CheckpointError(f"{path}: progress.{name} is {saved[name]!r}")
    if not isinstance(saved["evaluations"], list):
        raise CheckpointError(f"{path}: progress.evaluations is not a list")
    return saved


def _trim_scalar_logs(log_dir: Path, *, after_frames: int | None) -> None:
    """Drop the CSV log rows a killed run wrote after its last checkpoint (all of them
    when there is none), so the resumed run does not log those frames twice."""
    scalars = log_dir / "scalars"
    if not scalars.is_dir():
        return
    for leftover in scalars.glob(".*.csv"):  # a kill during an earlier trim
        leftover.unlink(missing_ok=True)
    for csv in sorted(scalars.glob("*.csv")):
        lines = csv.read_text().splitlines(keepends=True)
        kept = [
            line
            for line in lines
            if after_frames is not None
            and _row_step(line) is not None
            and _row_step(line) <= after_frames
        ]
        if kept != lines:
            write_text_atomic(csv, "".join(kept))


def _row_step(line: str) -> int | None:
    """The step of a TorchRL CSV row ``step,value`` (``None`` for a torn last line)."""
    step, _, value = line.partition(",")
    if not line.endswith("\n") or not value.strip():
        return None
    try:
        return int(step)
    except ValueError:
        return None


def _rates(groups: dict) -> str:
    return ", ".join(
        f"{g} {r['successes']}/{r['episodes']} [{r['success_low']:.2f}, {r['success_high']:.2f}]"
        for g, r in groups.items()
    )


def flat_metrics(results: dict) -> dict[str, float]:
    """The numbers of ``results`` as one flat mapping (for ``pilerl.sweeps.mark_done``)."""
    flat = {
        key: float(results[key])
        for key in (
            "frames",
            "batches",
            *SCOOP_FIELDS,
            "wall_s",
            "collection_s",
            "update_s",
            "evaluation_s",
        )
    }
    if results["collection_fps"] is not None:
        flat["collection_fps"] = float(results["collection_fps"])
    for when in ("before", "after_best", "after_final"):
        for group, result in results[when].items():
            for name in ("success_rate", "success_low", "success_high"):
                flat[f"{when}_{group}_{name}"] = float(result[name])
    cross_check = results.get("cross_check")
    for when in ("before", "after_best") if cross_check else ():
        for group, result in cross_check[when].items():
            for name in ("success_rate", "success_low", "success_high"):
                flat[f"cross_check_{when}_{group}_{name}"] = float(result[name])
    return flat


def finetune(config: FinetuneConfig, run_dir: str | Path, *, progress: bool = True) -> dict:
    """Fine-tune ``config.checkpoint`` by RL; returns ``results.json``'s content.

    Running again with the same ``run_dir`` resumes from ``last.ckpt``.
    """
    config.check_inputs()  # its settings were checked when it was built
    config = resolve_simulator_words(config)  # groups, mixtures and reward parts by name
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    run = _Run(config, run_dir, progress=progress)
    run.resume()
    run.start_clock()  # the budget covers the evaluations before and after training too
    run.evaluate_before()
    run.evaluate_cross_check_before()
    if _periodic(config) and not run.state["evaluations"]:
        run.evaluate_now()  # the cloned actor: the curve's first point and best.pt so far
        run.save()
    finished = run.train()
    return run.results(finished)
