"""Write rendered frames to an mp4 (imageio-ffmpeg ships its own ffmpeg binary)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from pilerl.io import atomic_path


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, *, fps: float) -> Path:
    """Encode RGB ``frames`` (H, W, 3 uint8) as H.264 mp4 at ``fps``; written atomically."""
    if not frames:
        raise ValueError(f"write_mp4({path}): no frames to write")
    path = Path(path)
    with (
        atomic_path(path) as tmp,
        imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7, macro_block_size=8) as writer,
    ):
        for frame in frames:
            writer.append_data(frame)
    return path
