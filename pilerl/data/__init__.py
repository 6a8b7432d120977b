"""Demonstrations: episode schema, on-disk store, recording, curation, replay buffers."""

from .buffers import make_replay_buffer
from .curation import build_dataset, compute_stats, downsample_episode
from .recorder import RecordingPlan, record_demonstrations, record_episode
from .schema import SCHEMA_VERSION, EpisodeMeta, SchemaError, make_episode, validate_episode
from .store import EpisodeStore

__all__ = [
    "SCHEMA_VERSION",
    "EpisodeMeta",
    "EpisodeStore",
    "RecordingPlan",
    "SchemaError",
    "build_dataset",
    "compute_stats",
    "downsample_episode",
    "make_episode",
    "make_replay_buffer",
    "record_demonstrations",
    "record_episode",
    "validate_episode",
]
