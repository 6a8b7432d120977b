"""Running controllers in a simulator and showing what happened (plots, videos)."""

from .episode import Episode, run_episode
from .plots import plot_scoop
from .video import write_mp4

__all__ = ["Episode", "plot_scoop", "run_episode", "write_mp4"]
