"""Sweeps: skipping finished jobs on re-runs, and summarising a multirun directory."""

from .completion import DONE_FILE, METRICS_FILE, is_done, mark_done
from .summary import load_jobs, summarize_sweep

__all__ = ["DONE_FILE", "METRICS_FILE", "is_done", "load_jobs", "mark_done", "summarize_sweep"]
