"""The one reader of what Hydra recorded in a job directory's ``.hydra/`` folder.

Hydra writes three files into every run or sweep job directory before the job starts:

- ``config.yaml``: the composed config (what a recipe received),
- ``overrides.yaml``: the command-line overrides of this job (``seed=3``, ``+x=1``),
- ``hydra.yaml``: Hydra's own config; ``hydra.runtime.choices`` names the option chosen
  in every config group (``sensors: s_pt``, ``policy: dannet``), defaults included.

Sweep summaries group jobs by their overrides (``pilerl.sweeps.summary``); the paper's
report reads each job's config and group choices (``pilerl.reports.results``). Both read
them here. Every problem is a ``ValueError`` naming the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

HYDRA_DIR = ".hydra"
CONFIG_FILE = "config.yaml"
OVERRIDES_FILE = "overrides.yaml"
HYDRA_FILE = "hydra.yaml"


def job_directories(sweep_dir: str | Path) -> list[Path]:
    """Every Hydra job directory under ``sweep_dir``: those whose ``.hydra/`` folder holds
    ``config.yaml`` or ``overrides.yaml``, sorted by path.

    Raises ``FileNotFoundError`` when ``sweep_dir`` is not a directory.
    """
    sweep_dir = Path(sweep_dir)
    if not sweep_dir.is_dir():
        raise FileNotFoundError(f"{sweep_dir}: no such sweep directory")
    found = {
        marker.parent.parent
        for name in (CONFIG_FILE, OVERRIDES_FILE)
        for marker in sweep_dir.rglob(f"{HYDRA_DIR}/{name}")
    }
    return sorted(found)


def read_config(job_dir: str | Path) -> dict[str, Any]:
    """The composed config Hydra saved for the job (``.hydra/config.yaml``)."""
    config = _read(job_dir, CONFIG_FILE, "config")
    if not isinstance(config, dict):
        raise ValueError(f"{_file(job_dir, CONFIG_FILE)}: expected a mapping of settings")
    return config


def read_overrides(job_dir: str | Path) -> dict[str, str]:
    """The job's own command-line overrides as ``{key: value}`` (``.hydra/overrides.yaml``).

    Overrides of Hydra itself (``hydra.*``) are left out; the ``+`` / ``++`` / ``~``
    prefixes are dropped from the keys (``+x=1`` -> ``{"x": "1"}``).
    """
    items = _read(job_dir, OVERRIDES_FILE, "overrides") or []
    if not isinstance(items, list):
        raise ValueError(f"{_file(job_dir, OVERRIDES_FILE)}: expected a list of overrides")
    overrides = {}
    for item in items:
        key, _, value = str(item).partition("=")
        if not key.startswith(("hydra.", "+hydra.")):
            overrides[key.lstrip("+~")] = value
    return overrides


def read_choices(job_dir: str | Path) -> dict[str, str]:
    """The option chosen in each config group (``hydra.runtime.choices`` of ``hydra.yaml``),
    e.g. ``{"sensors": "s_pt", "policy": "dannet"}``; Hydra's own groups included."""
    record = _read(job_dir, HYDRA_FILE, "Hydra record")
    try:
        choices = record["hydra"]["runtime"]["choices"]
    except (KeyError, TypeError):
        raise ValueError(f"{_file(job_dir, HYDRA_FILE)}: no hydra.runtime.choices") from None
    return {str(group): str(option) for group, option in choices.items()}


def _file(job_dir: str | Path, name: str) -> Path:
    return Path(job_dir) / HYDRA_DIR / name


def _read(job_dir: str | Path, name: str, what: str) -> Any:
    path = _file(job_dir, name)
    try:
        return yaml.safe_load(path.read_text())
    except OSError as error:
        raise ValueError(f"{path}: cannot read the {what} ({error.strerror})") from None
    except yaml.YAMLError as error:
        raise ValueError(f"{path}: unreadable {what} ({error})") from None
