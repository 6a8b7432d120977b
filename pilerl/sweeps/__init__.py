"""Sweeps: skipping finished jobs on re-runs, and summarising a multirun directory.

``hydra_record`` is the one reader of what Hydra recorded in a job directory (overrides,
group choices, config), for the summary here and for ``pilerl.reports``.

``summarize_sweep`` and ``load_jobs`` are imported on first use, so that
``python -m pilerl.sweeps.summary`` runs its module once (no runpy warning).
"""

from .completion import DONE_FILE, METRICS_FILE, is_done, mark_done

__all__ = ["DONE_FILE", "METRICS_FILE", "is_done", "load_jobs", "mark_done", "summarize_sweep"]


def __getattr__(name: str):
    if name in ("load_jobs", "summarize_sweep"):
        from . import summary

        return getattr(summary, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
