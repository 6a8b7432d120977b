"""The files of a run directory, named once.

Every recipe writes into one run directory (Hydra's output directory); the pipeline's
stages each write into a subdirectory of its own (``bc/``, ``finetune/``...). A
:class:`RunLayout` names those files by what they hold, so the code that writes them
(``pilerl.runs``, the stages), the code that reads them (reports, sweep summaries,
``resolve_checkpoint``) and the tests agree on one spelling:

| attribute | file | written by |
|---|---|---|
| ``run_record`` | ``run.json`` | ``begin_run``: settings, input fingerprints, provenance |
| ``metrics`` | ``metrics.json`` | ``finish_run``: the run's scalar results |
| ``done`` | ``done.json`` | ``finish_run``: the completion marker (after ``metrics``) |
| ``best_actor`` | ``best.pt`` | BC and fine-tuning: the actor to evaluate or deploy |
| ``final_actor`` | ``final.pt`` | BC and fine-tuning: the actor at the end of the budget |
| ``bc_state`` | ``last.pt`` | behaviour cloning: the resumable training state |
| ``rl_state`` | ``last.ckpt`` | fine-tuning: the resumable run (``pilerl.rl.run_checkpoint``) |
| ``losses_plot`` | ``losses.png`` | behaviour cloning: the loss curves |
| ``summary`` | ``summary.json`` | closed-loop evaluation: success with intervals per condition |
| ``results`` | ``results.json`` | fine-tuning: before / after with intervals |
| ``evaluations`` | ``evaluations.json`` | fine-tuning: the periodic evaluations |
| ``report`` / ``report_html`` | ``report.md`` / ``report.html`` | the pipeline's report |

This module imports nothing of pilerl, so every floor may use it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar


@dataclass(frozen=True)
class RunLayout:
    """The files of the run directory ``root`` (see the module docstring)."""

    root: Path

    RUN_RECORD: ClassVar[str] = "run.json"
    METRICS: ClassVar[str] = "metrics.json"
    DONE: ClassVar[str] = "done.json"
    BEST_ACTOR: ClassVar[str] = "best.pt"
    FINAL_ACTOR: ClassVar[str] = "final.pt"
    BC_STATE: ClassVar[str] = "last.pt"
    RL_STATE: ClassVar[str] = "last.ckpt"
    LOSSES_PLOT: ClassVar[str] = "losses.png"
    SUMMARY: ClassVar[str] = "summary.json"
    RESULTS: ClassVar[str] = "results.json"
    EVALUATIONS: ClassVar[str] = "evaluations.json"
    REPORT: ClassVar[str] = "report.md"
    REPORT_HTML: ClassVar[str] = "report.html"

    def __init__(self, root: str | Path) -> None:
        object.__setattr__(self, "root", Path(root))

    def sub(self, *parts: str) -> RunLayout:
        """The layout of a stage's subdirectory (``layout.sub("evaluation", "cloned")``)."""
        return RunLayout(self.root.joinpath(*parts))

    @property
    def run_record(self) -> Path:
        return self.root / self.RUN_RECORD

    @property
    def metrics(self) -> Path:
        return self.root / self.METRICS

    @property
    def done(self) -> Path:
        return self.root / self.DONE

    @property
    def best_actor(self) -> Path:
        return self.root / self.BEST_ACTOR

    @property
    def final_actor(self) -> Path:
        return self.root / self.FINAL_ACTOR

    @property
    def bc_state(self) -> Path:
        return self.root / self.BC_STATE

    @property
    def rl_state(self) -> Path:
        return self.root / self.RL_STATE

    @property
    def losses_plot(self) -> Path:
        return self.root / self.LOSSES_PLOT

    @property
    def summary(self) -> Path:
        return self.root / self.SUMMARY

    @property
    def results(self) -> Path:
        return self.root / self.RESULTS

    @property
    def evaluations(self) -> Path:
        return self.root / self.EVALUATIONS

    @property
    def report(self) -> Path:
        return self.root / self.REPORT

    @property
    def report_html(self) -> Path:
        return self.root / self.REPORT_HTML
