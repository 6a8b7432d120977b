"""What a run directory ran with: a fingerprint of its settings and inputs, and provenance.

Every recipe starts with :func:`begin_run` and ends with :func:`finish_run`. The first
writes ``run.json`` into the run directory: the resolved settings (less the ones that do
not change results, such as worker counts or videos), a fingerprint of each input file or
dataset, and the provenance (package versions, git commit and dirty flag, command line).
Running a recipe again in the same directory then

- skips it when it finished with the same settings and inputs,
- resumes it when it was interrupted with the same settings and inputs (or when only a
  budget that may grow, such as a fine-tune's frame count, changed),
- and refuses when anything else differs, naming the differing keys, so that a finished
  run is never reused under another config and a checkpoint never continues under
  another model or dataset.

Hydra writes ``.hydra/config.yaml`` before a recipe starts; when the recipe refuses, the
files Hydra overwrote are put back from ``run.json``, so the directory still describes
what it holds. Reports and sweep summaries read the settings a job actually ran with
from ``run.json`` (:func:`read_run_settings`).
"""

from __future__ import annotations

import fnmatch
import hashlib
import importlib.metadata
import json
import platform
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pilerl.io import write_text_atomic
from pilerl.layout import RunLayout
from pilerl.sweeps.completion import mark_done

HYDRA_FILES = ("config.yaml", "overrides.yaml", "hydra.yaml")
# settings that change how a run goes, not what it computes (glob patterns on dotted keys)
NOT_RESULTS = (
    "output_dir",
    "*.output_dir",
    "workers",  # record: episodes are seeded one by one, whichever process records them
    "demos.workers",
    "evaluation.workers",  # evaluation: results do not depend on the worker count (tested)
    "*.evaluation.workers",
    "*videos",
    "*video",
    "*video_conditions",
    "*render_width",
    "*render_height",
    "*camera",
    "logger.*",
    "*.progress",
    "draw_ahead",  # train_bc: torch's dropout masks drawn on a second thread, bit-identical
    "draw_packed_ahead",  # train_bc: packed masks drawn on a second thread, bit-identical
)  # collection workers and envs per worker change what RL collects: they stay in
PACKAGES = ("pilerl", "torch", "torchrl", "tensordict", "mujoco", "gymnasium", "hydra-core")
HASH_CHUNK_BYTES = 1 << 20


class RunMismatch(RuntimeError):
    """A run directory holds a run made with other settings or inputs."""


# the provenance of the run this process is doing (set by begin_run): checkpoints written
# during the run carry it (pilerl.policies.save_actor)
_CURRENT_RUN: dict[str, Any] = {}


def current_provenance() -> dict[str, Any]:
    """The provenance of the run in progress, or of this process when no run began."""
    return dict(_CURRENT_RUN) if _CURRENT_RUN else provenance()


# ---------------------------------------------------------------------------- fingerprints
def fingerprint_path(path: str | Path) -> str:
    """SHA-256 of a file, or of a dataset directory's ``index.json`` (its episode list).

    A directory without an index is fingerprinted by its files' names and sizes.
    """
    path = Path(path)
    digest = hashlib.sha256()
    if path.is_file():
        with path.open("rb") as f:
            while chunk := f.read(HASH_CHUNK_BYTES):
                digest.update(chunk)
    elif (path / "index.json").is_file():
        digest.update((path / "index.json").read_bytes())
    elif path.is_dir():
        for file in sorted(p for p in path.rglob("*") if p.is_file()):
            digest.update(f"{file.relative_to(path)}:{file.stat().st_size}\n".encode())
    else:
        raise FileNotFoundError(f"{path}: no such file or directory to fingerprint")
    return digest.hexdigest()


def flatten(settings: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mappings as one mapping of dotted keys; lists of mappings by index
    (``curriculum.stages.0.frames``); other lists and scalars are leaves."""
    flat = {}
    for key, value in settings.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat |= flatten(value, f"{dotted}.")
        elif isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
            for index, item in enumerate(value):
                flat |= flatten(item, f"{dotted}.{index}.")
        else:
            flat[dotted] = value
    return flat


def _matches(key: str, patterns: Iterable[str]) -> bool:
    return any(fnmatch.fnmatchcase(key, pattern) for pattern in patterns)


# ---------------------------------------------------------------------------- provenance
def provenance(**extra: Any) -> dict[str, Any]:
    """Package versions, git commit (and whether the tree was dirty), Python, command line.

    ``extra`` adds run-specific facts (dataset fingerprint, control rate, sensor set).
    """
    versions = {}
    for package in PACKAGES:
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            versions[package] = None
    return {
        "packages": versions,
        "git": git_state(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "command": [Path(sys.argv[0]).name, *sys.argv[1:]],
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        **extra,
    }


def git_state(repo: str | Path | None = None) -> dict[str, Any]:
    """The commit of the pilerl source tree and whether it had uncommitted changes."""
    repo = Path(repo) if repo is not None else Path(__file__).resolve().parent.parent

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(
                ["git", "-C", str(repo), *args], capture_output=True, text=True, timeout=10
            )
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return {"commit": None, "dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit, "dirty": bool(status)}


# ---------------------------------------------------------------------------- begin / finish
def begin_run(
    run_dir: str | Path,
    settings: Mapping[str, Any],
    *,
    inputs: Mapping[str, str | Path | None] | None = None,
    growable: Iterable[str] = (),
    added: Mapping[str, Any] | None = None,
    **facts: Any,
) -> bool:
    """Check ``run_dir`` against ``settings`` and ``inputs``; record them. True: skip it.

    Args:
        run_dir: the run directory (Hydra's output directory).
        settings: the resolved config as plain data (``OmegaConf.to_container``).
        inputs: name -> file or dataset directory the run reads (``None``: not used).
        growable: dotted keys (glob patterns) of budgets that may be raised to continue a
            run (a finished run with a larger budget resumes instead of being skipped).
        added: settings added to the config after runs were recorded without them:
            dotted key -> the value such a run ran with (a record without the key
            matches that value, so a new key does not refuse the runs made before it).
        facts: run-specific provenance (control rate, sensor set ...).

    Raises :class:`RunMismatch` when the directory holds a run with other settings or
    inputs, naming each differing key.
    """
    run_dir = Path(run_dir)
    layout = RunLayout(run_dir)
    growable = tuple(growable)
    flat = {k: v for k, v in flatten(settings).items() if not _matches(k, NOT_RESULTS)}
    input_prints = {
        name: fingerprint_path(path) for name, path in (inputs or {}).items() if path is not None
    }
    recorded = read_run_record(run_dir)
    if recorded is None and layout.done.exists():
        raise RunMismatch(
            f"{run_dir}: finished by an older pilerl that did not record its settings; "
            "its results cannot be matched to this config: choose another run directory"
        )
    if recorded is not None:
        differences = _differences(recorded, flat, input_prints, growable, added or {})
        if differences:
            _restore_hydra_files(run_dir, recorded)
            raise RunMismatch(
                f"{run_dir} holds a run made with other settings or inputs; refusing to reuse "
                "or continue it. Differences (recorded -> now): "
                + "; ".join(differences)
                + ". Run into another directory (hydra.run.dir=...) to keep both."
            )
        budgets = [k for k in set(recorded["settings"]) | set(flat) if _matches(k, growable)]
        budgets_same = all(recorded["settings"].get(k) == flat.get(k) for k in budgets)
        if layout.done.exists():
            if budgets_same:
                return True
            layout.done.unlink()  # a larger budget: unfinished until it ends again
    run_dir.mkdir(parents=True, exist_ok=True)
    for leftover in run_dir.glob(f".{layout.run_record.stem}.*{layout.run_record.suffix}"):
        leftover.unlink(missing_ok=True)  # a temporary run.json of a killed write
    record = {
        "settings": flat,
        "inputs": input_prints,
        "growable": list(growable),
        "provenance": provenance(**facts),
        "hydra_files": (recorded or {}).get("hydra_files") or _hydra_files(run_dir),
        "full_settings": dict(settings),
    }
    write_text_atomic(layout.run_record, json.dumps(record, indent=1, default=str))
    _CURRENT_RUN.clear()
    _CURRENT_RUN.update(record["provenance"], run_dir=str(run_dir), inputs=input_prints)
    return False


def finish_run(run_dir: str | Path, metrics: Mapping[str, float | int | bool]) -> None:
    """Write the run's scalar results and mark it finished (``metrics.json``, ``done.json``);
    checkpoints written after this no longer carry the run's provenance."""
    mark_done(run_dir, dict(metrics))
    _CURRENT_RUN.clear()


def read_run_record(run_dir: str | Path) -> dict[str, Any] | None:
    """``run.json`` of ``run_dir`` (``None`` when the directory has none)."""
    path = RunLayout(run_dir).run_record
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise RunMismatch(f"{path}: unreadable run record ({error})") from None
    if not isinstance(record, dict) or not isinstance(record.get("settings"), dict):
        raise RunMismatch(f"{path}: not a pilerl run record (no 'settings')")
    return record


def read_run_settings(run_dir: str | Path) -> dict[str, Any] | None:
    """The full resolved settings a run actually ran with (``None``: no ``run.json``)."""
    record = read_run_record(run_dir)
    return None if record is None else record.get("full_settings")


def _differences(
    recorded: dict, flat: dict, input_prints: dict, growable: tuple[str, ...], added: Mapping
) -> list[str]:
    before, now = {k: v for k, v in added.items() if k in flat} | recorded["settings"], flat
    differences = [
        f"{key}: {before.get(key, '<unset>')!r} -> {now.get(key, '<unset>')!r}"
        for key in sorted(set(before) | set(now))
        if not _matches(key, growable) and before.get(key, "<unset>") != now.get(key, "<unset>")
    ]
    recorded_inputs = recorded.get("inputs", {})
    for name in sorted(set(recorded_inputs) | set(input_prints)):
        old, new = recorded_inputs.get(name), input_prints.get(name)
        if old != new:
            differences.append(
                f"input {name}: {(old or '<none>')[:12]} -> {(new or '<none>')[:12]} (content)"
            )
    return differences


def _hydra_files(run_dir: Path) -> dict[str, str]:
    hydra_dir = run_dir / ".hydra"
    return {
        name: (hydra_dir / name).read_text() for name in HYDRA_FILES if (hydra_dir / name).is_file()
    }


def _restore_hydra_files(run_dir: Path, recorded: dict) -> None:
    """Put back the Hydra files that a refused invocation overwrote."""
    for name, text in (recorded.get("hydra_files") or {}).items():
        write_text_atomic(run_dir / ".hydra" / name, text)


# ---------------------------------------------------------------------------- checkpoints
def resolve_checkpoint(path: str | Path) -> Path:
    """A checkpoint file, or the ``best.pt`` inside a run directory passed instead.

    Raises ``FileNotFoundError`` saying what was expected when neither exists.
    """
    path = Path(path)
    if path.is_dir():
        best = RunLayout(path).best_actor
        if best.is_file():
            return best
        found = sorted(p.name for p in path.glob("*.pt"))
        raise FileNotFoundError(
            f"checkpoint={path}: a directory without {RunLayout.BEST_ACTOR}; expected a checkpoint "
            f"file or a train_bc / finetune run directory"
            + (f" (it holds {', '.join(found)})" if found else "")
        )
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint={path}: no such checkpoint file or run directory")
    return path
