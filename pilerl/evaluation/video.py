"""Write rendered frames to an mp4 (imageio-ffmpeg ships its own ffmpeg binary)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from pilerl.io import atomic_path
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, *, fps: float) -> Path:
    """Encode RGB ``frames`` (H, W, 3 uint8) as H.264 mp4 at ``fps``; written atomically.

    Frame sides need only be even (yuv420p), so 320x180 is written as it is.
    """
    if not frames:
        raise ValueError(f"write_mp4({path}): no frames to write")
    path = Path(path)
    with (
        atomic_path(path) as tmp,
        imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7, macro_block_size=2) as writer,
    ):
        for frame in frames:
            writer.append_data(frame)
    return path


def annotate_frames(
    episode,
    *,
    condition: str,
    sensor_ranges: dict[str, tuple[float, float]],
    success_fill: float = 0.5,
    simulator: str = DEFAULT_SIMULATOR,
) -> list[np.ndarray]:
    """The episode's frames with an overlay: condition, time, fill, outcome, sensor gauges.

    Frame k of ``run_episode`` shows the state after ``k * stride`` control steps, so the
    overlay reads the sensors and fill of that step. Each sensor is a small horizontal
    gauge scaled to its declared range (``sensor_ranges``: name -> (low, high)), so that
    winter (low drive pressure, spinning wheels) looks different from summer at a glance.
    Fill and outcome are ``simulator``'s declared fill and success keys.
    """
    from PIL import Image, ImageDraw, ImageFont

    if not episode.frames:
        return []
    dt = float(episode.time_s[0]) if len(episode.time_s) else 0.0
    stride = max(1, round(1.0 / (episode.frame_hz * dt))) if dt and episode.frame_hz else 1
    plugin = get_simulator(simulator)
    fill_key = plugin.fill_key
    fills = episode.info[fill_key][1:] if fill_key and fill_key in episode.info else None
    success = bool(episode.final_info.get(plugin.success_key, False))
    height = episode.frames[0].shape[0]
    font = ImageFont.load_default(size=max(8, height // 30))
    line = font.size + 2
    names = list(sensor_ranges)
    annotated = []
    for k, frame in enumerate(episode.frames):
        step = k * stride - 1  # index of the step whose end this frame shows (-1: reset)
        if step >= 0:
            readings = {n: float(episode.sensors[n][step]) for n in names}
        else:
            readings = {n: float(episode.start_sensors.get(n, np.nan)) for n in names}
        fill = float(fills[step]) if fills is not None and step >= 0 else 0.0
        image = Image.fromarray(frame)
        draw = ImageDraw.Draw(image, "RGBA")
        # header: condition, time, fill, outcome (the outcome shows from the last frame on)
        last = k == len(episode.frames) - 1
        outcome = ("SUCCESS" if success else "FAILED") if last else ""
        header = f"{condition}  t={max(step + 1, 0) * dt:5.1f} s  fill {fill:4.2f}  {outcome}"
        draw.rectangle((0, 0, image.width, line + 4), fill=(0, 0, 0, 150))
        draw.text((4, 2), header, fill=(255, 255, 255), font=font)
        fill_colour = (80, 220, 80) if fill >= success_fill else (240, 200, 60)
        draw.rectangle(
            (image.width - 84, 5, image.width - 84 + int(80 * min(fill, 1.0)), line),
            fill=fill_colour,
        )
        # sensor strip: one gauge per sensor, two columns along the bottom edge
        rows = (len(names) + 1) // 2
        column = image.width // 2
        top = image.height - rows * line - 4
        draw.rectangle((0, top, image.width, image.height), fill=(0, 0, 0, 150))
        for i, name in enumerate(names):
            low, high = sensor_ranges[name]
            value = readings[name]
            share = 0.0 if not np.isfinite(value) or high <= low else (value - low) / (high - low)
            x, y = (i // rows) * column + 4, top + 2 + (i % rows) * line
            gauge_left, gauge_right = x + int(0.5 * column), x + column - 10
            draw.text((x, y), _short_name(name), fill=(255, 255, 255), font=font)
            draw.rectangle((gauge_left, y + 2, gauge_right, y + line - 3), outline=(200, 200, 200))
            filled = gauge_left + int((gauge_right - gauge_left) * min(max(share, 0.0), 1.0))
            draw.rectangle((gauge_left, y + 2, filled, y + line - 3), fill=(90, 170, 255))
        annotated.append(np.asarray(image))
    return annotated


def sensor_ranges(env) -> dict[str, tuple[float, float]]:
    """Each sensor's declared (low, high) from a Gymnasium env's ``Dict`` observation space."""
    return {
        name: (float(np.min(space.low)), float(np.max(space.high)))
        for name, space in env.observation_space.spaces.items()
    }


def _short_name(sensor: str) -> str:
    """``telescope_pressure`` -> ``telescope p``; angles keep their name."""
    return sensor.replace("_pressure", " p").replace("_angle", " angle").replace("_", " ")
