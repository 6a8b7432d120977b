"""The shared recipe prologue (``pilerl.recipe``) and the run layout, in process."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import pytest

from pilerl.layout import RunLayout

ROOT = Path(__file__).resolve().parents[2]
MAX_RECIPE_LINES = 120

RECIPE = """
from dataclasses import dataclass

from pilerl.recipe import recipe


@dataclass
class Config:
    output_dir: str
    steps: int = 2
    workers: int = 1

    def __post_init__(self):
        if self.steps < 1:
            raise ValueError(f"steps: must be >= 1, got {self.steps}")


CALLS = []


@recipe("tiny", schema=Config, objective="score", usage_errors=(ValueError,))
def main(config, run):
    CALLS.append(config)
    run.begin(inputs={})
    (run.dir / "work.txt").write_text(str(config.steps))
    return {"score": 0.5 * config.steps, "steps": config.steps}


if __name__ == "__main__":
    main()
"""


@pytest.fixture
def tiny_recipe(tmp_path):
    """A recipe file and its conf/ (``tiny.yaml``), as a project lays them out."""
    (tmp_path / "recipes").mkdir()
    (tmp_path / "conf").mkdir()
    (tmp_path / "recipes" / "tiny.py").write_text(RECIPE)
    (tmp_path / "conf" / "tiny.yaml").write_text("steps: 2\nworkers: 1\noutput_dir: ???\n")
    return tmp_path / "recipes" / "tiny.py"


def run_tiny(recipe: Path, *overrides: str) -> dict:
    old = sys.argv
    sys.argv = [str(recipe), *overrides]
    try:
        return runpy.run_path(str(recipe), run_name="__main__")
    finally:
        sys.argv = old


def test_a_recipe_writes_its_metrics_then_skips_when_finished(tiny_recipe, tmp_path):
    run_dir = tmp_path / "run"
    first = run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}")
    assert len(first["CALLS"]) == 1 and first["CALLS"][0].steps == 2  # the dataclass
    layout = RunLayout(run_dir)
    assert json.loads(layout.metrics.read_text()) == {"score": 1.0, "steps": 2}
    assert layout.done.exists() and layout.run_record.exists()
    (run_dir / "work.txt").unlink()
    again = run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}", "workers=2")
    assert len(again["CALLS"]) == 1  # it began, found the run finished and stopped
    assert not (run_dir / "work.txt").exists()  # workers change no result: not run again


def test_a_recipe_refuses_a_directory_of_other_settings(tiny_recipe, tmp_path, capsys):
    run_dir = tmp_path / "run"
    run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}")
    with pytest.raises(SystemExit) as exit_:  # Hydra prints the error and exits 1
        run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}", "steps=3")
    assert exit_.value.code == 1
    assert "RunMismatch" in capsys.readouterr().err
    assert json.loads(RunLayout(run_dir).metrics.read_text())["steps"] == 2  # kept


def test_usage_errors_exit_2_before_anything_is_written(tiny_recipe, tmp_path, capsys):
    run_dir = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_:
        run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}", "steps=0")
    assert exit_.value.code == 2
    assert "steps: must be >= 1, got 0" in capsys.readouterr().out  # Hydra logs to stdout
    assert not RunLayout(run_dir).run_record.exists()


def test_metrics_without_a_recorded_run_are_refused(tiny_recipe, tmp_path, capsys):
    tiny_recipe.write_text(tiny_recipe.read_text().replace("    run.begin(inputs={})\n", ""))
    run_dir = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_:
        run_tiny(tiny_recipe, f"hydra.run.dir={run_dir}", f"output_dir={run_dir}")
    assert exit_.value.code == 1
    assert "returned metrics without run.begin()" in capsys.readouterr().err
    assert not RunLayout(run_dir).done.exists()


def test_run_layout_names_the_files_of_a_run_and_its_stages(tmp_path):
    layout = RunLayout(str(tmp_path))
    assert layout.run_record == tmp_path / "run.json"
    assert layout.sub("bc").best_actor == tmp_path / "bc" / "best.pt"
    assert layout.sub("finetune").rl_state == tmp_path / "finetune" / "last.ckpt"
    assert layout.sub("evaluation", "cloned").summary.parent.name == "cloned"


@pytest.mark.parametrize("recipe", sorted((ROOT / "recipes").glob("*.py")), ids=lambda p: p.name)
def test_every_recipe_is_thin(recipe):
    lines = len(recipe.read_text().splitlines())
    assert lines <= MAX_RECIPE_LINES, f"{recipe.name}: {lines} lines; move the work into pilerl/"
    assert "@recipe(" in recipe.read_text(), f"{recipe.name}: not a @recipe"
