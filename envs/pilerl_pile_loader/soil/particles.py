"""Cross-check soil: a pile of MuJoCo spheres that the bucket pushes and scoops by contact.

No earthmoving equation and no soil actuators: cutting resistance, intake, heaping and
spill all come out of MuJoCo's contact solver. It is slow next to ``heightfield.py`` and
coarse, and meant to check the fast model's fills and forces, not to train on.

**Coarse graining.** Gravel grains (2 cm) are replaced by clods of radius
``PARTICLE_RADIUS_M`` (11 cm, i.e. ~200x the grain volume), so that the digging zone holds a
few hundred bodies and the simulation runs faster than real time on one core. Each clod's
mass is its share of the bulk mass of the region it fills (bulk density x pile volume /
particle count), so masses and fill fractions are in the same units as the heightfield
model's. The bucket (rated 0.26 m^3) holds about 40 clods.

**Non-rotating grains.** Each particle moves on three slide joints (x, y, z) instead of a
free joint. Free spheres roll, and a pile of rolling spheres slumps to ~20 deg whatever
their sliding friction; real gravel interlocks. Without rotation the sliding friction
``tan(friction_angle)`` alone holds the face at the angle of repose, with 3 instead of 6
degrees of freedom per particle and no rolling-friction rows in the contacts.

**Digging zone.** Only the part of the pile the bucket can reach is made of particles:
``PARTICLE_ZONE_DEPTH_M`` behind the toe and ``PARTICLE_ZONE_HALF_WIDTH_M`` to each side of
y = 0 (the bucket path with the start pose's lateral offset). Beyond it the pile is rigid:
invisible static boxes with the pile's cross-section (face slab + crest) on both sides and
a wall behind. They hold the particles in as the rest of the pile would, touch only the
particles (collision bit ``WALL_CONTYPE``), and never the machine.

**Pile at reset.** The particles are laid on a hexagonal close-packed lattice filling the
pile shape, then settled once in ``bind`` with the machine parked far away; the settled
positions are cached and written back exactly at every ``reset``: the pile is the same
every episode (no shape noise), so a seed fixes the whole episode.

**Solver.** With hundreds of bodies in one contact island MuJoCo's Newton solver (dense
factorisation) is far too slow; the model switches to CG with an elliptic friction cone
and ``IMPRATIO`` (stiffer friction, so piles do not creep), few iterations, and MuJoCo's
body sleeping so that a pile at rest costs almost nothing. These options are global: the
machine's own contacts (tyres) are solved with them too when this soil model is used.

**Tallies** (every ``update``; particle counts times the particle mass):

- *in the bucket*: the particle centre lies inside the bucket's interior polygon
  (``BucketGeometry.polygon``, bucket frame x-z) and within ``|y_local| <= width / 2``;
- *spilled*: not in the bucket, centre outside the pile footprint (the digging zone grown
  by ``FOOTPRINT_MARGIN_M``) and below ``SPILL_HEIGHT_M`` (it has landed, off the pile);
- *pile*: every other particle (in the footprint, or still in the air).

So ``pile_mass_kg + bucket_load_kg + spilled_kg`` equals the initial mass at every call.
The ``payload`` body is left alone: the particles carry their own mass.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .base import SoilModel

if TYPE_CHECKING:
    from ..machine import Machine

# ---- particles (coarse-grained clods, see module docstring)
PARTICLE_RADIUS_M = 0.11  # clod radius [m]; sets the particle count, hence the speed
MAX_PARTICLES = 400  # cap: a larger pile gets proportionally larger clods
RADIUS_GROWTH = 1.05  # radius step while a lattice has more than MAX_PARTICLES
PARTICLE_ZONE_DEPTH_M = 1.9  # particles from the toe to this far behind it [m]
PARTICLE_ZONE_HALF_WIDTH_M = 1.0  # particles for |y| <= this [m]; bucket path +- 0.35 m
PARTICLE_RGBA = (0.55, 0.47, 0.36, 1.0)
# ---- collision bits (assets/wheel_loader.xml: ground 1/1, machine 2/1)
PARTICLE_CONTYPE = 1  # particles are seen by the ground and the machine (conaffinity 1)
PARTICLE_CONAFFINITY = 1 | 2 | 4  # particles see each other, the machine and the walls
WALL_CONTYPE = 4  # rigid rest of the pile: seen by particles only
WALL_THICKNESS_M = 0.4  # thickness of the boundary boxes [m]
WALL_GROUP = 3  # geom group hidden by MuJoCo's default render flags
# ---- contact priorities: higher wins the pair's friction (ground is 1)
PARTICLE_PRIORITY = 2  # particle friction tan(phi) governs particle-ground contacts
BUCKET_PRIORITY = 3  # steel friction tan(delta) governs particle-bucket contacts
BUCKET_GEOMS = ("bucket_floor", "bucket_back", "bucket_top", "bucket_side_l", "bucket_side_r")
TORSION_FRICTION = 0.0  # unused with condim 3
CONTACT_CONDIM = 3  # sliding friction only: the particles cannot rotate anyway
FRICTION_SCALE = 1.0
# ---- solver (global options; see module docstring)
SOLVER = mujoco.mjtSolver.mjSOL_CG
CONE = mujoco.mjtCone.mjCONE_ELLIPTIC
IMPRATIO = 10.0  # friction-to-normal impedance ratio; stops slow creep of a resting pile
SOLVER_ITERATIONS = 10
SOLVER_LS_ITERATIONS = 5
SOLVER_TOLERANCE = 1e-6
SLEEP_TOLERANCE_M_S = 2e-3  # a particle island at rest below this speed sleeps [m/s]
ARENA_BYTES = 96 * 2**20  # MuJoCo arena: a pile in motion makes thousands of contacts
# ---- settling in bind
PARK_DISTANCE_M = 40.0  # the machine waits this far behind the toe while the pile settles
SETTLE_MAX_S = 3.0  # settling stops once the pile sleeps, at the latest after this [s]
SETTLE_CHECK_S = 0.1  # how often settling checks whether the pile is asleep [s]
# ---- tallies
FOOTPRINT_MARGIN_M = 0.25  # the pile footprint reaches this far beyond the digging zone [m]
SPILL_HEIGHT_M = 0.5  # a particle off the footprint counts as spilled below this height [m]
EDGE_WINDOW_AHEAD_M = 0.25  # particles up to this far ahead of the cutting edge set its depth
VOLUME_GRID_M = 0.01  # grid step for the pile-volume integral [m]


class ParticleSoil(SoilModel):
    """Particle pile for cross-checking the heightfield model (see module docstring)."""

    name = "particles"

    # ------------------------------------------------------------------ build
    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        pile = self.pile
        self.x_back_m = pile.toe_x_m + min(PARTICLE_ZONE_DEPTH_M, pile.length_m)
        self.half_width_m = min(PARTICLE_ZONE_HALF_WIDTH_M, pile.half_width_m)
        self.zone_volume_m3 = self._zone_volume_m3()
        self.radius_m, self.lattice = self._fill_lattice()
        self.n_particles = len(self.lattice)
        self.particle_mass_kg = self.material.density_kg_m3 * self.zone_volume_m3 / self.n_particles

        friction = math.tan(self.repose_angle_rad) * FRICTION_SCALE
        self._first_body_name = "particle_0"
        for i, position in enumerate(self.lattice):
            body = spec.worldbody.add_body(name=f"particle_{i}", pos=position.tolist())
            for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
                body.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=list(axis))
            body.add_geom(
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[self.radius_m, 0.0, 0.0],
                mass=self.particle_mass_kg,
                contype=PARTICLE_CONTYPE,
                conaffinity=PARTICLE_CONAFFINITY,
                condim=CONTACT_CONDIM,
                priority=PARTICLE_PRIORITY,
                friction=[friction, TORSION_FRICTION, 0.0],
                rgba=list(PARTICLE_RGBA),
            )
        self._add_walls(spec, friction)

        tool_friction = math.tan(math.radians(self.material.tool_friction_angle_deg))
        for name in BUCKET_GEOMS:
            geom = spec.geom(name)
            geom.priority = BUCKET_PRIORITY
            geom.friction[0] = tool_friction

        option = spec.option
        option.solver = SOLVER
        option.cone = CONE
        option.impratio = IMPRATIO
        option.iterations = SOLVER_ITERATIONS
        option.ls_iterations = SOLVER_LS_ITERATIONS
        option.tolerance = SOLVER_TOLERANCE
        option.noslip_iterations = 0
        option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
        option.sleep_tolerance = SLEEP_TOLERANCE_M_S
        spec.memory = max(spec.memory, ARENA_BYTES)

    def _zone_volume_m3(self) -> float:
        """Volume [m^3] of the undisturbed pile inside the digging zone."""
        xs = np.arange(self.pile.toe_x_m, self.x_back_m, VOLUME_GRID_M) + VOLUME_GRID_M / 2
        ys = np.arange(-self.half_width_m, self.half_width_m, VOLUME_GRID_M) + VOLUME_GRID_M / 2
        grid_x, grid_y = np.meshgrid(xs, ys)
        heights = self.pile.surface_height(grid_x, grid_y, self.repose_angle_rad)
        return float(heights.sum() * VOLUME_GRID_M**2)

    def _fill_lattice(self) -> tuple[float, np.ndarray]:
        """Particle radius [m] and centres (N, 3) [m] filling the zone, at most MAX_PARTICLES."""
        radius = PARTICLE_RADIUS_M
        while True:
            centres = self._hcp_lattice(radius)
            if len(centres) <= MAX_PARTICLES:
                break
            radius *= RADIUS_GROWTH
        if len(centres) == 0:
            raise ValueError(
                f"ParticleSoil: the pile {self.pile} is too small for particles of "
                f"radius {radius:.3f} m"
            )
        return radius, centres

    def _hcp_lattice(self, r: float) -> np.ndarray:
        """Hexagonal close packing (ABAB layers, every grain in a pocket of three) whose
        centres lie under the pile surface, inside the digging zone."""
        layer_dz, row_dy = 2 * r * math.sqrt(2.0 / 3.0), math.sqrt(3.0) * r
        n_layers = int(self.pile.height_m / layer_dz) + 1
        n_rows = int(2 * self.half_width_m / row_dy) + 2
        n_cols = int((self.x_back_m - self.pile.toe_x_m) / (2 * r)) + 2
        layer, row, col = np.meshgrid(
            np.arange(n_layers), np.arange(-n_rows, n_rows + 1), np.arange(n_cols), indexing="ij"
        )
        odd_layer = layer % 2
        x = self.pile.toe_x_m + r + 2 * r * col + r * (row % 2) + r * odd_layer
        y = row * row_dy + odd_layer * r / math.sqrt(3.0)
        z = r + layer * layer_dz
        surface = self.pile.surface_height(x, y, self.repose_angle_rad)
        keep = (z <= surface) & (np.abs(y) <= self.half_width_m - r) & (x <= self.x_back_m - r)
        return np.stack([x[keep], y[keep], z[keep]], axis=1)

    def _add_walls(self, spec: mujoco.MjSpec, friction: float) -> None:
        """The rigid rest of the pile: face slab and crest box on each side, a wall behind."""
        pile, t = self.pile, WALL_THICKNESS_M
        slope = self.repose_angle_rad
        face_length = pile.height_m / math.sin(slope)
        crest_x = pile.toe_x_m + pile.height_m / math.tan(slope)
        # face slab: top face on the face plane from the toe (extended below ground) to the crest
        extra = t
        along = (face_length - extra) / 2  # centre of the slab along the face from the toe
        centre_xz = (
            np.array([pile.toe_x_m, 0.0])
            + along * np.array([math.cos(slope), math.sin(slope)])
            - t / 2 * np.array([-math.sin(slope), math.cos(slope)])
        )
        face_quat = [math.cos(-slope / 2), 0.0, math.sin(-slope / 2), 0.0]
        crest_half_length = (self.x_back_m + t / 2 - crest_x) / 2
        boxes = []
        for side in (-1.0, 1.0):
            y = side * (self.half_width_m + t / 2)
            boxes.append(
                (
                    [centre_xz[0], y, centre_xz[1]],
                    face_quat,
                    [(face_length + extra) / 2, t / 2, t / 2],
                )
            )
            if crest_half_length > 0:
                boxes.append(
                    (
                        [crest_x + crest_half_length, y, pile.height_m / 2],
                        [1.0, 0.0, 0.0, 0.0],
                        [crest_half_length, t / 2, pile.height_m / 2],
                    )
                )
        boxes.append(
            (
                [self.x_back_m + t / 2, 0.0, pile.height_m / 2],
                [1.0, 0.0, 0.0, 0.0],
                [t / 2, self.half_width_m + t, pile.height_m / 2],
            )
        )
        for i, (pos, quat, size) in enumerate(boxes):
            spec.worldbody.add_geom(
                name=f"pile_wall_{i}",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=pos,
                quat=quat,
                size=size,
                contype=WALL_CONTYPE,
                conaffinity=0,
                condim=CONTACT_CONDIM,
                priority=PARTICLE_PRIORITY,
                friction=[friction, TORSION_FRICTION, 0.0],
                group=WALL_GROUP,
                rgba=list(PARTICLE_RGBA[:3]) + [0.3],
            )

    # ------------------------------------------------------------------ bind
    def bind(self, model: mujoco.MjModel, data: mujoco.MjData, machine: Machine) -> None:
        self.model, self.data, self.machine = model, data, machine
        first = model.body(self._first_body_name).id
        self._bodies = slice(first, first + self.n_particles)
        joint = int(model.body_jntadr[first])
        self._qpos = slice(
            int(model.jnt_qposadr[joint]), int(model.jnt_qposadr[joint]) + 3 * self.n_particles
        )
        self._dofs = slice(
            int(model.jnt_dofadr[joint]), int(model.jnt_dofadr[joint]) + 3 * self.n_particles
        )
        last = joint + 3 * self.n_particles - 1
        if (
            model.jnt_qposadr[last] != self._qpos.stop - 1
            or model.jnt_dofadr[last] != self._dofs.stop - 1
        ):
            raise RuntimeError("ParticleSoil: the particles' joints are not contiguous")
        self._polygon = self.bucket.polygon
        self._footprint_x = (
            self.pile.toe_x_m - FOOTPRINT_MARGIN_M,
            self.x_back_m + FOOTPRINT_MARGIN_M,
        )
        self._footprint_half_width = self.half_width_m + FOOTPRINT_MARGIN_M
        self.initial_mass_kg = self.n_particles * self.particle_mass_kg
        self._settled_qpos = self._settle()
        self._counts = (self.n_particles, 0, 0)
        self._depth_m = 0.0

    def _settle(self) -> np.ndarray:
        """Let the lattice settle under gravity with the machine parked far behind; return the
        particles' joint positions [m] (displacements from their lattice points)."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[0] = self.pile.toe_x_m - PARK_DISTANCE_M  # the machine's root x
        mujoco.mj_forward(m, d)
        trees = np.unique(m.body_treeid[self._bodies])
        steps = max(1, round(SETTLE_CHECK_S / m.opt.timestep))
        for _ in range(max(1, round(SETTLE_MAX_S / SETTLE_CHECK_S))):
            mujoco.mj_step(m, d, nstep=steps)
            if not d.tree_awake[trees].any():
                break
        settled = d.qpos[self._qpos].copy()
        mujoco.mj_resetData(m, d)
        return settled

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator) -> None:
        """Write the cached settled pile back (no shape noise: ``rng`` is not drawn from)."""
        m, d = self.model, self.data
        d.qpos[self._qpos] = self._settled_qpos
        d.qvel[self._dofs] = 0.0
        d.qacc_warmstart[self._dofs] = 0.0
        mujoco.mj_kinematics(m, d)
        self._tally()
        self.initial_mass_kg = self.n_particles * self.particle_mass_kg

    # ------------------------------------------------------------------ update
    def update(self, dt: float) -> None:
        """Recount the particles (the physics happened in ``mj_step``); ``dt`` is unused."""
        self._tally()

    def particle_positions(self) -> np.ndarray:
        """Particle centres (N, 3) [m] in the world frame."""
        return self.data.xpos[self._bodies]

    def _tally(self) -> None:
        d, machine = self.data, self.machine
        positions = self.particle_positions()
        rotation = d.xmat[machine.bucket_body].reshape(3, 3)
        local = (positions - d.xpos[machine.bucket_body]) @ rotation  # bucket frame
        in_bucket = (np.abs(local[:, 1]) <= self.bucket.width_m / 2) & _inside_polygon(
            local[:, 0], local[:, 2], self._polygon
        )
        x, y, z = positions[:, 0], positions[:, 1], positions[:, 2]
        in_footprint = (
            (x >= self._footprint_x[0])
            & (x <= self._footprint_x[1])
            & (np.abs(y) <= self._footprint_half_width)
        )
        spilled = ~in_bucket & ~in_footprint & (z < SPILL_HEIGHT_M)
        n_bucket, n_spilled = int(in_bucket.sum()), int(spilled.sum())
        self._counts = (self.n_particles - n_bucket - n_spilled, n_bucket, n_spilled)
        self.bucket_load_kg = n_bucket * self.particle_mass_kg
        self.spilled_kg = n_spilled * self.particle_mass_kg
        self._depth_m = self._edge_depth(positions, in_bucket)

    def _edge_depth(self, positions: np.ndarray, in_bucket: np.ndarray) -> float:
        """Depth [m] of the cutting edge below the highest particle top just ahead of it."""
        machine = self.machine
        edge = self.data.site_xpos[machine.cutting_edge_site]
        heading = machine.heading()
        lateral = np.array([-heading[1], heading[0]])
        rel = positions[:, :2] - edge[:2]
        ahead, aside = rel @ heading, rel @ lateral
        near = (
            ~in_bucket
            & (ahead >= -self.radius_m)
            & (ahead <= EDGE_WINDOW_AHEAD_M)
            & (np.abs(aside) <= self.bucket.width_m / 2)
        )
        if not near.any():
            return 0.0
        top = float(positions[near, 2].max()) + self.radius_m
        return max(top - float(edge[2]), 0.0)

    # ------------------------------------------------------------------ tallies
    @property
    def pile_mass_kg(self) -> float:
        return self._counts[0] * self.particle_mass_kg

    @property
    def particle_counts(self) -> tuple[int, int, int]:
        """Particles (in the pile, in the bucket, spilled); they sum to ``n_particles``."""
        return self._counts

    def cutting_depth_m(self) -> float:
        return self._depth_m


def _inside_polygon(u: np.ndarray, v: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule: which points (u, v) lie inside ``polygon`` (K, 2)."""
    inside = np.zeros(u.shape, dtype=bool)
    for (u0, v0), (u1, v1) in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        crosses = (v0 > v) != (v1 > v)
        with np.errstate(divide="ignore", invalid="ignore"):
            u_cross = u0 + (v - v0) * (u1 - u0) / (v1 - v0)
        inside ^= crosses & (u < u_cross)
    return inside
