"""A dataset of demonstration episodes on disk: memory-mapped TensorDicts + a JSON index.

Layout of a dataset directory::

    index.json              schema version, sensors + units, controls, episode metadata,
                            normalisation statistics: the list of committed episodes
    .lock                   the writers' lock (``fcntl.flock``); empty
    episodes/ep_000000/     one episode: a TensorDict memmap (``TensorDict.memmap_``)
    episodes/ep_000001/
    ...

Crash consistency. ``index.json`` is the commit point: an episode belongs to the
dataset once the index lists it, and only then. A write memory-maps each episode into a
hidden temporary directory, renames it to ``ep_<id>``, and replaces the index atomically
at the end. Every write holds the dataset's lock and re-reads the index under it, so
several processes may append to one dataset at once (two ``record.py`` into one
directory) without overwriting each other. A process killed at any instant leaves the
committed episodes intact; what it left behind (temporary directories, an episode
directory renamed but never listed) is not part of the dataset, is ignored by readers,
and is cleared by the next writer under the lock: nobody has to delete anything by hand.

Safety. Loading never unpickles: an episode directory is checked against the schema
(only tensor leaves of the schema's dtypes and shapes, no files the store does not
write) before it is memory-mapped with ``allow_pickle=False``, and its values are
checked (finite readings and actions, increasing time) like an appended episode.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import shutil
import tempfile
from collections.abc import Callable, Hashable, Iterator, Sequence
from pathlib import Path

import torch
from tensordict import TensorDict

from pilerl.io import write_text_atomic

from .schema import (
    END_FLAGS,
    SCHEMA_VERSION,
    EpisodeMeta,
    SchemaError,
    required_keys,
    validate_episode,
)

INDEX = "index.json"
EPISODES = "episodes"
LOCK = ".lock"
TMP_PREFIX = ".tmp-"
EPISODE_PREFIX = "ep_"
MEMMAP_META = "meta.json"  # tensordict's description of a memory-mapped TensorDict
TENSORDICT_TYPE = "<class 'tensordict._td.TensorDict'>"
# dtypes an episode leaf may have: plain numbers only (no object or pickled leaves)
LEAF_DTYPES = {
    str(dtype): dtype
    for dtype in (
        torch.float16,
        torch.bfloat16,
        torch.float32,
        torch.float64,
        torch.uint8,
        torch.int8,
        torch.int16,
        torch.int32,
        torch.int64,
        torch.bool,
    )
}


class EpisodeStore:
    """Open (``open``) or create (``create``) a dataset directory; see module docstring."""

    def __init__(self, root: Path, index: dict) -> None:
        self.root = root
        self._index = index

    # ------------------------------------------------------------------ open / create
    @classmethod
    def create(
        cls,
        root: str | Path,
        *,
        sensors: dict[str, str],
        controls: Sequence[str],
        description: str = "",
        exist_ok: bool = False,
    ) -> EpisodeStore:
        """A new, empty dataset. ``sensors`` maps sensor name -> unit.

        With ``exist_ok``, an existing dataset with the same sensors and controls is
        opened instead (several processes may do this at once).
        """
        root = Path(root)
        root.mkdir(parents=True, exist_ok=True)
        with _locked(root):
            if (root / INDEX).exists():
                if not exist_ok:
                    raise FileExistsError(f"{root}: a dataset already exists here")
                existing = cls.open(root)
                if existing.sensors != dict(sensors) or existing.controls != list(controls):
                    raise SchemaError(
                        f"{root}: existing dataset has sensors {existing.sensors} and controls "
                        f"{existing.controls}, not {dict(sensors)} and {list(controls)}"
                    )
                existing._clear_uncommitted()
                return existing
            (root / EPISODES).mkdir(exist_ok=True)
            index = {
                "schema_version": SCHEMA_VERSION,
                "description": description,
                "sensors": dict(sensors),
                "controls": list(controls),
                "episodes": [],
                "stats": None,
            }
            store = cls(root, index)
            store._clear_uncommitted()
            store._write_index()
        return store

    @classmethod
    def open(cls, root: str | Path, *, writable: bool = False) -> EpisodeStore:
        """An existing dataset; checks the schema version and the index.

        ``writable`` also clears what an interrupted writer left behind (under the lock);
        every write does that anyway, so it only tidies the directory early.
        """
        root = Path(root)
        store = cls(root, _read_index(root))
        if writable:
            with _locked(root):
                store._reload()
                store._clear_uncommitted()
        return store

    # ------------------------------------------------------------------ properties
    @property
    def sensors(self) -> dict[str, str]:
        """Sensor name -> unit, in recording order."""
        return dict(self._index["sensors"])

    @property
    def controls(self) -> list[str]:
        return list(self._index["controls"])

    @property
    def description(self) -> str:
        return self._index.get("description", "")

    @property
    def stats(self) -> dict | None:
        """Normalisation statistics (see ``pilerl.data.stats``), once computed."""
        return self._index.get("stats")

    def set_stats(self, stats: dict) -> None:
        self.set_index_entry("stats", stats)

    def index_entry(self, key: str):
        """A free-form entry of the index (``None`` if absent), e.g. ``recording_plan``."""
        return self._index.get(key)

    def set_index_entry(self, key: str, value) -> None:
        """Store a JSON value in the index under ``key`` (not one of the store's own keys)."""
        if key in ("schema_version", "sensors", "controls", "episodes"):
            raise KeyError(f"{self.root}: {key!r} is kept by the store itself")
        with _locked(self.root):
            self._reload()
            self._index[key] = value
            self._write_index()

    def claim_index_entry(self, key: str, value):
        """Store ``value`` under ``key`` unless the index has one; returns the entry kept
        (checked and set under the lock: two writers cannot both claim)."""
        with _locked(self.root):
            self._reload()
            if self._index.get(key) is None:
                self._index[key] = value
                self._write_index()
            return self._index[key]

    def refresh(self) -> None:
        """Re-read the index (episodes other processes appended since)."""
        self._reload()

    def __len__(self) -> int:
        return len(self._index["episodes"])

    @property
    def episodes(self) -> list[EpisodeMeta]:
        return [EpisodeMeta.from_json(m) for m in self._index["episodes"]]

    @property
    def n_samples(self) -> int:
        return sum(m["n_samples"] for m in self._index["episodes"])

    # ------------------------------------------------------------------ write
    def append(self, episode: TensorDict, meta: EpisodeMeta) -> EpisodeMeta:
        """Validate and add one episode atomically; returns its metadata with id set."""
        return self.extend([(episode, meta)])[0]

    def extend(
        self,
        episodes: Sequence[tuple[TensorDict, EpisodeMeta]],
        *,
        identity: Callable[[EpisodeMeta], Hashable] | None = None,
    ) -> list[EpisodeMeta]:
        """Validate and add several episodes as one atomic change.

        Every episode is validated before anything is written. Under the dataset's lock,
        the index is re-read (other writers may have appended), the episode directories
        are written and renamed into place, and the index is replaced once at the end. If
        anything fails, the directories written by this call are removed again and the
        dataset is as it was.

        ``identity`` (optional) names what makes an episode unique (e.g. its seed):
        episodes whose identity is already in the dataset, or repeated in this call, are
        skipped, so writers racing on the same work store it once. Returns the metadata
        of the episodes added, ids set.
        """
        for episode, _ in episodes:
            self._check_episode(episode, where=f"{self.root} new episode")
        with _locked(self.root):
            self._reload()
            self._clear_uncommitted()
            if identity is not None:
                seen = {identity(m) for m in self.episodes}
                unique = []
                for episode, meta in episodes:
                    if identity(meta) not in seen:
                        seen.add(identity(meta))
                        unique.append((episode, meta))
                episodes = unique
            first_id = len(self)
            prepared = []
            for offset, (episode, meta) in enumerate(episodes):
                episode = episode.clone()
                episode["episode"] = torch.full_like(episode["episode"], first_id + offset)
                meta.id, meta.n_samples = first_id + offset, int(episode.batch_size[0])
                prepared.append((episode, meta))
            written: list[Path] = []
            try:
                for episode, meta in prepared:
                    final = self._episode_dir(meta.id)
                    tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=self.root / EPISODES))
                    try:
                        episode.memmap_(prefix=tmp)
                        tmp.rename(final)
                        written.append(final)
                    finally:
                        shutil.rmtree(tmp, ignore_errors=True)
                if prepared:
                    self._index["episodes"].extend(meta.to_json() for _, meta in prepared)
                    self._write_index()
            except BaseException:
                del self._index["episodes"][first_id:]
                for path in written:
                    shutil.rmtree(path, ignore_errors=True)
                raise
        return [meta for _, meta in prepared]

    # ------------------------------------------------------------------ read
    def load(self, episode_id: int) -> TensorDict:
        """One episode, memory-mapped read-only, checked against the schema (no pickle)."""
        if not 0 <= episode_id < len(self):
            raise IndexError(f"{self.root}: episode {episode_id} not in 0..{len(self) - 1}")
        path = self._episode_dir(episode_id)
        expected = self._index["episodes"][episode_id]["n_samples"]
        self._check_folder(path, n_samples=expected)
        try:
            td = TensorDict.load_memmap(path, allow_pickle=False)
        except Exception as error:  # noqa: BLE001 - re-raised with the place named
            raise SchemaError(f"{path}: cannot load episode ({error})") from error
        if td.batch_dims != 1 or td.batch_size[0] != expected:
            raise SchemaError(f"{path}: {tuple(td.batch_size)} samples, index says {expected}")
        self._check_episode(td, where=str(path))
        if not (td["episode"] == episode_id).all():
            raise SchemaError(f"{path}: its 'episode' column is not {episode_id}")
        return td

    def __iter__(self) -> Iterator[TensorDict]:
        for i in range(len(self)):
            yield self.load(i)

    def to_tensordict(self, episode_ids: Sequence[int] | None = None) -> TensorDict:
        """The chosen episodes (default: all) concatenated in memory, batch ``[N]``."""
        ids = range(len(self)) if episode_ids is None else episode_ids
        parts = [self.load(i).to_tensordict() for i in ids]
        if not parts:
            raise ValueError(f"{self.root}: no episodes selected")
        return torch.cat(parts, 0)

    # ------------------------------------------------------------------ schema checks
    def _leaf_layouts(self, n_samples: int) -> dict:
        """Schema key -> (dtype, shape) of an episode with ``n_samples`` rows."""
        row = (n_samples, 1)
        layouts = {name: (torch.float32, row) for name in self.sensors}
        layouts |= {("next", name): (torch.float32, row) for name in self.sensors}
        layouts |= {
            "action": (torch.float32, (n_samples, len(self.controls))),
            "time_s": (torch.float64, (n_samples,)),
            "step": (torch.int64, (n_samples,)),
            "episode": (torch.int64, (n_samples,)),
            ("next", "reward"): (torch.float32, row),
        }
        layouts |= {("next", flag): (torch.bool, row) for flag in END_FLAGS}
        return layouts

    def _check_episode(self, td: TensorDict, *, where: str) -> None:
        """Values (``validate_episode``), then every leaf: a plain tensor of the schema's
        dtype and shape; extra per-row columns (e.g. ``phase``) only at the top level."""
        validate_episode(td, list(self.sensors), action_dim=len(self.controls), where=where)
        layouts = self._leaf_layouts(int(td.batch_size[0]))
        # every non-TensorDict value counts as a leaf, so non-tensor data are seen too
        plain_leaf = lambda cls: not issubclass(cls, TensorDict)  # noqa: E731
        for key, value in td.items(include_nested=True, leaves_only=True, is_leaf=plain_leaf):
            if not isinstance(value, torch.Tensor):
                raise SchemaError(f"{where}: {key!r} is not a tensor ({type(value).__name__})")
            _check_leaf(key, value.dtype, tuple(value.shape), layouts, where=where)

    def _check_folder(self, path: Path, *, n_samples: int) -> None:
        """Refuse an episode directory holding anything the store does not write, before
        tensordict reads it: only ``meta.json`` files describing tensors and their data."""
        if not path.is_dir():
            raise SchemaError(f"{path}: cannot load episode (no such directory)")
        layouts = self._leaf_layouts(n_samples)
        described = set()
        for folder, prefix in ((path, ()), (path / "next", ("next",))):
            meta_path = folder / MEMMAP_META
            try:
                meta = json.loads(meta_path.read_text())
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
                raise SchemaError(f"{path}: cannot load episode ({meta_path}: {error})") from None
            if not isinstance(meta, dict) or meta.get("_type") != TENSORDICT_TYPE:
                raise SchemaError(f"{meta_path}: not a plain TensorDict; refusing to load it")
            expected_files = {MEMMAP_META}
            for name, entry in meta.items():
                if name in ("shape", "device", "_type"):
                    continue
                key = (*prefix, name) if prefix else name
                if not isinstance(entry, dict):
                    raise SchemaError(f"{meta_path}: entry {name!r} is not a description")
                if prefix == () and name == "next" and entry == {"type": "TensorDict"}:
                    expected_files.add("next")
                    continue
                if "type" in entry or "dtype" not in entry or entry.get("is_nested", False):
                    raise SchemaError(
                        f"{path}: {key!r} is not a tensor leaf ({entry.get('type', entry)}); "
                        "the store writes only tensors, refusing to load it"
                    )
                dtype = LEAF_DTYPES.get(entry["dtype"])
                shape = entry.get("shape")
                if dtype is None or not _is_shape(shape):
                    raise SchemaError(
                        f"{path}: {key!r} has dtype {entry['dtype']!r} and shape {shape!r}; "
                        f"allowed dtypes {sorted(LEAF_DTYPES)}"
                    )
                _check_leaf(key, dtype, tuple(shape), layouts, where=str(path))
                data = folder / f"{name}.memmap"
                size = math.prod(shape) * dtype.itemsize
                if not data.is_file() or data.stat().st_size != size:
                    actual = data.stat().st_size if data.is_file() else "no file"
                    raise SchemaError(
                        f"{path}: cannot load episode (missing files for {key!r}: "
                        f"{data.name} has {actual} bytes, expected {size})"
                    )
                expected_files.add(data.name)
                described.add(key)
            unexpected = sorted(p.name for p in folder.iterdir() if p.name not in expected_files)
            if unexpected:
                raise SchemaError(
                    f"{folder}: holds {unexpected}, which the store does not write; "
                    "refusing to load the episode"
                )
            if prefix == () and "next" not in expected_files:
                raise SchemaError(f"{path}: cannot load episode (no 'next' readings)")
        missing = [k for k in required_keys(list(self.sensors)) if k not in described]
        if missing:
            raise SchemaError(f"{path}: cannot load episode (missing files for {missing})")

    # ------------------------------------------------------------------ internals
    def _episode_dir(self, episode_id: int) -> Path:
        return self.root / EPISODES / f"{EPISODE_PREFIX}{episode_id:06d}"

    def _reload(self) -> None:
        self._index = _read_index(self.root)

    def _clear_uncommitted(self) -> None:
        """Remove what interrupted writers left (call under the lock): temporary episode
        directories, episode directories the index does not list, temporary index files.
        None of it was ever part of the dataset."""
        episodes = self.root / EPISODES
        listed = {self._episode_dir(m["id"]).name for m in self._index["episodes"]}
        for path in episodes.iterdir():
            if path.name.startswith(TMP_PREFIX) or (
                path.name.startswith(EPISODE_PREFIX) and path.name not in listed
            ):
                shutil.rmtree(path, ignore_errors=True)
        for path in self.root.glob(f".{Path(INDEX).stem}.*{Path(INDEX).suffix}"):
            path.unlink(missing_ok=True)

    def _write_index(self) -> None:
        # allow_nan=False: the index stays strict JSON that any reader can parse
        write_text_atomic(self.root / INDEX, json.dumps(self._index, indent=1, allow_nan=False))


@contextlib.contextmanager
def _locked(root: Path) -> Iterator[None]:
    """Hold the dataset's exclusive writer lock (released by the kernel if killed)."""
    with open(root / LOCK, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _read_index(root: Path) -> dict:
    path = root / INDEX
    if not path.exists():
        raise FileNotFoundError(f"{root}: not a pilerl dataset (no {INDEX})")
    try:
        index = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise SchemaError(f"{path}: corrupt index ({error})") from None
    if not isinstance(index, dict):
        raise SchemaError(f"{path}: corrupt index (not a JSON object)")
    version = index.get("schema_version")
    if version != SCHEMA_VERSION:
        raise SchemaError(f"{path}: schema_version {version!r}, this pilerl reads {SCHEMA_VERSION}")
    for key, kind in (("sensors", dict), ("controls", list), ("episodes", list)):
        if not isinstance(index.get(key), kind):
            raise SchemaError(f"{path}: index has no {key!r} ({kind.__name__})")
    if not (root / EPISODES).is_dir():
        raise SchemaError(f"{root}: has no {EPISODES}/ folder; not a complete pilerl dataset")
    for position, meta in enumerate(index["episodes"]):
        if not isinstance(meta, dict) or meta.get("id") != position:
            raise SchemaError(f"{path}: episode entry {position} does not have id {position}")
        if not isinstance(meta.get("n_samples"), int) or meta["n_samples"] < 1:
            raise SchemaError(f"{path}: episode {position} has n_samples {meta.get('n_samples')!r}")
    return index


def _check_leaf(key, dtype: torch.dtype, shape: tuple, layouts: dict, *, where: str) -> None:
    """A schema key must have its dtype and shape; an extra one must be a top-level numeric
    column with one entry per row."""
    n_samples = layouts["time_s"][1][0]
    if key in layouts:
        want_dtype, want_shape = layouts[key]
        if dtype != want_dtype or shape != want_shape:
            raise SchemaError(
                f"{where}: {key!r} has dtype {dtype} and shape {shape}, the schema says "
                f"{want_dtype} and {want_shape}"
            )
    elif isinstance(key, tuple) or str(dtype) not in LEAF_DTYPES or shape[:1] != (n_samples,):
        raise SchemaError(
            f"{where}: extra column {key!r} ({dtype}, shape {shape}) is not a per-row "
            f"numeric column of {n_samples} rows"
        )


def _is_shape(shape) -> bool:
    return isinstance(shape, list) and all(isinstance(n, int) and n >= 0 for n in shape)
