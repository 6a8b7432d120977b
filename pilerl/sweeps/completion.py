"""Job completion markers: a re-run sweep skips the jobs that already finished.

Hydra cannot resume a sweep. pilerl's recipes write their scalar results to
``metrics.json`` and then a ``done.json`` marker into their run directory when they
finish; a recipe that finds the marker logs that it skips and returns. Give the sweep a
fixed directory (``hydra.sweep.dir=multirun/my_sweep``) so that a re-run of the same sweep
lands in the same job directories.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

from pilerl.io import write_text_atomic
from pilerl.layout import RunLayout

METRICS_FILE = RunLayout.METRICS
DONE_FILE = RunLayout.DONE


def is_done(run_dir: str | Path) -> bool:
    """Whether the job in ``run_dir`` finished before."""
    return (Path(run_dir) / DONE_FILE).exists()


def mark_done(run_dir: str | Path, metrics: dict[str, float | int | bool]) -> None:
    """Write ``metrics.json`` (flat scalars) and then the ``done.json`` marker, atomically."""
    run_dir = Path(run_dir)
    bad = {
        k: v
        for k, v in metrics.items()
        if not isinstance(v, bool | int | float) or (isinstance(v, float) and math.isnan(v))
    }
    if bad:
        raise ValueError(f"mark_done({run_dir}): metrics must be finite scalars, got {bad}")
    write_text_atomic(run_dir / METRICS_FILE, json.dumps(metrics, indent=1, allow_nan=False))
    write_text_atomic(run_dir / DONE_FILE, json.dumps({"finished_at": time.time()}))
