"""Field checks the typed configs run in ``__post_init__``: a bad value fails when the
config is built (``OmegaConf.to_object`` in a recipe), before any work, with a
``ValueError`` naming the field (``where``) and the value."""

from __future__ import annotations

import math
from collections.abc import Sequence

MAX_RENDER_PX = 4096  # a video frame side [px]


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def positive_int(where: str, value) -> None:
    if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
        raise ValueError(f"{where}: must be a whole number >= 1, got {value!r}")


def non_negative_int(where: str, value) -> None:
    if not (isinstance(value, int) and not isinstance(value, bool) and value >= 0):
        raise ValueError(f"{where}: must be a whole number >= 0, got {value!r}")


def positive(where: str, value) -> None:
    if not (_number(value) and math.isfinite(value) and value > 0):
        raise ValueError(f"{where}: must be a finite number > 0, got {value!r}")


def non_negative(where: str, value) -> None:
    if not (_number(value) and math.isfinite(value) and value >= 0):
        raise ValueError(f"{where}: must be a finite number >= 0, got {value!r}")


def finite(where: str, value) -> None:
    if not (_number(value) and math.isfinite(value)):
        raise ValueError(f"{where}: must be a finite number, got {value!r}")


def fraction(where: str, value) -> None:
    """A share in [0, 1]."""
    if not (_number(value) and 0 <= value <= 1):
        raise ValueError(f"{where}: must lie in [0, 1], got {value!r}")


def name(where: str, value) -> None:
    """A non-empty name without surrounding blanks."""
    if not (isinstance(value, str) and value.strip() and value == value.strip()):
        raise ValueError(f"{where}: must be a non-empty name, got {value!r}")


def one_of(where: str, value, known: Sequence) -> None:
    if value not in known:
        raise ValueError(f"{where}: unknown {value!r}; known: {list(known)}")


def names(where: str, values, *, allow_empty: bool = False) -> None:
    """A list of distinct non-empty names."""
    if isinstance(values, str) or not isinstance(values, Sequence):
        raise ValueError(f"{where}: must be a list of names, got {values!r}")
    if not values and not allow_empty:
        raise ValueError(f"{where}: must name at least one, got an empty list")
    for i, value in enumerate(values):
        name(f"{where}[{i}]", value)
    repeated = sorted({v for v in values if list(values).count(v) > 1})
    if repeated:
        raise ValueError(f"{where}: {repeated} listed more than once")


def interval(where: str, values, *, low: float = -math.inf, high: float = math.inf) -> None:
    """A ``[low, high]`` pair of finite numbers inside ``[low, high]`` bounds, ordered."""
    if isinstance(values, str) or not isinstance(values, Sequence) or len(values) != 2:
        raise ValueError(f"{where}: must be a pair [low, high], got {values!r}")
    for i, value in enumerate(values):
        finite(f"{where}[{i}]", value)
    if values[0] > values[1]:
        raise ValueError(f"{where}: low {values[0]} is above high {values[1]}")
    if values[0] < low or values[1] > high:
        raise ValueError(f"{where}: must lie within [{low}, {high}], got {list(values)}")


def render_size(where: str, width, height) -> None:
    for axis, value in (("render_width", width), ("render_height", height)):
        positive_int(f"{where}{axis}", value)
        if value > MAX_RENDER_PX:
            raise ValueError(f"{where}{axis}: at most {MAX_RENDER_PX} px, got {value}")


def path(where: str, value) -> None:
    if not (isinstance(value, str) and value.strip()):
        raise ValueError(f"{where}: must be a path, got {value!r}")


VIDEO_CHOICES = ("auto", "true", "false")


def video_choice(where: str, value) -> None:
    """``auto``, ``true`` or ``false`` (Hydra hands a str field ``True`` for ``true``)."""
    if str(value).strip().lower() not in VIDEO_CHOICES:
        raise ValueError(f"{where}: must be one of {list(VIDEO_CHOICES)}, got {value!r}")
