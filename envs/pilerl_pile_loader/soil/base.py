"""What every soil model shares: the pile's shape, the bucket's shape, and the interface.

A soil model owns the material: the pile, the load in the bucket and what has spilled.
The environment asks it to add itself to the MuJoCo model spec before compiling
(``add_to_spec``), to bind to the compiled model (``bind``), to lay a fresh pile
(``reset``), to run the physics steps (``advance``: ``mj_step`` unless the soil has forces
of its own to set every step) and to advance the bucket-material interaction (``update``)
a few times per control step. Mass is the currency:
``pile_mass_kg + bucket_load_kg + spilled_kg`` is the same before and after every call.
"""

from __future__ import annotations

import functools
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import mujoco
import numpy as np

from ..conditions import Material

if TYPE_CHECKING:
    from ..machine import Machine


@dataclass(frozen=True)
class PileGeometry:
    """A windrow-shaped pile whose face (the toe line) lies along world y at ``toe_x_m``.

    The face and the sides rise at the material's angle of repose up to ``height_m``.

    Attributes:
        toe_x_m: world x of the toe line [m].
        height_m: crest height [m].
        length_m: extent of the modelled pile behind the toe [m].
        half_width_m: half the crest width along y [m].
        cell_size_m: heightfield resolution [m].
        roughness_m: amplitude of random surface undulation [m], drawn per episode.
    """

    toe_x_m: float = 0.0
    height_m: float = 1.2
    length_m: float = 3.6
    half_width_m: float = 2.2
    cell_size_m: float = 0.05
    roughness_m: float = 0.02

    def __post_init__(self) -> None:
        for name in ("height_m", "length_m", "half_width_m", "cell_size_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"PileGeometry.{name}: must be finite and > 0, got {value}")
        if not (0 <= self.roughness_m < self.height_m):
            raise ValueError(
                f"PileGeometry.roughness_m: must lie in [0, height_m), got {self.roughness_m}"
            )

    def surface_height(self, x: np.ndarray, y: np.ndarray, repose_angle_rad: float) -> np.ndarray:
        """Undisturbed pile surface height [m] at world (x, y)."""
        slope = math.tan(repose_angle_rad)
        from_face = (x - self.toe_x_m) * slope
        from_side = (self.half_width_m + self.height_m / slope - np.abs(y)) * slope
        return np.clip(np.minimum(np.minimum(from_face, from_side), self.height_m), 0.0, None)


@dataclass(frozen=True)
class BucketGeometry:
    """Cross-section of the bucket's inside in the bucket frame (x forward, z up), extruded
    over ``width_m``. Vertices go back-floor, cutting edge, top lip, back-top, matching
    assets/wheel_loader.xml."""

    interior_xz_m: tuple[tuple[float, float], ...] = (
        (0.0, -0.40),
        (0.60, -0.40),
        (0.20, 0.10),
        (0.0, 0.10),
    )
    width_m: float = 1.30
    heap_fraction: float = 0.10  # heap above the struck volume when curled back

    @functools.cached_property  # the dataclass is frozen: compute once
    def polygon(self) -> np.ndarray:
        return np.asarray(self.interior_xz_m, dtype=float)

    @functools.cached_property  # the dataclass is frozen: compute once
    def cross_section_m2(self) -> float:
        return _polygon_area(self.polygon)

    @functools.cached_property  # the dataclass is frozen: compute once
    def rated_volume_m3(self) -> float:
        """Struck capacity [m^3]; fill_fraction 1.0 means this much material."""
        return self.cross_section_m2 * self.width_m

    @property
    def cutting_edge_xz(self) -> np.ndarray:
        return self.polygon[1]

    @property
    def lip_xz(self) -> np.ndarray:
        return self.polygon[2]

    def centroid_xz(self) -> np.ndarray:
        p = self.polygon
        q = np.roll(p, -1, axis=0)
        cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
        area = cross.sum() / 2
        return np.array(
            [((p[:, 0] + q[:, 0]) * cross).sum(), ((p[:, 1] + q[:, 1]) * cross).sum()]
        ) / (6 * area)

    def holding_volume_m3(self, pitch_rad: float, repose_angle_rad: float) -> float:
        """Volume [m^3] the bucket keeps at a given floor pitch before material slides out.

        The free surface of the load passes through the lower end of the mouth and rises
        into the bucket at the angle of repose (granular material, not a liquid). Curled
        back far enough to hold its whole struck volume, the bucket also carries a heap.
        """
        c, s = math.cos(pitch_rad), math.sin(pitch_rad)
        rotate = np.array([[c, -s], [s, c]])
        world = self.polygon @ rotate.T  # (x, z) in a vertical plane, pitch applied
        edge, lip = world[1], world[2]
        low = edge if edge[1] <= lip[1] else lip
        inward = -1.0 if world[:, 0].mean() < low[0] else 1.0
        # keep points with z <= low_z + tan(repose) * inward distance from the mouth
        normal = np.array([-math.sin(repose_angle_rad) * inward, math.cos(repose_angle_rad)])
        kept = _clip_polygon(world, normal, float(normal @ low))
        fraction = _polygon_area(kept) / self.cross_section_m2 if len(kept) >= 3 else 0.0
        fraction = min(fraction, 1.0)
        return self.rated_volume_m3 * (fraction + self.heap_fraction * fraction**8)


def _polygon_area(p: np.ndarray) -> float:
    q = np.roll(p, -1, axis=0)
    return float(abs((p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]).sum()) / 2)


def _clip_polygon(poly: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of ``poly`` where ``normal . p <= offset``."""
    out = []
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        da, db = normal @ a - offset, normal @ b - offset
        if da <= 0:
            out.append(a)
        if (da < 0 < db) or (db < 0 < da):
            out.append(a + (b - a) * (da / (da - db)))
    return np.asarray(out)


class SoilModel(ABC):
    """Interface of a pluggable soil model. See the module docstring for the call order."""

    name: ClassVar[str]

    def __init__(self, material: Material, pile: PileGeometry, bucket: BucketGeometry) -> None:
        self.material, self.pile, self.bucket = material, pile, bucket
        self.bucket_load_kg = 0.0
        self.spilled_kg = 0.0
        self.initial_mass_kg = 0.0

    @property
    def repose_angle_rad(self) -> float:
        return math.radians(self.material.friction_angle_deg)

    @abstractmethod
    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        """Add the pile's bodies, geoms and force elements to the uncompiled model."""

    @abstractmethod
    def bind(self, model: mujoco.MjModel, data: mujoco.MjData, machine: Machine) -> None:
        """Look up ids in the compiled model; called once."""

    @abstractmethod
    def reset(self, rng: np.random.Generator) -> None:
        """Lay a fresh pile (shape noise from ``rng``), empty the bucket, zero the tallies."""

    def advance(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        """Run ``nstep`` physics steps (default ``mj_step``; a soil with forces of its own
        that depend on each step's contacts steps itself, e.g. the particle pile's bonds)."""
        mujoco.mj_step(model, data, nstep=nstep)

    @abstractmethod
    def update(self, dt: float) -> None:
        """Advance the bucket-material interaction by ``dt`` seconds of simulated time."""

    @property
    @abstractmethod
    def pile_mass_kg(self) -> float:
        """Material still in the pile [kg]."""

    @abstractmethod
    def cutting_depth_m(self) -> float:
        """Depth of the cutting edge below the local pile surface [m] (0 when outside)."""

    def prepare_render(self, renderer: mujoco.Renderer) -> None:  # noqa: B027 - optional hook
        """Push changed pile geometry to the renderer (default: nothing to do)."""

    @property
    def bucket_load_volume_m3(self) -> float:
        return self.bucket_load_kg / self.material.density_kg_m3

    @property
    def fill_fraction(self) -> float:
        """Bucket load as a fraction of the bucket's rated (struck) capacity."""
        return self.bucket_load_volume_m3 / self.bucket.rated_volume_m3
