"""The main job end to end on a tiny budget, and its refusal of bad settings."""

from __future__ import annotations

import json

from test_recipes import run_recipe

TINY = [
    "demos.episodes=3",
    "demos.validation_episodes=1",
    "demos.workers=1",
    "bc.gradient_steps=20",
    "evaluation.episodes=1",
    "evaluation.conditions=[summer,winter_c]",
    "evaluation.workers=1",
    "evaluation.video_conditions=[winter_c]",
    "evaluation.render_width=96",
    "evaluation.render_height=64",
    "finetune.time_budget_minutes=0.05",
    "finetune.algorithm.frames_per_batch=256",
    "finetune.algorithm.minibatch_size=128",
    "finetune.collection.envs_per_worker=2",
    "finetune.evaluation.every_frames=0",
    "finetune.evaluation.final_episodes=1",
    "finetune.evaluation.workers=1",
]


def test_pipeline_runs_demos_bc_evaluation_rl_and_reports(tmp_path):
    result = run_recipe("pipeline.py", f"hydra.run.dir={tmp_path}", *TINY)
    assert result.returncode == 0, result.stderr[-3000:]
    for path in (
        "demos/summer/index.json",
        "datasets/d_ii/index.json",
        "bc/best.pt",
        "bc/losses.png",
        "evaluation/cloned/summary.json",
        "finetune/best.pt",
        "finetune/results.json",
        "evaluation/finetuned/success.png",
        "fig3_control_signals.png",
        "fig5_attention_cloned.png",
        "report.html",
    ):
        assert (tmp_path / path).stat().st_size > 0, path
    videos = [p.name for p in (tmp_path / "evaluation" / "finetuned" / "videos").glob("*.mp4")]
    assert videos and all(v.startswith("winter_c") for v in videos)
    before = json.loads((tmp_path / "evaluation" / "cloned" / "summary.json").read_text())
    assert set(before) == {"summer", "winter_c"} and before["summer"]["episodes"] == 1
    report = (tmp_path / "report.md").read_text()
    for heading in ("## Demonstrations", "## Closed loop", "## RL fine-tuning", "(Fig. 5)"):
        assert heading in report
    assert "The paper reports 100% winter success for dannet" not in report  # no pooled winter
    # the fine-tune's before / after again on the heightfield's mouth intake (conf/pipeline.yaml)
    results = json.loads((tmp_path / "finetune" / "results.json").read_text())
    assert results["cross_check"]["env"]["soil_options"] == {
        "intake": "mouth",
        "body_resistance": True,
    }
    assert "Does the gain carry over?" in report and "fine-tuned, cross-check" in report
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert set(metrics) >= {"cloned_summer_success_rate", "finetuned_winter_c_success_rate"}


def test_pipeline_refuses_a_controller_rl_cannot_train_before_any_work(tmp_path):
    result = run_recipe("pipeline.py", f"hydra.run.dir={tmp_path}", "policy=rf", *TINY)
    assert result.returncode != 0 and "'rf' cannot be fine-tuned" in result.stderr
    assert not (tmp_path / "demos").exists()
    result = run_recipe(
        "pipeline.py", f"hydra.run.dir={tmp_path / 'b'}", "finetune.algorithm.clip_epsilon=-1"
    )
    assert result.returncode != 0 and "clip_epsilon" in result.stderr
    assert not (tmp_path / "b" / "demos").exists()
