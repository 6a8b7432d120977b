"""Fast soil: a heightfield pile carved by the bucket, resisted by the earthmoving equation.

Per update (a few per control step):

1. **Intake.** Every pile column whose (x, y) lies under the bucket's inside gives the
   bucket the material between the bucket floor and min(surface, bucket roof); material
   above collapses onto it. Intake stops at what the bucket can hold at its current pitch
   (``BucketGeometry.holding_volume_m3``); the rest stays in the pile.
2. **Spill.** Load above the holding volume slides out with time constant
   ``SPILL_TIME_CONSTANT_S`` and is tallied as spilled.
3. **Resistance.** The cutting-edge depth below the pile surface ahead of it sets the FEE
   force (``earthmoving.py``), scaled by ``BUCKET_RESISTANCE_FACTOR`` because a bucket
   also drags its side plates and floor through the material (a calibration constant,
   see docs/machine_model.md). MuJoCo applies it through three actuators on the
   cutting-edge site: ``soil_push`` resists forward motion along the heading (one-sided:
   soil pushes, never pulls), ``soil_side`` resists sideways motion of the buried bucket,
   and ``soil_lift`` resists vertical motion (breakout, ``breakout_force_n``: the uplift
   resistance of a buried plate after Meyerhof & Adams, 1968). Each is a damper ``F = -c v``
   clamped to a force cap, so MuJoCo's implicit integrator handles the stiffness while the
   soil stays perfectly plastic once the cap is reached. The vertical cap is the same up
   and down: an asymmetric damper on a machine vibrating on its tyres would rectify the
   vibration and ratchet the front axle off the ground. The ground contact, not the
   pile, carries a bucket pressed down.
4. **Payload.** The load's mass is written into the ``payload`` body, so booms, cylinders
   and tyres feel it.

Mass is conserved exactly: what leaves a column enters the bucket, what leaves the bucket
is counted as spilled.

**Intake through the mouth (option, not the default).** The default intake takes every
column under the bucket's inside, whichever way the material came in: a bucket lowered or
dragged onto the pile with its floor below the surface takes the material under its floor
and back plate too, which a real bucket pushes aside. With ``intake="mouth"`` the bucket
admits only what passes its mouth: every update, the mouth (cutting edge to top lip, over
the bucket width; ``MOUTH_SAMPLES`` x ``MOUTH_WIDTH_SAMPLES`` patches) sweeps a volume
along its outward normal, counted where the patch lies below the pile surface. That volume
is a credit that the column intake above may spend, columns nearest the mouth first; the
rest stays in the pile. Unspent credit fades with ``MOUTH_CREDIT_TIME_S``: the grid is
5 cm, so a column enters the bucket's footprint a moment after the mouth sweeps it.
``measure_mouth=True`` keeps the default intake and only tallies the swept volume
(``mouth_swept_m3``), to compare the two. docs/soil_models.md has the numbers.

**Resistance over the buried body (option, not the default).** By default the FEE depth
is the cutting edge's: a curled bucket, whose edge has risen while its heel is still deep
in the pile, meets only the shallow edge's resistance. With ``body_resistance=True`` the
FEE depth is that of the bucket's lowest point (the heel of a curled bucket, the edge of
a level one) below the pile surface ahead of the cutting edge, where the failure wedge
in front of the bucket comes out, wherever that lowest point is buried (the surface one
cell ahead of it lies above it); Reece's blade depth is the depth of the tool's deepest
point. The same depth sets the sideways resistance. The resistance beyond the edge's acts
on the floor's underside, which a curled bucket turns face-down and forward (rake = the
bucket's pitch): the FEE puts the soil's reaction on a blade of rake beta and tool
friction delta at cot(beta + delta) of its horizontal part vertically, here upward, so
the push damper acts along a direction slanted down by that ratio (capped so that its
horizontal part is the FEE force): pushed, a curled bucket rides up on the pile, as it
does on particles. The breakout keeps the edge's depth:
the soil a lifted bucket must raise lies over its floor and ahead of its edge, and the
columns over the bucket are the ones its intake carved (their material is the load, whose
weight the payload body carries). ``cutting_depth_m`` stays the edge's.
"""

from __future__ import annotations

import bisect
import functools
import math
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .base import BucketGeometry, SoilModel
from .earthmoving import GRAVITY_M_S2, cutting_force_n, fee_factors

if TYPE_CHECKING:
    from ..machine import Machine

RAKE_ANGLE_DEG = 65.0  # effective rake of a loader bucket's back plate (McKyes' beta) [deg]
BUCKET_RESISTANCE_FACTOR = 2.0  # bucket vs flat blade: side plates and floor friction
YIELD_SPEED_M_S = 0.002  # blade speed at which the full FEE force develops [m/s]
UPLIFT_COEFFICIENT = 0.95  # Meyerhof & Adams (1968) K_u for phi 30-40 deg: breakout shear
SIDE_RATIO = 1.0  # sideways resistance of a buried bucket / horizontal cutting force
SPILL_TIME_CONSTANT_S = 0.15  # how fast an over-full bucket sheds its excess [s]
MAX_PILE_HEIGHT_M = 2.0  # heightfield elevation range [m]
EDGE_SAMPLES = 7  # points along the cutting edge where the depth is sampled
HOLDING_TABLE_POINTS = 721  # pitch samples of the holding-volume table (0.5 deg apart)
MOUTH_SAMPLES = 16  # patches along the mouth (cutting edge to lip) for the swept volume
MOUTH_WIDTH_SAMPLES = 5  # patches across the bucket width for the swept volume
MOUTH_CREDIT_TIME_S = 0.2  # how long swept volume may wait for its columns [s]
INTAKE_MODES = ("footprint", "mouth")  # the default first
PILE_RGBA = (0.55, 0.47, 0.36, 1.0)
RENDER_SINK_M = 0.005  # drawn pile sits this far down so bare cells hide under the ground
CANDIDATE_MARGIN_M = 1e-6  # cells this far beyond the bucket's extent are still tested [m]
FLOOR_MARGIN_M = 1e-9  # a surface this far below the bucket's lowest point gives nothing [m]
UP = np.array([0.0, 0.0, 1.0])  # world vertical


@functools.lru_cache(maxsize=32)
def holding_table(bucket: BucketGeometry, repose_angle_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(pitch [rad], holding volume [m^3]) sampled over a full turn: the volume the bucket
    holds depends only on its pitch, its geometry and the repose angle, so the table is
    computed once per (bucket, repose angle) in a process, not once per simulator built
    (0.1 s each); both arrays are read-only."""
    pitch = np.linspace(-math.pi, math.pi, HOLDING_TABLE_POINTS)
    volume = np.array([bucket.holding_volume_m3(p, repose_angle_rad) for p in pitch])
    pitch.flags.writeable = False
    volume.flags.writeable = False
    return pitch, volume


class HeightfieldSoil(SoilModel):
    """The default, fast soil model (see module docstring)."""

    name = "heightfield"

    def __init__(
        self,
        material,
        pile,
        bucket,
        *,
        intake: str = "footprint",
        measure_mouth: bool = False,
        body_resistance: bool = False,
    ) -> None:
        """Options (``soil_options`` of the env):

        - ``intake``: ``"footprint"`` (default) takes every column under the bucket's
          inside; ``"mouth"`` only what the bucket mouth sweeps (module docstring).
        - ``measure_mouth``: tally the volume [m^3] the mouth sweeps below the pile surface
          (``mouth_swept_m3``) without changing the intake; ``intake="mouth"`` tallies it
          too.
        - ``body_resistance``: resist the bucket over the depth of its lowest buried point,
          not only its cutting edge's (module docstring).
        """
        super().__init__(material, pile, bucket)
        if intake not in INTAKE_MODES:
            raise ValueError(
                f"HeightfieldSoil.intake: must be one of {list(INTAKE_MODES)}, got {intake!r}"
            )
        if not isinstance(measure_mouth, bool):
            raise ValueError(
                f"HeightfieldSoil.measure_mouth: must be true or false, got {measure_mouth!r}"
            )
        if not isinstance(body_resistance, bool):
            raise ValueError(
                f"HeightfieldSoil.body_resistance: must be true or false, got {body_resistance!r}"
            )
        self.intake = intake
        self.body_resistance = body_resistance
        self.resistance_depth_m = 0.0  # the depth [m] the resistance was computed for
        self.measure_mouth = measure_mouth or intake == "mouth"
        self.mouth_swept_m3 = 0.0

    # ------------------------------------------------------------------ build
    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        pile = self.pile
        self._x0 = pile.toe_x_m - 0.3
        self._y0 = -(pile.half_width_m + pile.height_m / math.tan(self.repose_angle_rad) + 0.2)
        length_x, length_y = pile.length_m + 0.3, -2 * self._y0
        self.ncol = int(round(length_x / pile.cell_size_m)) + 1
        self.nrow = int(round(length_y / pile.cell_size_m)) + 1
        self.dx = length_x / (self.ncol - 1)
        self.dy = length_y / (self.nrow - 1)
        spec.add_hfield(
            name="pile",
            nrow=self.nrow,
            ncol=self.ncol,
            size=[length_x / 2, length_y / 2, MAX_PILE_HEIGHT_M, 0.01],
            userdata=[0.0] * (self.nrow * self.ncol),  # heights are written at reset
        )
        spec.worldbody.add_geom(
            name="pile",
            type=mujoco.mjtGeom.mjGEOM_HFIELD,
            hfieldname="pile",
            pos=[self._x0 + length_x / 2, self._y0 + length_y / 2, -RENDER_SINK_M],
            contype=0,
            conaffinity=0,
            rgba=list(PILE_RGBA),
        )
        for name in ("soil_push", "soil_side", "soil_lift"):
            actuator = spec.add_actuator(name=name, target="cutting_edge")
            actuator.trntype = mujoco.mjtTrn.mjTRN_SITE
            actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            actuator.gainprm[0] = 0.0
            actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-1.0, 1.0]  # rewritten every update
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.ctrlrange = [-1.0, 1.0]  # unused: gain 0

    def bind(self, model: mujoco.MjModel, data: mujoco.MjData, machine: Machine) -> None:
        self.model, self.data, self.machine = model, data, machine
        self._hfield = model.hfield("pile").id
        self._adr = int(model.hfield_adr[self._hfield])
        self._push = model.actuator("soil_push").id
        self._side = model.actuator("soil_side").id
        self._lift = model.actuator("soil_lift").id
        self._payload = model.body("payload").id
        xs = self._x0 + self.dx * np.arange(self.ncol)
        ys = self._y0 + self.dy * np.arange(self.nrow)
        self._grid_x, self._grid_y = np.meshgrid(xs, ys)  # (nrow, ncol)
        self._cell_x, self._cell_y = xs, ys[:, None]  # the same cell centres, to broadcast
        # MuJoCo's array attributes build a new NumPy view at every access (~1 us each, a
        # few dozen per control step): keep the views, they share the model's memory
        self._xmat, self._xpos = data.xmat, data.xpos
        self._gear, self._forcerange = model.actuator_gear, model.actuator_forcerange
        self._biasprm = model.actuator_biasprm
        self._body_mass, self._body_inertia = model.body_mass, model.body_inertia
        # each soil damper's direction (gear), force range and bias, as row views written
        # element by element at every update (a row assigned from a tuple converts it to an
        # array first: ~1 us each)
        self._damper_rows = {
            name: (model.actuator_gear[i, :3], model.actuator_forcerange[i], self._biasprm[i])
            for name, i in (("push", self._push), ("side", self._side), ("lift", self._lift))
        }
        self._direction = np.zeros(3)  # a soil damper's world direction, filled in place
        self._payload_inertia = model.body_inertia[self._payload]
        self._payload_written_kg = -1.0  # the payload mass last written to the model [kg]
        self.cell_area_m2 = self.dx * self.dy
        self._factors = fee_factors(
            rake_angle_rad=math.radians(RAKE_ANGLE_DEG),
            friction_angle_rad=self.repose_angle_rad,
            tool_friction_angle_rad=math.radians(self.material.tool_friction_angle_deg),
        )
        polygon = self.bucket.polygon
        self._polygon_local = np.zeros((len(polygon), 3))
        self._polygon_local[:, 0], self._polygon_local[:, 2] = polygon[:, 0], polygon[:, 1]
        # the polygon's edges as (start, end) vertex indices
        self._edge_pairs = [(i, (i + 1) % len(polygon)) for i in range(len(polygon))]
        # the holding volume depends only on pitch: tabulate it once (as lists: read by
        # ``_holding_volume_m3`` with plain floats)
        pitch_table, volume_table = holding_table(self.bucket, self.repose_angle_rad)
        self._pitch_table, self._holding_table = pitch_table.tolist(), volume_table.tolist()
        # constants of the breakout force (``breakout_force_n``), computed once
        self._floor_m = float(self.bucket.cutting_edge_xz[0] - self.bucket.polygon[0, 0])
        self._tan_repose = math.tan(self.repose_angle_rad)
        self._edge_offsets_list = (
            np.linspace(-0.45, 0.45, EDGE_SAMPLES) * self.bucket.width_m
        ).tolist()
        self._bind_far_box()
        self.heights = np.zeros((self.nrow, self.ncol))  # pile surface [m]; reset/update write it
        self._pile_mass_kg: float | None = None  # of ``heights``; None: to be summed
        self._bind_mouth()

    def _bind_far_box(self) -> None:
        """The box [m] the bucket's hinge must leave for the bucket to be far from the pile
        (``update``): the grid's cell centres grown by the bucket's reach and two cells.

        The reach bounds, in the horizontal plane, how far from the hinge anything an
        update reads can lie: a corner of the intake's footprint (a polygon vertex's
        distance, at most its norm, plus half the width) and a sample point of the depth
        (the cutting edge, a vertex, plus one cell ahead, plus at most half the width
        across). Beyond the box by more than that, the footprint's window is empty and
        every sample point rounds to a cell off the grid (two cells of margin), so the
        intake takes nothing and the depths are 0, as the full update finds."""
        reach_m = (
            float(np.linalg.norm(self._polygon_local, axis=1).max())
            + self.bucket.width_m / 2
            + self.dx
        )
        grow_m = reach_m + 2 * max(self.dx, self.dy)
        x_end, y_end = self._x0 + (self.ncol - 1) * self.dx, self._y0 + (self.nrow - 1) * self.dy
        self._far_box = (self._x0 - grow_m, x_end + grow_m, self._y0 - grow_m, y_end + grow_m)

    def _bind_mouth(self) -> None:
        """Mouth patch centres (bucket frame) and the mouth's outward normal (bucket frame)."""
        edge, lip = self.bucket.cutting_edge_xz, self.bucket.lip_xz
        along = (np.arange(MOUTH_SAMPLES) + 0.5) / MOUTH_SAMPLES
        across = ((np.arange(MOUTH_WIDTH_SAMPLES) + 0.5) / MOUTH_WIDTH_SAMPLES - 0.5) * (
            self.bucket.width_m
        )
        xz = edge + along[:, None] * (lip - edge)  # (K, 2)
        points = np.zeros((MOUTH_SAMPLES, MOUTH_WIDTH_SAMPLES, 3))
        points[..., 0] = xz[:, None, 0]
        points[..., 1] = across[None, :]
        points[..., 2] = xz[:, None, 1]
        self._mouth_local = points.reshape(-1, 3)
        mouth_m = float(np.linalg.norm(lip - edge))
        self._mouth_patch_m2 = mouth_m * self.bucket.width_m / len(self._mouth_local)
        tangent = (lip - edge) / mouth_m
        normal = np.array([tangent[1], -tangent[0]])
        if normal @ (self.bucket.centroid_xz() - (edge + lip) / 2) > 0:
            normal = -normal  # outward: away from the inside
        self._mouth_normal_local = np.array([normal[0], 0.0, normal[1]])
        self._mouth_previous: np.ndarray | None = None
        self._mouth_credit_m3 = 0.0

    def reset(self, rng: np.random.Generator) -> None:
        heights = self.pile.surface_height(self._grid_x, self._grid_y, self.repose_angle_rad)
        if self.pile.roughness_m > 0:
            heights = heights + self._undulation(rng) * (heights > 0)
        self.heights = np.clip(heights, 0.0, MAX_PILE_HEIGHT_M)
        self._pile_changed()
        self.bucket_load_kg = 0.0
        self.spilled_kg = 0.0
        self._depth_m = 0.0
        self.resistance_depth_m = 0.0
        self.mouth_swept_m3 = 0.0
        self._mouth_previous = None
        self._mouth_credit_m3 = 0.0
        self.initial_mass_kg = self.pile_mass_kg
        self._write_payload()
        self._write_resistance(0.0, (1.0, 0.0), 0.0)
        self._sync_hfield()

    def _undulation(self, rng: np.random.Generator) -> np.ndarray:
        """Smooth random bumps of amplitude ``roughness_m`` (three random plane waves)."""
        bumps = np.zeros_like(self._grid_x)
        for _ in range(3):
            wavelength = rng.uniform(0.4, 1.5)
            angle, phase = rng.uniform(0, 2 * np.pi, size=2)
            k = 2 * np.pi / wavelength
            bumps += np.sin(
                k * (np.cos(angle) * self._grid_x + np.sin(angle) * self._grid_y) + phase
            )
        return self.pile.roughness_m * bumps / 3

    # ------------------------------------------------------------------ tallies
    @property
    def pile_mass_kg(self) -> float:
        if self._pile_mass_kg is None:
            self._pile_mass_kg = float(
                self.heights.sum() * self.cell_area_m2 * self.material.density_kg_m3
            )
        return self._pile_mass_kg

    def _pile_changed(self) -> None:
        """Have the pile's mass summed again when next read; called wherever ``heights``
        change. The heightfield holds ~12,000 cells: summed at every step's ``info`` it
        cost more than the intake, and after every intake twice per step while digging;
        summed when read after a change, it is the same sum of the same heights."""
        self._pile_mass_kg = None

    def cutting_depth_m(self) -> float:
        return self._depth_m

    # ------------------------------------------------------------------ update
    def update(self, dt: float) -> None:
        """One soil update (module docstring). The per-call cost is Python's: the few
        points of the bucket are plain floats, NumPy runs only the matrix products (kept
        as they were: their last bits follow the BLAS kernel, see docs/performance.md)
        and the intake's arrays over the pile's cells."""
        machine = self.machine
        heading_xy = machine.heading_xy()
        rotation = self._xmat[machine.bucket_body].reshape(3, 3)
        hinge = self._xpos[machine.bucket_body]
        pitch = machine.bucket_pitch()
        hold_m3 = self._holding_volume_m3(pitch)
        if self.measure_mouth:
            swept_m3 = self._mouth_sweep_m3(hinge, rotation)
            self.mouth_swept_m3 += swept_m3
            fade = math.exp(-dt / MOUTH_CREDIT_TIME_S)
            self._mouth_credit_m3 = self._mouth_credit_m3 * fade + swept_m3
        x_min, x_max, y_min, y_max = self._far_box
        if not (x_min <= hinge.item(0) <= x_max and y_min <= hinge.item(1) <= y_max):
            if not (math.isfinite(hinge.item(0)) and math.isfinite(hinge.item(1))):
                # NaN fails every comparison and lands here: the physics diverged
                raise RuntimeError(
                    "simulation diverged: the heightfield soil got a non-finite bucket "
                    f"position {hinge.tolist()} m; check the condition overrides and "
                    "machine parameters"
                )
            # far from the pile (``_bind_far_box``): what the full update finds there,
            # without the polygon, the intake and the depth samples: nothing taken, depths
            # 0, no resistance; the load still spills and the dampers turn with the bucket
            self._spill(dt, hold_m3)
            self._depth_m = self.resistance_depth_m = 0.0
            self._write_resistance(0.0, heading_xy, 0.0, to_bucket=rotation.T)
            self._write_payload(unless_unchanged=True)
            return
        # bucket inside polygon in world coordinates (np.dot: the products of ``@``, bit
        # for bit, at half its call overhead)
        world = hinge + np.dot(self._polygon_local, rotation.T)
        if hold_m3 - self.bucket_load_kg / self.material.density_kg_m3 > 0.0:  # room left
            # the polygon in the vertical plane through the hinge: (s along heading, z)
            s_poly = np.dot(world[:, :2] - hinge[:2], np.array(heading_xy))
            self._intake(hinge, heading_xy, s_poly, world[:, 2], hold_m3)
        self._spill(dt, hold_m3)

        edge = world[1]
        self._depth_m = self._edge_depth(edge, heading_xy)
        depth_m, lift_ratio = self._depth_m, 0.0
        force = self._resistance_n(depth_m)
        if self.body_resistance:
            lowest = world[int(np.argmin(world[:, 2]))]
            depth_m = self._body_depth(edge, lowest, heading_xy)
            edge_force = force
            force = self._resistance_n(depth_m)
            lift_ratio = self._underside_lift_ratio(pitch, force, edge_force)
        self.resistance_depth_m = depth_m
        self._write_resistance(
            force,
            heading_xy,
            self.breakout_force_n(self._depth_m),
            lift_ratio=lift_ratio,
            to_bucket=rotation.T,
        )
        self._write_payload(unless_unchanged=True)

    def _spill(self, dt: float, hold_m3: float) -> None:
        """Load above ``hold_m3`` slides out (module docstring, 2)."""
        density = self.material.density_kg_m3
        load_m3 = self.bucket_load_kg / density
        if load_m3 > hold_m3:
            spill_m3 = (load_m3 - hold_m3) * (1.0 - math.exp(-dt / SPILL_TIME_CONSTANT_S))
            self.bucket_load_kg -= spill_m3 * density
            self.spilled_kg += spill_m3 * density

    def _holding_volume_m3(self, pitch_rad: float) -> float:
        """Holding volume [m^3] at ``pitch_rad`` from the table: ``np.interp``'s arithmetic
        (the interval's slope times the offset from its left end, plus its left value; a
        table point exactly; the end values beyond the ends) on plain floats, a third of
        its cost for one point."""
        pitches, volumes = self._pitch_table, self._holding_table
        j = bisect.bisect_right(pitches, pitch_rad) - 1
        if j < 0:
            return volumes[0]
        if j >= len(pitches) - 1:
            return volumes[-1]
        if pitches[j] == pitch_rad:
            return volumes[j]
        slope = (volumes[j + 1] - volumes[j]) / (pitches[j + 1] - pitches[j])
        return slope * (pitch_rad - pitches[j]) + volumes[j]

    def _resistance_n(self, depth_m: float) -> float:
        """Horizontal resistance [N] of the bucket meeting the pile ``depth_m`` deep."""
        return BUCKET_RESISTANCE_FACTOR * cutting_force_n(
            self._factors,
            depth_m=depth_m,
            width_m=self.bucket.width_m,
            density_kg_m3=self.material.density_kg_m3,
            cohesion_pa=self.material.cohesion_pa,
        )

    def _underside_lift_ratio(self, pitch_rad: float, force_n: float, edge_force_n: float) -> float:
        """Upward over horizontal soil force on a curled bucket (module docstring).

        The resistance beyond the edge's (``force_n - edge_force_n``) acts on the floor's
        underside, a blade facing forward-down at rake ``pitch_rad``: the soil's reaction
        leans up by cot(pitch + delta) of its horizontal part (the FEE's vertical
        component for a blade of rake beta and tool friction delta, McKyes 1985, with the
        blade turned face-down)."""
        body_n = force_n - edge_force_n
        if force_n <= 0.0 or body_n <= 0.0 or pitch_rad <= 0.0:
            return 0.0
        angle = pitch_rad + math.radians(self.material.tool_friction_angle_deg)
        if angle >= math.pi / 2:
            return 0.0
        return body_n / math.tan(angle) / force_n

    def _window(
        self, x_min: float, x_max: float, y_min: float, y_max: float
    ) -> tuple[slice, slice] | None:
        """Grid index window (rows, cols) covering the box [x_min, x_max] x [y_min, y_max] [m]."""
        c0 = int(math.floor((x_min - self._x0) / self.dx))
        c1 = int(math.ceil((x_max - self._x0) / self.dx)) + 1
        r0 = int(math.floor((y_min - self._y0) / self.dy))
        r1 = int(math.ceil((y_max - self._y0) / self.dy)) + 1
        c0, r0 = max(c0, 0), max(r0, 0)
        c1, r1 = min(c1, self.ncol), min(r1, self.nrow)
        if c0 >= c1 or r0 >= r1:
            return None
        return slice(r0, r1), slice(c0, c1)

    def _intake(
        self,
        hinge: np.ndarray,
        heading: tuple[float, float] | np.ndarray,
        s_poly: np.ndarray,
        z_poly: np.ndarray,
        hold_m3: float,
    ) -> None:
        """Move the material under the bucket's inside into the bucket (module docstring, 1).

        Plain floats for the footprint's few corners and NumPy only over the cells that can
        hold material (inside the bucket's width and its extent along the heading): the
        arithmetic per cell, and the order of the sum, are those of the whole-window form.
        """
        density = self.material.density_kg_m3
        room_m3 = hold_m3 - self.bucket_load_kg / density
        if room_m3 <= 0.0:
            return
        hx, hy = float(heading[0]), float(heading[1])
        lx, ly = -hy, hx  # lateral: the heading turned 90 deg to the left
        half_width = self.bucket.width_m / 2
        h0, h1 = float(hinge[0]), float(hinge[1])
        s_values = s_poly.tolist()
        s_min, s_max = min(s_values), max(s_values)
        # footprint: the polygon's extent along the heading, the bucket width across it
        corners_x, corners_y = [], []
        for s_corner in (s_min, s_max):
            for side in (-1.0, 1.0):
                across = side * half_width
                corners_x.append(h0 + s_corner * hx + across * lx)
                corners_y.append(h1 + s_corner * hy + across * ly)
        window = self._window(min(corners_x), max(corners_x), min(corners_y), max(corners_y))
        if window is None:
            return
        rows, cols = window
        heights = self.heights[window]
        z_values = z_poly.tolist()
        # the ufuncs' reduce and maximum directly: what ndarray.max, .min and np.clip(x, 0,
        # None) call, without their Python wrappers (~0.3 us each)
        if np.maximum.reduce(heights, axis=None) <= min(z_values):
            return
        # vertical extent of the bucket polygon at each cell's s: intersect with its edges
        # (edges seen end-on along the heading hold no cell); the polygon's edges as plain
        # floats: (start s, start z, rise, span along s) of each edge that holds cells
        edges = []
        for a, b in self._edge_pairs:
            span = s_values[b] - s_values[a]
            if abs(span) >= 1e-9:
                edges.append((s_values[a], z_values[a], z_values[b] - z_values[a], span))
        if not edges:
            return
        rel_x = self._cell_x[cols] - h0  # (cols,)
        rel_y = self._cell_y[rows] - h1  # (rows, 1)
        s = rel_x * hx + rel_y * hy  # (rows, cols): along the heading
        inside_width = np.abs(rel_x * lx + rel_y * ly) <= half_width
        # only cells within the polygon's extent along the heading can lie on one of its
        # edges (the margin keeps any cell whose edge parameter rounds into [0, 1])
        candidate = inside_width & (s >= s_min - CANDIDATE_MARGIN_M)
        candidate &= s <= s_max + CANDIDATE_MARGIN_M
        # and only cells whose surface lies above the polygon's lowest point can give: the
        # floor over a cell, interpolated along an edge, lies below that point by rounding
        # at most (~1e-15 m, far less than the margin), so a lower cell's column is
        # negative and it gives nothing either way
        candidate &= heights > min(z_values) - FLOOR_MARGIN_M
        if not candidate.any():
            return
        surface = heights[candidate]
        # one row per edge, one column per cell: NumPy reduces across rows in one pass over
        # the cells, along a short last axis row by row (~6x slower here, measured)
        s_a, z_a, rise, span = np.array(edges).T[:, :, None]  # each (edges, 1)
        t = (s[candidate] - s_a) / span
        on_edge = (t >= 0.0) & (t <= 1.0)
        z_at = z_a + t * rise
        # lowest and highest crossing over the edges each cell lies on (inf, -inf: none;
        # np.where then a reduce: ~40% faster here than a reduce's own ``where=``)
        z_floor = np.minimum.reduce(np.where(on_edge, z_at, np.inf), axis=0)
        z_roof = np.maximum.reduce(np.where(on_edge, z_at, -np.inf), axis=0)
        # a cell on no edge (outside the polygon) has z_roof -inf and z_floor +inf: its
        # column is -inf, which the clip at 0 turns into the 0.0 it takes
        column = np.minimum(surface, z_roof) - z_floor
        taken = np.zeros(heights.shape)
        taken[candidate] = np.maximum(column, 0.0)
        taken_m3 = float(np.add.reduce(taken, axis=None)) * self.cell_area_m2
        if taken_m3 <= 0.0:
            return
        if self.intake == "mouth":
            floor = np.zeros(heights.shape)  # cells outside the candidates give nothing
            floor[candidate] = np.where(np.isfinite(z_floor), z_floor, 0.0)
            taken, taken_m3 = self._through_mouth(taken, s, floor, s_poly, z_poly, room_m3)
            if taken_m3 <= 0.0:
                return
        elif taken_m3 > room_m3:
            taken *= room_m3 / taken_m3
            taken_m3 = room_m3
        heights -= taken  # a view: the window of ``self.heights``
        self._pile_changed()
        self.bucket_load_kg += taken_m3 * density

    def _mouth_sweep_m3(self, hinge: np.ndarray, rotation: np.ndarray) -> float:
        """Pile volume [m^3] the mouth swept into the bucket since the last update: each
        patch's displacement along the mouth's outward normal times its area, where the
        patch lies below the pile surface (0 on the first update after a reset)."""
        points = hinge + self._mouth_local @ rotation.T
        previous, self._mouth_previous = self._mouth_previous, points
        if previous is None:
            return 0.0
        advance = (points - previous) @ (rotation @ self._mouth_normal_local)
        cols = np.rint((points[:, 0] - self._x0) / self.dx).astype(int)
        rows = np.rint((points[:, 1] - self._y0) / self.dy).astype(int)
        on_grid = (cols >= 0) & (cols < self.ncol) & (rows >= 0) & (rows < self.nrow)
        surface = np.zeros(len(points))
        surface[on_grid] = self.heights[rows[on_grid], cols[on_grid]]
        buried = on_grid & (points[:, 2] < surface)
        return float(np.clip(advance[buried], 0.0, None).sum()) * self._mouth_patch_m2

    def _through_mouth(
        self,
        taken: np.ndarray,
        s: np.ndarray,
        z_floor: np.ndarray,
        s_poly: np.ndarray,
        z_poly: np.ndarray,
        room_m3: float,
    ) -> tuple[np.ndarray, float]:
        """Limit the column intake ``taken`` [m] to the mouth's swept-volume credit and the
        room left, spending it on the columns nearest the mouth first; return the heights
        taken and their volume [m^3]."""
        budget_m3 = min(self._mouth_credit_m3, room_m3)
        if budget_m3 <= 0.0:
            return taken, 0.0
        edge, lip = np.array([s_poly[1], z_poly[1]]), np.array([s_poly[2], z_poly[2]])
        tangent = (lip - edge) / max(float(np.linalg.norm(lip - edge)), 1e-9)
        # distance behind the mouth line of each column's middle of what it gives
        middle_z = z_floor + taken / 2
        behind = np.abs((s - edge[0]) * tangent[1] - (middle_z - edge[1]) * tangent[0])
        flat_taken = taken.ravel()
        order = np.argsort(np.where(flat_taken > 0, behind.ravel(), np.inf), kind="stable")
        volumes = flat_taken[order] * self.cell_area_m2
        before = np.cumsum(volumes) - volumes
        granted = np.clip(budget_m3 - before, 0.0, volumes)
        limited = np.zeros_like(flat_taken)
        limited[order] = granted / self.cell_area_m2
        taken_m3 = float(granted.sum())
        self._mouth_credit_m3 -= taken_m3
        return limited.reshape(taken.shape), taken_m3

    def _edge_depth(self, edge: np.ndarray, heading: np.ndarray) -> float:
        """Mean depth [m] of the cutting edge below the pile surface one cell ahead of it.

        Plain Python over the few sample points: NumPy's per-call overhead would dominate.
        """
        hx, hy = float(heading[0]), float(heading[1])
        x0, y0, dx, dy, ncol, nrow = self._x0, self._y0, self.dx, self.dy, self.ncol, self.nrow
        edge_x, edge_y, edge_z = edge.tolist()
        ahead_x, ahead_y = edge_x + hx * dx, edge_y + hy * dx
        heights, total, inside = self.heights, 0.0, False
        for offset in self._edge_offsets_list:
            col = round((ahead_x - hy * offset - x0) / dx)
            row = round((ahead_y + hx * offset - y0) / dy)
            if 0 <= col < ncol and 0 <= row < nrow:
                inside = True
                total += max(heights.item(row, col) - edge_z, 0.0)
        return total / len(self._edge_offsets_list) if inside else 0.0

    def _body_depth(self, edge: np.ndarray, lowest: np.ndarray, heading: np.ndarray) -> float:
        """Mean depth [m] of the bucket's lowest point below the pile surface one cell ahead
        of the cutting edge, over the edge's sample points: where the point one cell ahead
        of the lowest point (at the same offset across the bucket) lies above the surface,
        the bucket is not buried there and the edge's own depth counts. At least the edge's
        depth (``_edge_depth``), equal to it for a level bucket."""
        hx, hy = float(heading[0]), float(heading[1])
        ahead_x, ahead_y = float(edge[0]) + hx * self.dx, float(edge[1]) + hy * self.dx
        low_x, low_y = float(lowest[0]) + hx * self.dx, float(lowest[1]) + hy * self.dx
        edge_z, low_z = float(edge[2]), min(float(lowest[2]), float(edge[2]))
        heights, total, inside = self.heights, 0.0, False
        for offset in self._edge_offsets_list:
            col = round((ahead_x - hy * offset - self._x0) / self.dx)
            row = round((ahead_y + hx * offset - self._y0) / self.dy)
            if not (0 <= col < self.ncol and 0 <= row < self.nrow):
                continue
            inside = True
            surface = float(heights[row, col])
            bottom = edge_z
            low_col = round((low_x - hy * offset - self._x0) / self.dx)
            low_row = round((low_y + hx * offset - self._y0) / self.dy)
            low_on_grid = 0 <= low_col < self.ncol and 0 <= low_row < self.nrow
            if low_on_grid and float(heights[low_row, low_col]) > low_z:
                bottom = low_z
            total += max(surface - bottom, 0.0)
        return total / len(self._edge_offsets_list) if inside else 0.0

    # ------------------------------------------------------------------ MuJoCo writes
    def breakout_force_n(self, depth_m: float) -> float:
        """Resistance [N] of the pile to lifting the bucket floor ``depth_m`` below its surface.

        Meyerhof & Adams (1968), a strip anchor pulled up through sand (shallow case): the
        shear on the two failure planes, ``w (gamma d^2 K_u tan phi + 2 c d)``, plus the
        weight of the soil column over the bucket floor, ``gamma w L d``, less what the
        bucket already holds (its weight is the payload body's). 0 outside the pile.
        """
        if depth_m <= 0.0:
            return 0.0
        m = self.material
        gamma = m.density_kg_m3 * GRAVITY_M_S2  # unit weight [N/m^3]
        width = self.bucket.width_m
        shear = width * (
            gamma * depth_m**2 * UPLIFT_COEFFICIENT * self._tan_repose
            + 2.0 * m.cohesion_pa * depth_m
        )
        column = gamma * width * self._floor_m * depth_m - self.bucket_load_kg * GRAVITY_M_S2
        return shear + max(column, 0.0)

    def _write_resistance(
        self,
        force_n: float,
        heading: tuple[float, float] | np.ndarray,
        breakout_n: float,
        *,
        lift_ratio: float = 0.0,
        to_bucket: np.ndarray | None = None,
    ) -> None:
        """Caps and directions of the three soil dampers. ``force_n``: horizontal
        resistance [N]; ``lift_ratio``: upward over horizontal (0: horizontal only); the
        push damper then acts along the slanted direction, capped so that its horizontal
        part is ``force_n``. ``to_bucket``: world to bucket frame, if already at hand."""
        rows, direction = self._damper_rows, self._direction
        if to_bucket is None:
            to_bucket = self._xmat[self.machine.bucket_body].reshape(3, 3).T
        hx, hy = float(heading[0]), float(heading[1])
        # each direction into the damper's gear row: np.dot's ``out`` writes the product of
        # ``@`` there, bit for bit (the same BLAS call)
        gear, forcerange, biasprm = rows["push"]
        if lift_ratio > 0.0:
            slant = math.hypot(1.0, lift_ratio)
            direction[0], direction[1], direction[2] = hx / slant, hy / slant, -lift_ratio / slant
            push_n = force_n * slant  # forward-down
        else:
            direction[0], direction[1], direction[2] = hx, hy, 0.0
            push_n = force_n
        np.dot(to_bucket, direction, out=gear)
        forcerange[0], forcerange[1] = -push_n, 0.0
        biasprm[2] = -push_n / YIELD_SPEED_M_S
        gear, forcerange, biasprm = rows["side"]
        direction[0], direction[1], direction[2] = -hy, hx, 0.0
        np.dot(to_bucket, direction, out=gear)
        side = SIDE_RATIO * force_n
        forcerange[0], forcerange[1] = -side, side
        biasprm[2] = -side / YIELD_SPEED_M_S
        gear, forcerange, biasprm = rows["lift"]
        np.dot(to_bucket, UP, out=gear)
        forcerange[0], forcerange[1] = -breakout_n, breakout_n
        biasprm[2] = -breakout_n / YIELD_SPEED_M_S

    def _write_payload(self, *, unless_unchanged: bool = False) -> None:
        """The load's mass and inertia into the payload body; ``unless_unchanged``: not
        when the mass is the one last written (the bucket outside the pile)."""
        mass = max(self.bucket_load_kg, 1e-6)
        if unless_unchanged and mass == self._payload_written_kg:
            return
        self._body_mass[self._payload] = mass
        self._payload_inertia[:] = mass * 0.02  # ~0.25 m radius of gyration
        self._payload_written_kg = mass

    def _sync_hfield(self) -> None:
        data = self.model.hfield_data
        data[self._adr : self._adr + self.heights.size] = self.heights.ravel() / MAX_PILE_HEIGHT_M

    def prepare_render(self, renderer: mujoco.Renderer) -> None:
        self._sync_hfield()
        renderer._gl_context.make_current()  # upload needs the renderer's GL context current
        mujoco.mjr_uploadHField(self.model, renderer._mjr_context, self._hfield)
