"""A dataset of demonstration episodes on disk: memory-mapped TensorDicts + a JSON index.

Layout of a dataset directory::

    index.json              schema version, sensors + units, controls, episode metadata,
                            normalisation statistics
    episodes/ep_000000/     one episode: a TensorDict memmap (``TensorDict.memmap_``)
    episodes/ep_000001/
    ...

Writes are atomic per episode: the episode is memory-mapped into a hidden temporary
directory, renamed into place, and only then listed in the index (itself replaced
atomically). An interrupted write leaves the earlier episodes intact and no partial
episode visible; the leftover temporary directory is removed the next time the dataset
is opened for writing.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

import torch
from tensordict import TensorDict

from pilerl.io import write_text_atomic

from .schema import (
    SCHEMA_VERSION,
    EpisodeMeta,
    SchemaError,
    required_keys,
    validate_episode,
)

INDEX = "index.json"
EPISODES = "episodes"
TMP_PREFIX = ".tmp-"


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
        """A new, empty dataset. ``sensors`` maps sensor name -> unit."""
        root = Path(root)
        if (root / INDEX).exists():
            if not exist_ok:
                raise FileExistsError(f"{root}: a dataset already exists here")
            existing = cls.open(root, writable=True)
            if existing.sensors != dict(sensors) or existing.controls != list(controls):
                raise SchemaError(
                    f"{root}: existing dataset has sensors {existing.sensors} and controls "
                    f"{existing.controls}, not {dict(sensors)} and {list(controls)}"
                )
            return existing
        (root / EPISODES).mkdir(parents=True, exist_ok=True)
        index = {
            "schema_version": SCHEMA_VERSION,
            "description": description,
            "sensors": dict(sensors),
            "controls": list(controls),
            "episodes": [],
            "stats": None,
        }
        store = cls(root, index)
        store._write_index()
        return store

    @classmethod
    def open(cls, root: str | Path, *, writable: bool = False) -> EpisodeStore:
        """An existing dataset; checks the schema version and the index."""
        root = Path(root)
        path = root / INDEX
        if not path.exists():
            raise FileNotFoundError(f"{root}: not a pilerl dataset (no {INDEX})")
        try:
            index = json.loads(path.read_text())
        except json.JSONDecodeError as error:
            raise SchemaError(f"{path}: corrupt index ({error})") from None
        version = index.get("schema_version")
        if version != SCHEMA_VERSION:
            raise SchemaError(
                f"{path}: schema_version {version!r}, this pilerl reads {SCHEMA_VERSION}"
            )
        for key in ("sensors", "controls", "episodes"):
            if key not in index:
                raise SchemaError(f"{path}: index has no {key!r}")
        store = cls(root, index)
        if writable:
            for leftover in (root / EPISODES).glob(f"{TMP_PREFIX}*"):
                shutil.rmtree(leftover, ignore_errors=True)
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
        self._index["stats"] = stats
        self._write_index()

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

    def extend(self, episodes: Sequence[tuple[TensorDict, EpisodeMeta]]) -> list[EpisodeMeta]:
        """Validate and add several episodes as one atomic change.

        Every episode is validated before anything is written; the episode directories
        are written and renamed into place, and the index is updated once at the end. If
        anything fails, the directories written by this call are removed again and the
        dataset is as it was.
        """
        first_id = len(self)
        prepared = []
        for offset, (episode, meta) in enumerate(episodes):
            episode_id = first_id + offset
            validate_episode(
                episode,
                list(self.sensors),
                action_dim=len(self.controls),
                where=f"{self.root} episode {episode_id}",
            )
            episode = episode.clone()
            episode["episode"] = torch.full_like(episode["episode"], episode_id)
            meta.id, meta.n_samples = episode_id, int(episode.batch_size[0])
            prepared.append((episode, meta))
        written: list[Path] = []
        try:
            for episode, meta in prepared:
                final = self._episode_dir(meta.id)
                if final.exists():
                    raise FileExistsError(f"{final}: exists but is not in the index; remove it")
                tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=self.root / EPISODES))
                try:
                    episode.memmap_(prefix=tmp)
                    tmp.rename(final)
                    written.append(final)
                finally:
                    shutil.rmtree(tmp, ignore_errors=True)
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
        """One episode, memory-mapped read-only."""
        if not 0 <= episode_id < len(self):
            raise IndexError(f"{self.root}: episode {episode_id} not in 0..{len(self) - 1}")
        path = self._episode_dir(episode_id)
        try:
            td = TensorDict.load_memmap(path)
        except Exception as error:  # noqa: BLE001 - re-raised with the place named
            raise SchemaError(f"{path}: cannot load episode ({error})") from error
        expected = self._index["episodes"][episode_id]["n_samples"]
        if td.batch_dims != 1 or td.batch_size[0] != expected:
            raise SchemaError(f"{path}: {tuple(td.batch_size)} samples, index says {expected}")
        # load_memmap silently skips leaves whose files are gone: check the schema's keys
        present = set(td.keys(include_nested=True, leaves_only=True))
        missing = [k for k in required_keys(list(self.sensors)) if k not in present]
        if missing:
            raise SchemaError(f"{path}: cannot load episode (missing files for {missing})")
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

    # ------------------------------------------------------------------ internals
    def _episode_dir(self, episode_id: int) -> Path:
        return self.root / EPISODES / f"ep_{episode_id:06d}"

    def _write_index(self) -> None:
        # allow_nan=False: the index stays strict JSON that any reader can parse
        write_text_atomic(self.root / INDEX, json.dumps(self._index, indent=1, allow_nan=False))
