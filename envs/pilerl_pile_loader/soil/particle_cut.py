"""The particle soil's cohesion checked without the bucket: an unsupported vertical cut.

A block of the particle soil's grains (``particles.add_grain``: the same spheres, friction,
contacts, bonds and solver) is laid on its close-packed lattice between a rough back wall
(the rest of the pile: grains bond to it), two frictionless side walls (plane strain) and a
gate, on the ground (neither bonds, as the site's floor and the steel do not); it settles for
``SETTLE_S`` against the gate, then the gate goes and the face is free. Terzaghi's critical
height of a vertical cut in a soil of cohesion c, friction angle phi and bulk density gamma
is H_c = 4 c / (gamma g) tan(45 deg + phi / 2) (Terzaghi 1943, Theoretical Soil Mechanics;
a Coulomb wedge with the tension zone counted: an upper bound, the exact limit-analysis
value is ~0.96 of it). A face lower than H_c should stand, one well above it collapse, and
a loose block (c = 0) slump whatever its height.

``run_cut`` measures what the face did ``WATCH_S`` after release: a face collapses within a
fraction of a second (a grain falls half its diameter in ~0.1 s); MuJoCo's soft friction
lets a standing face creep slowly (docs/soil_models.md, "Cohesion"), so the verdict depends
on how long one watches, and this one watches for as long as a scoop loads a face.

Used by tests/envs/test_particle_cohesion.py and benchmarks/particle_cohesion.py.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from .bonds import GrainBonds, step_physics
from .particles import (
    ARENA_BYTES_PER_GRAIN,
    CONE,
    CONTACT_CONDIM,
    CONTACT_TIMECONST_S,
    GROUND_CONTYPE,
    HCP_SOLID_FRACTION,
    PARTICLE_FRICTION_RATIO,
    PARTICLE_PRIORITY,
    SOLVER,
    SOLVER_ITERATIONS,
    SOLVER_LS_ITERATIONS,
    SOLVER_TOLERANCE,
    WALL_CONTYPE,
    add_grain,
    bond_force_n,
)

GRAVITY_M_S2 = 9.81
TIMESTEP_S = 0.002  # the env's physics step (assets/wheel_loader.xml)
SETTLE_S = 0.3  # the block settles against the gate this long [s]
WATCH_S = 1.5  # the face is judged this long after the gate goes [s]
LENGTH_RATIO = 0.9  # block length behind the face / its height (the failure wedge: ~0.55)
MIN_LENGTH_DIAMETERS = 4  # at least this many grains behind the face
ROWS = 4  # grain rows across (between the frictionless side walls)
WALL_M = 0.2  # wall thickness [m]
FRICTIONLESS_PRIORITY = PARTICLE_PRIORITY + 1  # the side walls' and gate's condim 1 governs


def critical_height_m(cohesion_pa: float, friction_angle_deg: float, density_kg_m3: float) -> float:
    """Terzaghi's critical height [m] of an unsupported vertical cut."""
    return (
        4.0
        * cohesion_pa
        / (density_kg_m3 * GRAVITY_M_S2)
        * math.tan(math.radians(45.0 + friction_angle_deg / 2.0))
    )


@dataclass(frozen=True)
class CutResult:
    """What a released face did ``WATCH_S`` after the gate went (grain diameter D)."""

    height_m: float  # the block's height at release (top of the highest grain) [m]
    grains: int
    bond_n: float  # each grain's bond force G [N]
    moved_fraction: float  # grains that moved more than D / 2
    max_displacement_m: float  # the furthest any grain moved [m]
    face_top_drop_m: float  # how far the top of the front grain column fell [m]
    cpu_s: float  # CPU time of settling and watching [s]


def build_cut(
    height_m: float,
    cohesion_pa: float,
    friction_angle_deg: float,
    density_kg_m3: float,
    diameter_m: float,
) -> tuple[mujoco.MjModel, np.ndarray, float]:
    """The model (grains ``g0``...), its lattice sites (N, 3) [m] and the face's x [m]."""
    r = diameter_m / 2.0
    length = max(LENGTH_RATIO * height_m, MIN_LENGTH_DIAMETERS * diameter_m)
    spec = mujoco.MjSpec()
    option = spec.option
    option.timestep = TIMESTEP_S
    option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    option.solver = SOLVER
    option.cone = CONE
    option.iterations = SOLVER_ITERATIONS
    option.ls_iterations = SOLVER_LS_ITERATIONS
    option.tolerance = SOLVER_TOLERANCE
    friction = PARTICLE_FRICTION_RATIO * math.tan(math.radians(friction_angle_deg))
    contact = {"solref": [CONTACT_TIMECONST_S, 1.0]}  # the pile's grain contacts
    rough = {
        "condim": CONTACT_CONDIM,
        "priority": PARTICLE_PRIORITY,
        "friction": [friction, 0.0, 0.0],
        **contact,
    }
    smooth = {"condim": 1, "priority": FRICTIONLESS_PRIORITY, **contact}
    world = spec.worldbody
    world.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[5.0, 5.0, 0.1],
        contype=GROUND_CONTYPE,
        conaffinity=GROUND_CONTYPE,
        **rough,
    )
    layer_dz, row_dy = 2.0 * r * math.sqrt(2.0 / 3.0), math.sqrt(3.0) * r
    sites = []
    for layer in range(int((height_m - 2.0 * r) / layer_dz) + 1):
        odd = layer % 2
        for row in range(ROWS):
            x = r + r * (row % 2) + r * odd
            while x <= length - r + 1e-9:
                sites.append((x, row * row_dy + odd * r / math.sqrt(3.0), r + layer * layer_dz))
                x += 2.0 * r
    sites = np.array(sites)
    sites[:, 1] -= (sites[:, 1].max() + sites[:, 1].min()) / 2.0
    half_width = sites[:, 1].max() + r
    face_x = sites[:, 0].max() + r
    wall_h = sites[:, 2].max() + 3.0 * r
    t = WALL_M
    walls = world.add_body(name="walls")
    box = mujoco.mjtGeom.mjGEOM_BOX
    walls.add_geom(
        type=box,
        pos=[-t / 2, 0.0, wall_h / 2],
        size=[t / 2, half_width + t, wall_h / 2],
        contype=WALL_CONTYPE,
        conaffinity=0,
        **rough,
    )
    # the side walls and the gate are not soil: like the ground, grains do not bond to them
    for side in (-1.0, 1.0):
        walls.add_geom(
            type=box,
            pos=[face_x / 2, side * (half_width + t / 2), wall_h / 2],
            size=[face_x / 2 + t, t / 2, wall_h / 2],
            contype=GROUND_CONTYPE,
            conaffinity=0,
            **smooth,
        )
    walls.add_geom(
        name="gate",
        type=box,
        pos=[face_x + t / 2, 0.0, wall_h / 2],
        size=[t / 2, half_width, wall_h / 2],
        contype=GROUND_CONTYPE,
        conaffinity=0,
        **smooth,
    )
    # a grain's mass: the bulk density times its share of the close-packed lattice
    mass = density_kg_m3 * math.pi * diameter_m**3 / 6.0 / HCP_SOLID_FRACTION
    bond = bond_force_n(cohesion_pa, friction_angle_deg, diameter_m)
    for i, site in enumerate(sites):
        add_grain(spec, f"g{i}", site, r, mass, friction, contact, bond)
    n = len(sites)
    spec.memory = ARENA_BYTES_PER_GRAIN * n
    return spec.compile(), sites, face_x


def run_cut(
    height_m: float,
    cohesion_pa: float,
    friction_angle_deg: float,
    density_kg_m3: float,
    diameter_m: float,
    watch_s: float = WATCH_S,
) -> CutResult:
    """Settle the block against the gate, remove it, watch the face (module docstring)."""
    for name, value in (("height_m", height_m), ("diameter_m", diameter_m), ("watch_s", watch_s)):
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"run_cut: {name} must be a finite number > 0, got {value!r}")
    if not (math.isfinite(cohesion_pa) and cohesion_pa >= 0.0):
        raise ValueError(f"run_cut: cohesion_pa must be a finite number >= 0, got {cohesion_pa!r}")
    model, sites, face_x = build_cut(
        height_m, cohesion_pa, friction_angle_deg, density_kg_m3, diameter_m
    )
    data = mujoco.MjData(model)
    bodies = np.array([model.body(f"g{i}").id for i in range(len(sites))])
    bond = bond_force_n(cohesion_pa, friction_angle_deg, diameter_m)
    bonds = GrainBonds(model, bodies, bond) if bond > 0 else None

    def advance(seconds: float) -> None:
        step_physics(model, data, round(seconds / model.opt.timestep), bonds)

    start = time.process_time()
    advance(SETTLE_S)
    before = data.xpos[bodies].copy()
    model.geom_contype[model.geom("gate").id] = 0
    advance(watch_s)
    after = data.xpos[bodies]
    moved = np.linalg.norm(after - before, axis=1)
    r = diameter_m / 2.0
    front = sites[:, 0] > face_x - 3.0 * r  # the grains of the face column at release
    return CutResult(
        height_m=float(before[:, 2].max() + r),
        grains=len(sites),
        bond_n=bond_force_n(cohesion_pa, friction_angle_deg, diameter_m),
        moved_fraction=float(np.mean(moved > r)),
        max_displacement_m=float(moved.max()),
        face_top_drop_m=float(before[front, 2].max() - after[front, 2].max()),
        cpu_s=time.process_time() - start,
    )
