"""The README's first command (the main job) left a report, plots and videos behind.

CI runs the README's two commands in order, in a plain shell: the main job
(``recipes/pipeline.py`` on its defaults) and then these tests. This test reads the newest
finished main-job run under ``outputs/pipeline/`` of the checkout; on a machine where the
main job has not been run yet it is skipped, saying so.
"""

from __future__ import annotations

import json
from pathlib import Path

import imageio.v3 as iio
import pytest

ROOT = Path(__file__).resolve().parents[2]
RUNS = ROOT / "outputs" / "pipeline"


def newest_finished_run() -> Path | None:
    finished = sorted(p.parent for p in RUNS.glob("*/done.json"))
    return finished[-1] if finished else None


@pytest.fixture(scope="module")
def run_dir() -> Path:
    run = newest_finished_run()
    if run is None:
        pytest.skip(f"no finished main job under {RUNS}: run the README's first command first")
    return run


def test_the_main_job_wrote_its_report_and_plots(run_dir):
    for path in (
        "report.md",
        "report.html",
        "run.json",
        "bc/best.pt",
        "bc/losses.png",
        "evaluation/cloned/success.png",
        "evaluation/cloned/fill.png",
        "evaluation/finetuned/success.png",
        "evaluation/finetuned/fill.png",
        "finetune/success_curve.png",
        "fig3_control_signals.png",
        "fig5_attention_cloned.png",
    ):
        assert (run_dir / path).is_file() and (run_dir / path).stat().st_size > 0, path
    report = (run_dir / "report.md").read_text()
    for heading in ("## Demonstrations", "## Closed loop", "## RL fine-tuning", "## Videos"):
        assert heading in report
    for image in report.split("](")[1:]:  # every linked file exists
        target = image.split(")")[0]
        if not target.startswith("http"):
            assert (run_dir / target).exists(), target
    provenance = json.loads((run_dir / "run.json").read_text())["provenance"]
    assert provenance["packages"]["pilerl"] and "commit" in provenance["git"]


def test_the_main_job_wrote_videos_with_moving_frames(run_dir):
    from pilerl.rendering import rendering_available

    available, why = rendering_available()
    if not available:
        pytest.skip(f"this machine cannot render ({why}): the main job ran without videos")
    videos = sorted((run_dir / "evaluation" / "finetuned" / "videos").glob("*.mp4"))
    assert videos, "no videos: the main job must render in a plain shell"
    frames = list(iio.imiter(videos[0]))
    assert len(frames) > 10
    assert frames[0].std() > 0 and abs(frames[-1].astype(float) - frames[0]).mean() > 0
    assert f"]({videos[0].relative_to(run_dir)})" in (run_dir / "report.md").read_text()
