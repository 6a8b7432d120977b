"""Cross-check soil: a pile of MuJoCo spheres that the bucket pushes and scoops by contact.

No earthmoving equation and no soil actuators: cutting resistance, intake, heaping and
spill all come out of MuJoCo's contact solver. It is slower than ``heightfield.py``; it is
meant to cross-check the fast model's fills and forces, not to train on. Cohesion
(``Material.cohesion_pa``) bonds the grains (below, "Cohesion"); at c = 0 they are loose.

**Resolution.** Granular flow through an opening jams when the opening spans only a few
grain diameters, so the grain size is set by the bucket mouth (cutting edge to top lip,
0.64 m): ``mouth_grains`` diameters across it (default ``MOUTH_GRAINS`` = 6: 10.7 cm
grains). Real 0-32 mm gravel gives ~25; at 3-4 the fill jams low (see
docs/soil_models.md for how fill converges with resolution). ``max_particles`` caps the
moving grains: while the zone would hold more, the radius grows. Each grain's mass is its
share of the bulk mass of the pile region it fills (bulk density x zone volume / grain
count), so masses and fill fractions are in the heightfield model's units, whatever the
resolution: a bucket packed as densely as the pile reads its rated capacity, less the gaps
a grain wide along its plates (``packed_bucket_fill``: 0.72 at 3 grains across the mouth,
0.86 at 4, 0.87 at 6, 0.93 at 8), the most a struck bucket can read at that resolution.
The default pile has 637 moving grains of 1.6 kg; a rated load is ~280 of them.

**Non-rotating grains.** Each particle moves on three slide joints (x, y, z), not a free
joint. Free spheres roll, and a pile of rolling spheres slumps to ~20 deg whatever their
friction; gravel interlocks. Without rotation, sliding friction alone holds the pile, with
3 instead of 6 degrees of freedom per particle and no rolling-friction rows per contact.
The particle friction is ``PARTICLE_FRICTION_RATIO x tan(friction angle)``: non-rotating
spheres in a packing are stronger than their contact friction; with this ratio the
close-packed face stands at the angle of repose and a collapsing block of them runs out to
~33 deg for dry gravel's 38 deg (slump test).

**Cohesion.** Each grain of a cohesive material (c > 0) pulls its contacts closed with a
constant force G, spread evenly over the body's n contacts along each one's normal: MuJoCo's
body adhesion (an adhesion actuator with a body transmission, which the pile used until
session 34), computed once per physics step by ``bonds.GrainBonds`` and applied through
three motors on the grain's slides. So a grain-grain contact is held by G/n_a + G/n_b and
the bond forces around a grain sum to about 2 G whatever its coordination number k
(exactly, where the neighbours have as many contacts). The bond strength G comes from soil
mechanics, not from fills:

- Rumpf (1958, Chem. Ing. Tech. 30: 144): a packing of spheres of diameter D, porosity
  eps and k bonds of force F per sphere breaks in tension at
  sigma_t = (1 - eps) k F / (pi D^2); here k F = 2 G, so sigma_t = 2 (1 - eps) G / (pi D^2);
- Mohr-Coulomb's uniaxial tensile strength (its envelope, no tension cut-off):
  sigma_t = 2 c cos phi / (1 + sin phi) = 2 c tan(45 deg - phi / 2);
- so G = pi D^2 sigma_t / (2 (1 - eps)) = pi D^2 c tan(45 deg - phi / 2) / (1 - eps)
  (``bond_force_n``), with 1 - eps = 0.7405, the grains' close-packed lattice. G scales
  with D^2, so the packing's strength is the same at every resolution. At the default
  resolution (10.7 cm) winter_c's c = 2000 Pa gives G = 52 N (3.7 grain weights),
  winter_a's 4000 Pa 103 N.

Assumptions: the bonds are brittle and have no range (MuJoCo makes a contact only while
the spheres overlap: no margin or gap, so a bond holds while grains touch and is gone once
they part); the packing is isotropic (Rumpf); the shear strength is not set separately: it
is the grains' friction on the bonds' extra normal force. Where the derivation's
approximations land is checked without the bucket, against Terzaghi's critical height of
an unsupported vertical cut, H_c = 4 c / (gamma g) tan(45 deg + phi / 2)
(``particle_cut.py``, tests/envs/test_particle_cohesion.py, docs/soil_models.md): faces of
winter_c's grains (H_c 0.97 m) of 0.48, 0.74 and 0.92 H_c stand for 1.5 s, 1.19 H_c starts
to fail and 1.46 H_c collapses; loose, 0.48 H_c slumps. So ``COHESION_CALIBRATION`` is 1
(no factor). MuJoCo's soft friction lets a loaded face creep (0.74 H_c: 6 cm in 4 s;
0.92 H_c falls within 4 s), and 8 cm grains fail a little lower (0.96 H_c within 1.5 s).
A grain with few contacts holds each harder (a pair of free grains: 2 G).

Nothing bonds to the steel or to the ground: cohesion is the soil's strength against
itself; soil-tool adhesion is a separate property, which the heightfield's cutting force
(no adhesion term) leaves out too, and the ground is the site's firm floor, which a bucket
scrapes clean (bonded to it, a grain under the cutting edge could not get away: pinched
between the plate and the ground, winter_c seed 1 shot one 2 m high). The bonds act on
every contact of the grain's body, so a cohesive grain's sphere touches only the pile
(grains, walls, and the static core, moved to its own bit ``COHESIVE_CORE_CONTYPE``) and a
copy of it on a welded, massless child body (``{name}_unbonded``) touches only the machine
and the ground. Cost: one pass over the contacts per physics step; MuJoCo's adhesion
actuators cost per awake grain times contacts (a prototype of the cut test, 738 awake
grains: 10.3 -> 20.6 ms per step; 5.6-6.0 ms of a 15.4 ms winter_c digging step), which is
why they were replaced (docs/soil_models.md, "Speed"). Bonded grains are allowed to sleep
(MuJoCo keeps actuated bodies awake by default). Option ``cohesion=False`` keeps the
grains loose; at c = 0 the model is the loose one, bit for bit.

**Contact stiffness.** MuJoCo's soft contacts are normalised by mass: at rest under a
normal force F a grain of mass m sinks ``(1 - d) tau^2 F / (c m)`` into what it touches
(``tau`` the time constant of ``solref``, ``d`` the impedance of ``solimp``, ``c`` a factor of
the pyramidal friction cone: ``contact_parameters``). By default (``contact_modulus_pa=None``)
the grains, core and walls have ``tau`` = ``CONTACT_TIMECONST_S`` = 2 physics steps (0.004 s
at 500 Hz, the stiffest MuJoCo integrates stably) and MuJoCo's default impedance, and the
bucket plates, whose contact priority outranks the grains' so that their ``solref`` /
``solimp`` govern bucket-grain contacts, have MuJoCo's defaults (0.02 s) at dry gravel's
steel friction (tan 25 deg) and the same compliance at every other (``steel_contact``:
the pyramidal cone stiffens a contact by 2 / (mu^2 (1 + mu^2)), 3.4x on winter_c's
tan 15 deg with MuJoCo's defaults, nearly a hard constraint that the capped CG left
unresolved: grains sank a whole radius into the plates and were thrown out of the pile at
tens of m/s). Under the same stress the lighter grains of a finer pile sink deeper (~1/D^2
of their diameter), into each other and into the steel. With 0.01 s grain contacts the
fill fell with resolution (docs/soil_models.md). The option ``contact_modulus_pa`` gives
every grain contact a stiffness set by the material and proportional to the grain diameter
D instead (``contact_modulus_pa`` x D against steel, the core and the walls, half that
between two grains: a packing's modulus is then the same at every resolution), for the
bucket plates too: ``tau`` stays, the impedance carries the resolution,
``1 - d = c m / (K tau^2)`` (below an impedance of 0.7 the time constant gets longer
instead). Measured, it made the finer piles fill less, not converge: the soft bucket
contacts had been letting fine grains sink into the cutting edge (docs/soil_models.md), so
it is not the default. The slump test reads the same with the default contacts at 0.01 s
and 0.004 s (a released block of grains settles at 31 and 33 deg mean angle).

**Digging zone.** Only the part of the pile the bucket reaches is made of moving grains:
up to ``PARTICLE_ZONE_DEPTH_M`` behind the toe, ``PARTICLE_ZONE_HALF_WIDTH_M`` either side
of the bucket's path (the walls go snug against the lattice: 1.28 m and 0.72 m at the
default resolution, the bucket is 1.3 m wide), and down to ``ACTIVE_DEPTH_M`` below the
pile surface. (The nominal expert's scoops move grains up to 0.91 m behind the toe, 0.32 m
deep and 0.66 m aside.)
Deeper lattice sites are the *static core*: spheres of the same size fixed to a static
body, so grains rest on a rough bed as in the pile, and the bucket meets the core as a
solid were it to dig that deep. The pile is uniform along its toe line, so ``reset``
slides the zone sideways to where the start pose aims the bucket (``AIM_DEPTH_M`` into the
pile). Beyond the zone the pile is rigid: invisible static boxes shaped like the pile
(face slab + crest box on both sides, a wall behind) hold the grains as the rest of the
pile would. They touch only grains (collision bit ``WALL_CONTYPE``), never the machine.

**Pile at reset.** The particles are laid on a hexagonal close-packed lattice filling the
pile shape and settled once in ``bind`` with the machine parked far away; the settled
positions are cached and written back exactly at every ``reset``, where the resting pile
falls asleep at once. The pile is the same every episode (no shape noise, ``rng`` is not
used), so a seed fixes the whole episode.

**Solver** (global MuJoCo options, so the machine's own contacts use them too). The
grains touching each other and the bucket form one contact island that Newton's
factorisation makes far too slow (a scoop at the default resolution did not finish in
5 min), so this model uses CG with a pyramidal friction cone and ``solver_iterations``
iterations (default ``SOLVER_ITERATIONS``), the largest cost of a step. Driving and lifting
in free air, the machine then matches the default Newton solver to a few per cent (drive
pressure 0.14 MPa off on average, of about 4 MPa; 14 iterations: 0.22 MPa, 10: 0.76 MPa).
In the pile the cap leaves contact forces unconverged, and the fill depends on it too
(docs/soil_models.md): with the earlier soft 0.01 s contacts, at 6 grains across the
mouth 20 and 40 iterations gave the same mean fill and 14 a quarter less, and at 8, 20 and
40 the same (``conf/soil/particles_fine.yaml`` sets 40); with today's 0.004 s contacts
the nominal expert's summer seed 0 filled 0.471 at 20, 0.237 at 30 and 0.212 at 40
(session 30). The tyres' contacts are in the same solve:
until session 30 the default was 20 iterations, and with the bucket in the pile CG stopped
at the cap on every step, leaving the tyre-ground contacts unresolved (the tyres left the
ground on 29-47 % of the physics steps of a winter_c drive-in, the front ones on ~1/3 in
summer); the drive, a stiff velocity servo on the wheels, read the hopping tyres'
traction, and on ice p_d chattered between 2 MPa and the relief (docs/soil_models.md,
"The drive pressure's chatter on ice"). At 30 p_d reads the slip cap, as on the heightfield
(the tyres were logged on the ground at 40 and 100 iterations; at 30 only p_d was); the
pile also stays packed (~3 times the contacts of the 20-iteration pile once awake), so
digging costs about twice as long per simulated second. Fewer iterations run faster but
are not a cheaper version of the same pile.
MuJoCo's body sleeping freezes a resting pile, so driving up to it costs almost nothing.

**Sleeping.** MuJoCo wakes or puts to sleep a whole contact island, and the pile the
machine touches is one island, so while the machine digs every grain is awake. Small
islands still fall asleep, a grain or two at a time, and are woken again soon after. Each
time any tree falls asleep, ``mj_step`` recomputes the whole step (``mj_forwardSkip`` in
its ``mj_advance``: the constraint solve again), and with the bucket in the default pile
that happened on about a third of the physics steps (summer, the `rise` operator that was
the nominal expert until session 33, seed 0; 1-2 grains at a time): nearly 30 % of a digging
step's time. So while the machine touches a
grain (any contact between a grain and a machine geom at the last ``update``), the grains'
sleep policy is ``mjSLEEP_NEVER``; once it touches none, their compiled policy is back and
the pile can settle asleep (``reset`` restores it too). Kept awake, those few grains move
as they would with sleeping off (the same trajectory, bit for bit, as disabling sleep with
the bucket in the pile); the fill is unchanged within the seeds' spread, and that
operator's summer scoops run 1.4x faster (0.44x to 0.62x real time, CPU time; today's
stall expert digs longer, 0.44x with the rule, not measured without it; the bonded
winter_c pile: no faster; docs/soil_models.md, "Speed", session 33). Option
``sleep_in_contact=True`` lets them sleep as before.

**Tallies** (every ``update``; particle counts times the particle mass):

- *in the bucket*: the particle centre lies inside the bucket's interior polygon
  (``BucketGeometry.polygon``, bucket frame x-z) and within ``|y_local| <= width / 2``;
- *spilled*: not in the bucket, centre outside the pile footprint (the digging zone and the
  rigid boxes around it, plus ``FOOTPRINT_MARGIN_M`` in front of the toe) and lower than
  ``SPILL_HEIGHT_M`` (it has landed off the pile);
- *pile*: every other particle (on the footprint, or still in the air).

So ``pile_mass_kg + bucket_load_kg + spilled_kg`` equals the initial mass at every call.
The ``payload`` body is left alone: the particles carry their own mass.

**Cutting depth** (``cutting_depth_m`` [m], as of the last ``update``, measured when
read): the heightfield's definition, the mean over ``EDGE_SAMPLES`` points across the
cutting edge, one heightfield cell ahead of it, of how far the pile surface there lies
above the edge (0 where it lies below). The surface over a point is the top of the highest
grain covering it (within ``COVER_RADIUS_RATIO`` radii, horizontally) that belongs to the
pile: resting on the ground or the static core through a chain of touching grains, not in
the bucket. Grains thrown into the air or carried on the machine are not the pile surface:
the contact solver can throw grains metres high, and the highest grain anywhere across the
bucket up to 0.25 m ahead, which this reading used to be, then read metres of depth.

**Fill** (``fill_measure``). ``"count"`` (default): the load's mass over the mass of a
rated bucket at the pile's bulk density, so a bucket packed as densely as the pile reads
``packed_bucket_fill`` (the plates leave gaps a grain wide). ``"volume"``: the bulk volume
of the load, measured the way the heightfield measures its intake: vertical columns
(``VOLUME_CELL_M`` square, in the heading frame) over the bucket's inside, each filled from
the bucket floor up to the top of the highest grain in the bucket that covers it (a grain
covers the columns within ``COVER_RADIUS_RATIO`` radii of its centre: the radius whose
disks cover a close-packed layer), at most to the bucket's roof or mouth. Voids between
grains under that surface count, as they do in a bulk volume; grains heaped above the
mouth do not, as in ``"count"``. Mass bookkeeping is the same for both.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .base import SoilModel
from .bonds import GrainBonds, add_bond_motors, step_physics

if TYPE_CHECKING:
    from ..machine import Machine

# ---- particles (see module docstring)
MOUTH_GRAINS = 6.0  # default resolution: grain diameters across the bucket mouth
MAX_PARTICLES = 3000  # default cap on the moving grains (the default pile has fewer)
RADIUS_GROWTH = 1.05  # radius step while a lattice holds more than max_particles
PARTICLE_FRICTION_RATIO = 0.7  # particle friction / tan(friction angle) (slump-test fit)
PARTICLE_ZONE_DEPTH_M = 1.3  # particles from the toe to this far behind it [m]
PARTICLE_ZONE_HALF_WIDTH_M = 0.75  # particles within this of the bucket's path [m]
ACTIVE_DEPTH_M = 0.4  # grains deeper than this below the surface form the static core [m]
AIM_DEPTH_M = 0.5  # the zone is centred where the bucket's path is this far into the pile [m]
PARTICLE_RGBA = (0.55, 0.47, 0.36, 1.0)
# ---- contacts (assets/wheel_loader.xml: ground contype 1 / conaffinity 1, machine 2 / 1)
PARTICLE_CONTYPE = 1  # seen by the ground and the machine (their conaffinity 1)
PARTICLE_CONAFFINITY = 1 | 2 | 4  # sees other particles, the machine, the core and the walls
CORE_CONTYPE = 1  # the static core: seen by particles and the machine (not the ground: static)
WALL_CONTYPE = 4  # the rigid rest of the pile: seen by particles only
WALL_THICKNESS_M = 0.6  # thickness of the boxes around the zone [m]
WALL_GROUP = 3  # geom group that MuJoCo does not draw by default
CONTACT_CONDIM = 3  # sliding friction only: the particles cannot rotate
CONTACT_TIMECONST_S = 0.004  # stiffest stable contacts: 2 physics steps at 500 Hz [s]
# a grain's normal contact stiffness against steel per metre of its diameter [N/m per m]
# for contact_modulus_pa (not the default: docs/soil_models.md); a packing of them has a
# bulk modulus of about 0.47 x this
GRAIN_CONTACT_MODULUS_PA = 5e7
# MuJoCo impedances the grains' contacts use: below 0.7 a grain pressed on a plate with the
# pyramidal cone bounced off at 500 Hz (a softer contact gets a longer time constant
# instead); nearer to 1 the solver hardly converges (refused)
CONTACT_IMPEDANCE_RANGE = (0.7, 0.999)
# the bucket plates' contacts by default: MuJoCo's default solref / solimp at this steel
# friction angle (dry gravel's, summer's: where the default contacts were chosen and
# measured); at any other steel friction the impedance makes up for the pyramidal cone's
# 2 / (mu^2 (1 + mu^2)) stiffening (``steel_contact``), so that a grain's normal contact
# with the plates is as stiff whatever the friction (docs/soil_models.md, "Grains thrown
# out of the pile on low-friction steel")
STEEL_REFERENCE_FRICTION_ANGLE_DEG = 25.0
# below this the compensation's time constant exceeds ~0.07 s (3.4x MuJoCo's 0.02 s): the
# plates' contacts would hardly push back in an impact; refused (wet steel on ice ~ 3 deg
# is not a pile-loading condition here)
MIN_STEEL_FRICTION_ANGLE_DEG = 5.0
MUJOCO_SOLREF = (0.02, 1.0)  # MuJoCo's default solref: time constant [s], damping ratio
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)  # MuJoCo's default solimp
SOLIMP_WIDTH_M = 0.001  # MuJoCo's default (unused: the impedance is flat, d0 = dmax)
PARTICLE_PRIORITY = 2  # > ground's 1: particle friction governs particle-ground contacts
BUCKET_PRIORITY = 3  # > particles': steel friction tan(delta) governs bucket contacts
BUCKET_GEOMS = ("bucket_floor", "bucket_back", "bucket_top", "bucket_side_l", "bucket_side_r")
# bevelled_edge option: a steel strip on the floor plate's front whose top face rises at
# this angle from ahead of the edge, at the plate's underside, back to the plate's top
BEVEL_ANGLE_DEG = 30.0
BEVEL_HALF_THICKNESS_M = 0.005
BEVEL_MASS_KG = 0.5
# ---- solver (global options; see module docstring)
SOLVER = mujoco.mjtSolver.mjSOL_CG
CONE = mujoco.mjtCone.mjCONE_PYRAMIDAL
# 30, not 20: at 20 the tyres' contacts were left unresolved in the pile and on ice the
# drive pressure chattered (module docstring, "Solver"; docs/soil_models.md)
SOLVER_ITERATIONS = 30
SOLVER_LS_ITERATIONS = 10
SOLVER_TOLERANCE = 1e-6
ARENA_BYTES_PER_GRAIN = 24_000  # MuJoCo's arena (contacts, constraint rows) per sphere [B]
SLEEP_TOLERANCE_M_S = 5e-3  # a resting particle island below this speed sleeps [m/s]
# ---- settling in bind
PARK_DISTANCE_M = 40.0  # the machine waits this far behind the toe while the pile settles [m]
SETTLE_AWAKE_S = 0.5  # settling time before the pile may fall asleep [s]
SETTLE_MAX_S = 3.0  # settling stops once the pile sleeps, at the latest after this [s]
SETTLE_CHECK_S = 0.1  # how often settling checks whether the pile sleeps [s]
# ---- tallies
FOOTPRINT_MARGIN_M = 0.25  # the footprint reaches this far in front of the toe [m]
SPILL_HEIGHT_M = 0.5  # off the footprint, a particle centre below this has spilled [m]
EDGE_SAMPLES = 7  # points across the cutting edge where its depth is sampled (as the heightfield)
EDGE_SAMPLE_SPAN = 0.9  # the sample points span this share of the bucket width (as the heightfield)
TOUCH_GAP_RATIO = 0.25  # grains touch across a gap of at most this share of their diameter
VOLUME_GRID_M = 0.01  # grid step of the zone-volume integral [m]
FILL_MEASURES = ("count", "volume")  # the default first
VOLUME_CELL_M = 0.02  # column size of the load's bulk volume (fill_measure="volume") [m]
COVER_RADIUS_RATIO = 2.0 / math.sqrt(3.0)  # disks of this x radius cover a packed layer
# ---- cohesion (module docstring, "Cohesion")
HCP_SOLID_FRACTION = math.pi / (3.0 * math.sqrt(2.0))  # 1 - porosity of the grains' lattice
# a factor on the Rumpf / Mohr-Coulomb bond force (bond_force_n): 1, none needed, since faces
# below Terzaghi's critical height stand and faces well above it fall
# (tests/envs/test_particle_cohesion.py checks it)
COHESION_CALIBRATION = 1.0
# collision bits of a cohesive pile: its grains' soil geoms touch grains, core and walls
# (bonded); their unbonded copies touch the machine and the ground (assets/wheel_loader.xml:
# machine contype 2, ground contype / conaffinity 1); the core moves to its own bit
COHESIVE_GRAIN_CONTYPE = 8
COHESIVE_CORE_CONTYPE = 16
COHESIVE_GRAIN_CONAFFINITY = WALL_CONTYPE | COHESIVE_GRAIN_CONTYPE | COHESIVE_CORE_CONTYPE
MACHINE_CONTYPE = 2
GROUND_CONTYPE = 1
UNBONDED_CONAFFINITY = MACHINE_CONTYPE | GROUND_CONTYPE
COHESIVE_CORE_CONAFFINITY = MACHINE_CONTYPE  # the machine still meets the core
UNBONDED_MASS_KG = 1e-6  # the unbonded copy's welded child body


class ParticleSoil(SoilModel):
    """A pile of non-rotating MuJoCo spheres (see module docstring).

    Attributes set by ``add_to_spec``: ``radius_m`` [m], ``n_particles``,
    ``particle_mass_kg`` [kg], ``zone_volume_m3`` [m^3]; by ``reset``: ``zone_offset_y_m`` [m].
    """

    name = "particles"

    def __init__(
        self,
        material,
        pile,
        bucket,
        *,
        max_particles: int = MAX_PARTICLES,
        mouth_grains: float = MOUTH_GRAINS,
        solver_iterations: int = SOLVER_ITERATIONS,
        fill_measure: str = "count",
        contact_timeconst_s: float = CONTACT_TIMECONST_S,
        contact_modulus_pa: float | None = None,
        bevelled_edge: bool = False,
        zone_scale: float = 1.0,
        cohesion: bool = True,
        sleep_in_contact: bool = False,
    ) -> None:
        """Options (``soil_options`` of the env), the resolution:

        - ``mouth_grains``: grain diameters across the bucket mouth (cutting edge to lip);
          sets the grain size. The default 6 gives grains of 10.7 cm diameter.
        - ``max_particles``: a cap on the moving grains; while the zone would hold more,
          the radius grows (so the mouth spans fewer grains than asked).
        - ``solver_iterations``: MuJoCo's CG iterations per physics step (global: the
          machine's contacts too); fewer run faster but leave contact forces, and with
          them the fill, less converged (docs/soil_models.md).
        - ``fill_measure``: ``"count"`` (default, the load's mass) or ``"volume"`` (the
          load's bulk volume under its surface; module docstring).
        - ``contact_timeconst_s``: the grains' contact time constant [s] (MuJoCo's
          ``solref``, critically damped); MuJoCo integrates no faster than 2 physics steps
          (0.004 s at 500 Hz). With ``contact_modulus_pa`` it sets how fast a contact
          responds, not how stiff it is.
        - ``contact_modulus_pa``: ``None`` (default): MuJoCo's mass-normalised contacts
          (default impedance; under a load F a grain of mass m sinks about (F / m) tau^2,
          so the lighter grains of a finer pile sink deeper), the bucket's contacts at
          MuJoCo's defaults made as compliant at every steel friction as at tan 25 deg
          (``steel_contact``). A number: a grain's normal contact stiffness against steel
          per metre of its diameter [N/m per m] (between two grains half that), the same
          at every resolution, for the bucket plates too (module docstring;
          ``GRAIN_CONTACT_MODULUS_PA`` is the value docs/soil_models.md measured: it
          made the finer piles fill less, not converge).
        - ``bevelled_edge``: a ``BEVEL_ANGLE_DEG`` chamfer on the front of the bucket's
          floor plate (``bucket_bevel``, steel like the plates): the blunt 2.4 cm plate
          face meets a small grain near its equator and pushes it ahead; the chamfer lifts
          it over the edge, as a real bevelled cutting edge does (docs/soil_models.md).
          The edge moves ``0.024 / tan(BEVEL_ANGLE_DEG)`` m (4 cm) forward.
        - ``zone_scale``: scales the digging zone's extent behind the toe, its half width
          and its active depth (``PARTICLE_ZONE_DEPTH_M``, ``PARTICLE_ZONE_HALF_WIDTH_M``,
          ``ACTIVE_DEPTH_M``); above 1 the grains the bucket pushes meet the zone's walls
          and the static core later, at the cost of more grains.
        - ``cohesion``: ``True`` (default): the material's ``cohesion_pa`` bonds the grains
          (module docstring, "Cohesion"); ``False``: loose grains whatever the material
          (the pile as it was before cohesion was represented, for comparison).
        - ``sleep_in_contact``: ``False`` (default): no grain falls asleep while the machine
          touches a grain (module docstring, "Sleeping"); ``True``: grains fall asleep
          whenever MuJoCo finds their island at rest, as before session 33 (slower, for
          comparison).
        """
        super().__init__(material, pile, bucket)
        if not (isinstance(max_particles, int) and 20 <= max_particles <= 5000):
            raise ValueError(
                f"ParticleSoil.max_particles: must be an int in [20, 5000], got {max_particles!r}"
            )
        if isinstance(mouth_grains, bool) or not (
            isinstance(mouth_grains, int | float) and 1.0 <= mouth_grains <= 12.0
        ):
            raise ValueError(
                f"ParticleSoil.mouth_grains: must be a number in [1, 12], got {mouth_grains!r}"
            )
        if isinstance(solver_iterations, bool) or not (
            isinstance(solver_iterations, int) and 1 <= solver_iterations <= 1000
        ):
            raise ValueError(
                "ParticleSoil.solver_iterations: must be an int in [1, 1000], "
                f"got {solver_iterations!r}"
            )
        if fill_measure not in FILL_MEASURES:
            raise ValueError(
                f"ParticleSoil.fill_measure: must be one of {list(FILL_MEASURES)}, "
                f"got {fill_measure!r}"
            )
        if isinstance(contact_timeconst_s, bool) or not (
            isinstance(contact_timeconst_s, int | float) and 0.002 <= contact_timeconst_s <= 0.1
        ):
            raise ValueError(
                "ParticleSoil.contact_timeconst_s: must be a number in [0.002, 0.1] s, "
                f"got {contact_timeconst_s!r}"
            )
        if contact_modulus_pa is not None and (
            isinstance(contact_modulus_pa, bool)
            or not (
                isinstance(contact_modulus_pa, int | float) and 1e5 <= contact_modulus_pa <= 1e10
            )
        ):
            raise ValueError(
                "ParticleSoil.contact_modulus_pa: must be None or a number in [1e5, 1e10] Pa, "
                f"got {contact_modulus_pa!r}"
            )
        if not isinstance(bevelled_edge, bool):
            raise ValueError(
                f"ParticleSoil.bevelled_edge: must be true or false, got {bevelled_edge!r}"
            )
        self.bevelled_edge = bevelled_edge
        if isinstance(zone_scale, bool) or not (
            isinstance(zone_scale, int | float) and 0.5 <= zone_scale <= 2.0
        ):
            raise ValueError(
                f"ParticleSoil.zone_scale: must be a number in [0.5, 2], got {zone_scale!r}"
            )
        self.zone_scale = float(zone_scale)
        if not isinstance(cohesion, bool):
            raise ValueError(f"ParticleSoil.cohesion: must be true or false, got {cohesion!r}")
        self.cohesion = cohesion
        if not isinstance(sleep_in_contact, bool):
            raise ValueError(
                f"ParticleSoil.sleep_in_contact: must be true or false, got {sleep_in_contact!r}"
            )
        self.sleep_in_contact = sleep_in_contact
        self.bonds: GrainBonds | None = None  # a cohesive pile's, from ``bind``
        self.active_depth_m = ACTIVE_DEPTH_M * self.zone_scale
        self.fill_measure = fill_measure
        self.contact_timeconst_s = float(contact_timeconst_s)
        self.contact_modulus_pa = None if contact_modulus_pa is None else float(contact_modulus_pa)
        self.max_particles = max_particles
        self.mouth_grains = float(mouth_grains)
        self.solver_iterations = solver_iterations

    @property
    def mouth_length_m(self) -> float:
        """Width [m] of the bucket mouth: the cutting edge to the top lip."""
        return float(np.linalg.norm(self.bucket.lip_xz - self.bucket.cutting_edge_xz))

    @property
    def mouth_diameters(self) -> float:
        """How many grain diameters the bucket mouth spans at the built resolution."""
        return self.mouth_length_m / (2.0 * self.radius_m)

    # ------------------------------------------------------------------ build
    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        pile = self.pile
        scale = self.zone_scale
        self.x_back_m = pile.toe_x_m + min(PARTICLE_ZONE_DEPTH_M * scale, pile.length_m)
        self.half_width_m = min(PARTICLE_ZONE_HALF_WIDTH_M * scale, pile.half_width_m)
        self.radius_m, sites = self._fill_lattice()
        # the walls go snug against the lattice, so that no grain can slump into a gap
        self.x_back_m = float(sites[:, 0].max()) + self.radius_m
        self.half_width_m = float(np.abs(sites[:, 1]).max()) + self.radius_m
        moving = self._depth_below_surface(sites) <= self.active_depth_m
        self.lattice, self.core = sites[moving], sites[~moving]
        self.zone_volume_m3 = self._zone_volume_m3()
        self.n_particles = len(self.lattice)
        self.particle_mass_kg = self.material.density_kg_m3 * self.zone_volume_m3 / self.n_particles
        rated_kg = self.material.density_kg_m3 * self.bucket.rated_volume_m3
        self.packed_bucket_fill = len(self.packed_bucket_sites()) * self.particle_mass_kg / rated_kg

        friction = PARTICLE_FRICTION_RATIO * math.tan(self.repose_angle_rad)
        tool_friction = math.tan(math.radians(self.material.tool_friction_angle_deg))
        grain_contact, bucket_contact = self._contact_parameters(friction, tool_friction)
        bucket_geoms = BUCKET_GEOMS
        if self.bevelled_edge:
            _add_bevel(spec)
            bucket_geoms = (*BUCKET_GEOMS, "bucket_bevel")
        self.bond_force_n = (
            bond_force_n(
                self.material.cohesion_pa, self.material.friction_angle_deg, 2.0 * self.radius_m
            )
            if self.cohesion
            else 0.0
        )
        for i, position in enumerate(self.lattice):
            add_grain(
                spec,
                f"particle_{i}",
                position,
                self.radius_m,
                self.particle_mass_kg,
                friction,
                grain_contact,
                self.bond_force_n,
            )
        walls = self._add_walls(spec, friction, grain_contact)
        for i, position in enumerate(self.core):
            walls.add_geom(
                name=f"core_{i}",
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                pos=position.tolist(),
                size=[self.radius_m, 0.0, 0.0],
                contype=COHESIVE_CORE_CONTYPE if self.bond_force_n > 0 else CORE_CONTYPE,
                conaffinity=COHESIVE_CORE_CONAFFINITY if self.bond_force_n > 0 else 0,
                condim=CONTACT_CONDIM,
                priority=PARTICLE_PRIORITY,
                friction=[friction, 0.0, 0.0],
                group=WALL_GROUP,
                rgba=list(PARTICLE_RGBA),
                **grain_contact,
            )

        for name in bucket_geoms:
            geom = spec.geom(name)
            if geom is None:
                raise ValueError(f"ParticleSoil: the machine model has no bucket geom {name!r}")
            geom.priority = BUCKET_PRIORITY
            geom.friction[0] = tool_friction
            for key, value in bucket_contact.items():
                setattr(geom, key, value)

        spec.memory = max(spec.memory, ARENA_BYTES_PER_GRAIN * len(sites))
        option = spec.option
        option.solver = SOLVER
        option.cone = CONE
        option.iterations = self.solver_iterations
        option.ls_iterations = SOLVER_LS_ITERATIONS
        option.tolerance = SOLVER_TOLERANCE
        option.noslip_iterations = 0
        option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
        option.sleep_tolerance = SLEEP_TOLERANCE_M_S

    def _contact_parameters(
        self, friction: float, tool_friction: float
    ) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
        """MuJoCo ``solref`` / ``solimp`` of the grains (also the static core and walls) and
        of the bucket plates (they govern bucket-grain contacts), from the grain's mass and
        diameter (module docstring); sets ``grain_stiffness_n_m`` (against steel, None for
        the mass-normalised contacts)."""
        if self.contact_modulus_pa is None:
            self.grain_stiffness_n_m = None
            angle_deg = self.material.tool_friction_angle_deg
            if not angle_deg >= MIN_STEEL_FRICTION_ANGLE_DEG:
                raise ValueError(
                    f"particle soil: the material's tool_friction_angle_deg must be >= "
                    f"{MIN_STEEL_FRICTION_ANGLE_DEG:g} deg, got {angle_deg!r}: below it the "
                    "bucket plates' contacts, kept as compliant as on dry gravel's steel, get "
                    "time constants too long to stop a grain in an impact (steel_contact)"
                )
            solref, solimp = steel_contact(tool_friction)
            return {"solref": [self.contact_timeconst_s, 1.0]}, {
                "solref": solref,
                "solimp": solimp,
            }
        self.grain_stiffness_n_m = self.contact_modulus_pa * 2.0 * self.radius_m
        contacts = []
        for mu in (friction, tool_friction):
            tau, d = contact_parameters(
                self.particle_mass_kg, self.grain_stiffness_n_m, mu, self.contact_timeconst_s
            )
            contacts.append({"solref": [tau, 1.0], "solimp": [d, d, SOLIMP_WIDTH_M, 0.5, 2.0]})
        return contacts[0], contacts[1]

    def _depth_below_surface(self, points: np.ndarray) -> np.ndarray:
        """Vertical depth [m] of points (N, 3) below the undisturbed pile surface."""
        surface = self.pile.surface_height(points[:, 0], points[:, 1], self.repose_angle_rad)
        return surface - points[:, 2]

    def _zone_volume_m3(self) -> float:
        """Volume [m^3] of the undisturbed pile inside the digging zone, down to
        ``ACTIVE_DEPTH_M`` below its surface (the moving grains; the core below is rigid)."""
        xs = np.arange(self.pile.toe_x_m, self.x_back_m, VOLUME_GRID_M) + VOLUME_GRID_M / 2
        ys = np.arange(-self.half_width_m, self.half_width_m, VOLUME_GRID_M) + VOLUME_GRID_M / 2
        grid_x, grid_y = np.meshgrid(xs, ys)
        heights = self.pile.surface_height(grid_x, grid_y, self.repose_angle_rad)
        return float(np.minimum(heights, self.active_depth_m).sum() * VOLUME_GRID_M**2)

    def _fill_lattice(self) -> tuple[float, np.ndarray]:
        """Grain radius [m] and lattice sites (N, 3) [m] filling the zone, with at most
        ``max_particles`` sites in the moving layer."""
        radius = self.mouth_length_m / (2.0 * self.mouth_grains)
        sites = self._hcp_lattice(radius)
        while np.count_nonzero(self._depth_below_surface(sites) <= self.active_depth_m) > (
            self.max_particles
        ):
            radius *= RADIUS_GROWTH
            sites = self._hcp_lattice(radius)
        if len(sites) == 0:
            raise ValueError(
                f"ParticleSoil: the pile {self.pile} holds no particle of radius {radius:.3f} m"
            )
        return radius, sites

    def _hcp_lattice(self, r: float) -> np.ndarray:
        """Hexagonal close packing (ABAB layers, every grain in a pocket of three below) of
        spheres of radius ``r`` [m] whose centres lie under the pile surface in the zone."""
        layer_dz, row_dy = 2 * r * math.sqrt(2.0 / 3.0), math.sqrt(3.0) * r
        n_layers = int(self.pile.height_m / layer_dz) + 1
        n_rows = int(self.half_width_m / row_dy) + 2
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
        centres = np.stack([x[keep], y[keep], z[keep]], axis=1)
        if len(centres):  # odd layers sit r / sqrt(3) off: centre the lattice on y = 0
            centres[:, 1] -= (centres[:, 1].max() + centres[:, 1].min()) / 2
        return centres

    def packed_bucket_sites(self) -> np.ndarray:
        """Grain centres (N, 3) [m], bucket frame, of the bucket's inside packed like the pile:
        the same lattice, the first layer on the floor, whole grains between the side plates,
        every site whose centre lies inside the interior polygon (in the pile: under the
        surface). Its fill is the most a struck bucket reads at this resolution (walls leave
        gaps a grain wide, which matter less the finer the grains)."""
        r, polygon = self.radius_m, self.bucket.polygon
        half_width = self.bucket.width_m / 2
        layer_dz, row_dy = 2 * r * math.sqrt(2.0 / 3.0), math.sqrt(3.0) * r
        (x0, z0), (x1, z1) = polygon.min(axis=0), polygon.max(axis=0)
        layer, row, col = np.meshgrid(
            np.arange(int((z1 - z0) / layer_dz) + 2),
            np.arange(int(2 * half_width / row_dy) + 2),
            np.arange(int((x1 - x0) / (2 * r)) + 2),
            indexing="ij",
        )
        odd = layer % 2
        x = x0 + r + 2 * r * col + r * (row % 2) + r * odd
        y = -half_width + r + row * row_dy + odd * r / math.sqrt(3.0)
        z = z0 + r + layer * layer_dz
        keep = (np.abs(y) <= half_width - r) & _inside_polygon(x, z, polygon)
        return np.stack([x[keep], y[keep], z[keep]], axis=1)

    def _add_walls(
        self, spec: mujoco.MjSpec, friction: float, contact: dict[str, list[float]]
    ) -> mujoco.MjsBody:
        """The rigid rest of the pile: a face slab and a crest box on each side of the zone and
        a wall behind it, up to the pile surface.

        They sit on a static body (a mocap body would keep the particles touching it awake)
        that ``reset`` slides sideways with the particles."""
        pile, t = self.pile, WALL_THICKNESS_M
        slope = self.repose_angle_rad
        face_length = pile.height_m / math.sin(slope)
        crest_x = pile.toe_x_m + pile.height_m / math.tan(slope)
        along, normal = (
            np.array([math.cos(slope), math.sin(slope)]),
            np.array([-math.sin(slope), math.cos(slope)]),
        )
        # face slab: top face on the face plane, from t below ground in front of the toe
        face_xz = np.array([pile.toe_x_m, 0.0]) + (face_length - t) / 2 * along - t / 2 * normal
        face_quat = [math.cos(-slope / 2), 0.0, math.sin(-slope / 2), 0.0]
        level = [1.0, 0.0, 0.0, 0.0]
        crest_half_length = (self.x_back_m + t - crest_x) / 2
        boxes = []
        for side in (-1.0, 1.0):
            y = side * (self.half_width_m + t / 2)
            boxes.append(
                ([face_xz[0], y, face_xz[1]], face_quat, [(face_length + t) / 2, t / 2, t / 2])
            )
            if crest_half_length > 0:
                boxes.append(
                    (
                        [crest_x + crest_half_length, y, pile.height_m / 2],
                        level,
                        [crest_half_length, t / 2, pile.height_m / 2],
                    )
                )
        back_height = float(
            pile.surface_height(np.array([self.x_back_m]), np.array([0.0]), slope)[0]
        )
        boxes.append(
            (
                [self.x_back_m + t / 2, 0.0, back_height / 2],
                level,
                [t / 2, self.half_width_m + t, back_height / 2],
            )
        )
        walls = spec.worldbody.add_body(name="pile_walls")
        for i, (pos, quat, size) in enumerate(boxes):
            walls.add_geom(
                name=f"pile_wall_{i}",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=pos,
                quat=quat,
                size=size,
                contype=WALL_CONTYPE,
                conaffinity=0,
                condim=CONTACT_CONDIM,
                priority=PARTICLE_PRIORITY,
                friction=[friction, 0.0, 0.0],
                group=WALL_GROUP,
                rgba=[*PARTICLE_RGBA[:3], 0.3],
                **contact,
            )
        return walls

    # ------------------------------------------------------------------ bind
    def bind(self, model: mujoco.MjModel, data: mujoco.MjData, machine: Machine) -> None:
        self.model, self.data, self.machine = model, data, machine
        first = model.body("particle_0").id
        # a cohesive grain's steel proxy is a child body, numbered right after its grain
        stride = 2 if self.bond_force_n > 0 else 1
        self._bodies = slice(first, first + stride * self.n_particles, stride)
        joint = int(model.body_jntadr[first])
        qpos0, dof0 = int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])
        self._qpos = slice(qpos0, qpos0 + 3 * self.n_particles)
        self._dofs = slice(dof0, dof0 + 3 * self.n_particles)
        last = joint + 3 * self.n_particles - 1
        if model.jnt_qposadr[last] != self._qpos.stop - 1 or (
            model.jnt_dofadr[last] != self._dofs.stop - 1
        ):
            raise RuntimeError("ParticleSoil: the particles' joints are not contiguous")
        self._walls_body = model.body("pile_walls").id
        self._polygon = self.bucket.polygon
        self._footprint_x = (
            self.pile.toe_x_m - FOOTPRINT_MARGIN_M,
            self.x_back_m + WALL_THICKNESS_M,
        )
        self._footprint_half_width = self.half_width_m + WALL_THICKNESS_M
        self.zone_offset_y_m = 0.0
        self.initial_mass_kg = self.n_particles * self.particle_mass_kg
        self.bonds = (
            GrainBonds(model, np.arange(model.nbody)[self._bodies], self.bond_force_n)
            if self.bond_force_n > 0
            else None
        )
        self._settled_qpos = self._settle()
        self._counts = (self.n_particles, 0, 0)
        self._depth_m: float | None = 0.0
        self._depth_inputs: tuple[np.ndarray, ...] | None = None
        self._edge_offsets_m = (
            np.linspace(-EDGE_SAMPLE_SPAN / 2, EDGE_SAMPLE_SPAN / 2, EDGE_SAMPLES)
            * self.bucket.width_m
        )
        from scipy.spatial import cKDTree  # here: the heightfield's users never pay its import

        self._core_tree = cKDTree(self.core) if len(self.core) else None
        self._bind_volume_columns()
        self._bind_sleep_policy()

    def _bind_sleep_policy(self) -> None:
        """Which geoms are the grains' and the machine's, and the grains' kinematic trees with
        their compiled sleep policy, for ``_update_sleep_policy``."""
        m = self.model
        grain_body = np.zeros(m.nbody, dtype=bool)
        grain_body[self._bodies] = True
        # a cohesive grain's unbonded copy is a welded child: its root is the grain
        geom_root = m.body_rootid[m.geom_bodyid]
        self._grain_geom = grain_body[geom_root]
        self._machine_geom = geom_root == m.body_rootid[self.machine.bucket_body]
        self._grain_trees = np.unique(m.body_treeid[self._bodies])
        self._grain_sleep_policy = m.tree_sleep_policy[self._grain_trees].copy()
        self._grains_may_sleep = True

    def _update_sleep_policy(self) -> None:
        """Keep the grains from falling asleep while the machine touches one of them, and let
        them sleep again once it touches none (module docstring, "Sleeping")."""
        if not self.sleep_in_contact:
            self._set_grains_may_sleep(not self.machine_touches_a_grain())

    def machine_touches_a_grain(self) -> bool:
        """Whether a contact of the last physics step joins a grain and a machine geom."""
        pairs = self.data.contact.geom[: self.data.ncon]
        grain, machine = self._grain_geom, self._machine_geom
        return bool(
            (grain[pairs[:, 0]] & machine[pairs[:, 1]]).any()
            or (grain[pairs[:, 1]] & machine[pairs[:, 0]]).any()
        )

    def _set_grains_may_sleep(self, may_sleep: bool) -> None:
        if may_sleep != self._grains_may_sleep:
            self.model.tree_sleep_policy[self._grain_trees] = (
                self._grain_sleep_policy if may_sleep else int(mujoco.mjtSleepPolicy.mjSLEEP_NEVER)
            )
            self._grains_may_sleep = may_sleep

    def _settle(self) -> np.ndarray:
        """Let the lattice settle under gravity with the machine parked far behind the pile;
        return the particles' joint positions [m] (displacements from the lattice).

        The first ``SETTLE_AWAKE_S`` run with sleeping off (a freshly laid lattice would
        fall asleep before its contacts take the load), then until the pile sleeps."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[0] = self.pile.toe_x_m - PARK_DISTANCE_M  # the machine's free joint: root x
        mujoco.mj_forward(m, d)
        sleep = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        m.opt.enableflags &= ~sleep
        self.advance(m, d, max(1, round(SETTLE_AWAKE_S / m.opt.timestep)))
        m.opt.enableflags |= sleep
        trees = np.unique(m.body_treeid[self._bodies])
        steps = max(1, round(SETTLE_CHECK_S / m.opt.timestep))
        while d.time < SETTLE_MAX_S and d.tree_awake[trees].any():
            self.advance(m, d, steps)
        self.settle_time_s = float(d.time)
        settled = d.qpos[self._qpos].copy()
        mujoco.mj_resetData(m, d)
        return settled

    def _bind_volume_columns(self) -> None:
        """The bucket's inside (bucket frame), column centres across the bucket, and the
        stencil of column offsets a grain covers, for ``fill_measure="volume"``."""
        polygon, cell = self.bucket.polygon, VOLUME_CELL_M
        self._polygon_local = np.zeros((len(polygon), 3))
        self._polygon_local[:, 0], self._polygon_local[:, 2] = polygon[:, 0], polygon[:, 1]
        half_width = self.bucket.width_m / 2
        self._volume_y = np.arange(-half_width, half_width, cell) + cell / 2
        reach = COVER_RADIUS_RATIO * self.radius_m
        n = int(math.ceil(reach / cell))
        di, dj = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1), indexing="ij")
        near = np.hypot(di * cell, dj * cell) <= reach
        self._cover_offsets = np.stack([di[near], dj[near]], axis=1)  # (K, 2): along, across
        self._in_bucket = np.zeros(self.n_particles, dtype=bool)
        self._load_volume_m3: float | None = 0.0

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator) -> None:
        """Lay the cached settled pile where the start pose aims the bucket (no shape noise:
        ``rng`` is not used)."""
        m, d = self.model, self.data
        self.zone_offset_y_m = self._aim_offset_y()
        qpos = self._settled_qpos.reshape(-1, 3).copy()
        qpos[:, 1] += self.zone_offset_y_m
        d.qpos[self._qpos] = qpos.ravel()
        d.qvel[self._dofs] = 0.0
        m.body_pos[self._walls_body, 1] = self.zone_offset_y_m
        _refresh_static_bodies(m, d)
        self._set_grains_may_sleep(True)  # the laid pile falls asleep at once
        self._tally()
        self.initial_mass_kg = self.n_particles * self.particle_mass_kg

    def _aim_offset_y(self) -> float:
        """World y [m] of the cutting edge's straight path ``AIM_DEPTH_M`` into the pile,
        clipped so that the zone stays on the pile's straight stretch."""
        edge = self.data.site_xpos[self.machine.cutting_edge_site]
        heading = self.machine.heading()
        if heading[0] <= 0.0:
            return 0.0
        target_x = self.pile.toe_x_m + AIM_DEPTH_M
        y = edge[1] + heading[1] / heading[0] * (target_x - edge[0])
        limit = max(self.pile.half_width_m - self.half_width_m, 0.0)
        return float(np.clip(y, -limit, limit))

    # ------------------------------------------------------------------ update
    def advance(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        """``nstep`` physics steps; a cohesive pile's bonds set from each step's contacts."""
        step_physics(model, data, nstep, self.bonds)

    def update(self, dt: float) -> None:
        """Recount the particles and set whether they may fall asleep; the physics of the last
        ``dt`` seconds ran in ``advance``."""
        self._tally()
        self._update_sleep_policy()

    def particle_positions(self) -> np.ndarray:
        """Particle centres (N, 3) [m], world frame, as of the last physics step."""
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
        on_footprint = (
            (x >= self._footprint_x[0])
            & (x <= self._footprint_x[1])
            & (np.abs(y - self.zone_offset_y_m) <= self._footprint_half_width)
        )
        spilled = ~in_bucket & ~on_footprint & (z < SPILL_HEIGHT_M)
        n_bucket, n_spilled = int(in_bucket.sum()), int(spilled.sum())
        self._in_bucket = in_bucket
        self._load_volume_m3 = None  # measured when read
        self._counts = (self.n_particles - n_bucket - n_spilled, n_bucket, n_spilled)
        self.bucket_load_kg = n_bucket * self.particle_mass_kg
        self.spilled_kg = n_spilled * self.particle_mass_kg
        # measured when read (once per control step, not at every soil update), from the
        # grains and the edge as they are now
        edge = d.site_xpos[machine.cutting_edge_site].copy()
        self._depth_inputs = (positions.copy(), in_bucket, edge, machine.heading())
        self._depth_m = None

    def _edge_depth(
        self,
        positions: np.ndarray,
        in_bucket: np.ndarray,
        edge: np.ndarray,
        heading: np.ndarray,
    ) -> float:
        """Depth [m] of the cutting edge below the pile surface just ahead of it, as the
        heightfield defines it: the mean, over ``EDGE_SAMPLES`` points across the edge
        (``EDGE_SAMPLE_SPAN`` of the bucket width) one heightfield cell
        (``pile.cell_size_m``) ahead of it, of the height of the pile surface above the
        edge (0 where the surface lies below it).

        The surface over a point is the top of the highest grain of the pile or of the
        static core covering it (centre within ``COVER_RADIUS_RATIO`` radii of the point,
        horizontally), the ground (0) where none does. Grains in the bucket and grains
        that touch neither the ground nor the core through a chain of touching grains
        (``_resting_grains``: thrown into the air, carried on the machine) are not the
        pile. The rigid rest of the pile around the zone does not count: the machine
        passes through it.

        ``positions`` (N, 3) [m] are the grain centres, ``in_bucket`` (N,) which of them
        are in the bucket, ``edge`` (3,) [m] the middle of the cutting edge and ``heading``
        (2,) the machine's horizontal unit heading, all in the world frame."""
        lateral = np.array([-heading[1], heading[0]])
        points = (
            edge[:2] + self.pile.cell_size_m * heading + self._edge_offsets_m[:, None] * lateral
        )
        reach = COVER_RADIUS_RATIO * self.radius_m
        surface = np.zeros(EDGE_SAMPLES)
        if len(self.core):  # the core's spheres sit where reset slid the zone
            core = self.core
            covers = _horizontal_distance(points, core[:, 0], core[:, 1] + self.zone_offset_y_m)
            covers = covers <= reach
            surface = np.max(np.where(covers, core[:, 2] + self.radius_m, 0.0), axis=1)
        covers = (_horizontal_distance(points, positions[:, 0], positions[:, 1]) <= reach) & (
            ~in_bucket
        )
        if covers.any():
            covers &= self._resting_grains(positions, ~in_bucket)
            tops = np.max(np.where(covers, positions[:, 2] + self.radius_m, 0.0), axis=1)
            surface = np.maximum(surface, tops)
        return float(np.maximum(surface - float(edge[2]), 0.0).mean())

    def _resting_grains(self, positions: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """Which grains (N,) rest on the ground or on the static core, directly or through
        a chain of touching ``candidates`` (grains touch across a gap of at most
        ``TOUCH_GAP_RATIO`` of their diameter; the ground lies at z = 0)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        r, gap = self.radius_m, TOUCH_GAP_RATIO * 2.0 * self.radius_m
        index = np.flatnonzero(candidates)
        grains = positions[index]
        n = len(index)
        pairs = cKDTree(grains).query_pairs(2.0 * r + gap, output_type="ndarray")
        on_base = grains[:, 2] <= r + gap
        if self._core_tree is not None:
            in_core_frame = grains - np.array([0.0, self.zone_offset_y_m, 0.0])
            distance, _ = self._core_tree.query(in_core_frame, distance_upper_bound=2.0 * r + gap)
            on_base |= np.isfinite(distance)
        base = np.flatnonzero(on_base)
        rows = np.concatenate([pairs[:, 0], base])  # node n stands for the ground and core
        cols = np.concatenate([pairs[:, 1], np.full(len(base), n)])
        graph = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n + 1, n + 1))
        _, labels = connected_components(graph, directed=False)
        resting = np.zeros(len(positions), dtype=bool)
        resting[index] = labels[:n] == labels[n]
        return resting

    # ------------------------------------------------------------------ tallies
    @property
    def bucket_load_volume_m3(self) -> float:
        """The load's volume [m^3]: its mass at bulk density (``fill_measure="count"``) or
        its bulk volume under its surface (``"volume"``; module docstring)."""
        if self.fill_measure == "count":
            return self.bucket_load_kg / self.material.density_kg_m3
        if self._load_volume_m3 is None:
            self._load_volume_m3 = self.load_bulk_volume_m3()
        return self._load_volume_m3

    def load_bulk_volume_m3(self) -> float:
        """Bulk volume [m^3] of the grains in the bucket: vertical columns over the bucket's
        inside, from its floor up to the top of the highest grain covering the column, at
        most to its roof or mouth.

        Measured in the vertical plane through the hinge along the heading (s, z), as the
        heightfield's intake measures its columns (the bucket's roll is neglected)."""
        if not self._in_bucket.any():
            return 0.0
        d, machine = self.data, self.machine
        rotation = d.xmat[machine.bucket_body].reshape(3, 3)
        hinge = d.xpos[machine.bucket_body]
        heading = machine.heading()
        world = hinge + self._polygon_local @ rotation.T
        s_poly = (world[:, :2] - hinge[:2]) @ heading
        cell = VOLUME_CELL_M
        s_cols = np.arange(s_poly.min(), s_poly.max(), cell) + cell / 2
        floor, roof = _vertical_extent(s_cols, s_poly, world[:, 2])
        # grain tops over the columns: the highest covering grain per column
        grains = self.particle_positions()[self._in_bucket]
        rel = grains - hinge
        along = np.rint((rel[:, :2] @ heading - s_cols[0]) / cell).astype(int)
        across = np.rint((rel @ rotation[:, 1] - self._volume_y[0]) / cell).astype(int)
        rows = along[:, None] + self._cover_offsets[None, :, 0]
        cols = across[:, None] + self._cover_offsets[None, :, 1]
        tops = np.broadcast_to((grains[:, 2] + self.radius_m)[:, None], rows.shape)
        on_grid = (rows >= 0) & (rows < len(s_cols)) & (cols >= 0) & (cols < len(self._volume_y))
        top = np.full((len(s_cols), len(self._volume_y)), -np.inf)
        np.maximum.at(top, (rows[on_grid], cols[on_grid]), tops[on_grid])
        height = np.clip(np.minimum(top, roof[:, None]) - floor[:, None], 0.0, None)
        return float(height.sum()) * cell * cell

    @property
    def pile_mass_kg(self) -> float:
        return self._counts[0] * self.particle_mass_kg

    @property
    def particle_counts(self) -> tuple[int, int, int]:
        """Particles (in the pile, in the bucket, spilled); they sum to ``n_particles``."""
        return self._counts

    def cutting_depth_m(self) -> float:
        """Depth [m] of the cutting edge below the pile surface just ahead of it, as of the
        last ``update`` (``_edge_depth``; 0 outside the pile)."""
        if self._depth_m is None:
            self._depth_m = self._edge_depth(*self._depth_inputs)
        return self._depth_m


def bond_force_n(
    cohesion_pa: float,
    friction_angle_deg: float,
    diameter_m: float,
    solid_fraction: float = HCP_SOLID_FRACTION,
) -> float:
    """The adhesive force G [N] each grain of diameter ``diameter_m`` pulls its contacts with
    (module docstring, "Cohesion"): Mohr-Coulomb's uniaxial tensile strength
    sigma_t = 2 c tan(45 deg - phi / 2) for cohesion ``cohesion_pa`` and friction angle
    ``friction_angle_deg``, carried by Rumpf's bonds, sigma_t = (1 - eps) k F / (pi D^2),
    where MuJoCo's body adhesion makes the bonds around a grain sum to k F = 2 G:
    G = pi D^2 sigma_t / (2 (1 - eps)); times ``COHESION_CALIBRATION``. 0 for c = 0."""
    if not cohesion_pa >= 0.0:
        raise ValueError(f"bond_force_n: cohesion must be >= 0 Pa, got {cohesion_pa!r}")
    tensile_pa = 2.0 * cohesion_pa * math.tan(math.radians(45.0 - friction_angle_deg / 2.0))
    return COHESION_CALIBRATION * math.pi * diameter_m**2 * tensile_pa / (2.0 * solid_fraction)


def add_grain(
    spec: mujoco.MjSpec,
    name: str,
    position: np.ndarray,
    radius_m: float,
    mass_kg: float,
    friction: float,
    contact: dict[str, list[float]],
    bond_n: float = 0.0,
) -> mujoco.MjsBody:
    """A grain: a sphere on three slide joints (x, y, z) in ``spec``'s world body.

    Loose (``bond_n`` 0): one geom that touches other grains, the core, the walls, the
    ground and the machine. Cohesive (``bond_n`` > 0 [N], ``bond_force_n``): the grain's
    geom touches only the pile (grains, the core with ``COHESIVE_CORE_CONTYPE``, walls), its
    bonds (``bonds.GrainBonds``, a force ``bond_n`` spread over the body's contacts) pull
    them closed, and a copy of the sphere on a child body (``{name}_unbonded``, welded to
    it) touches only the machine and the ground, so that the bonds, which act on every
    contact of the grain's body, leave the steel and the site's floor alone. The grain gets
    three motors on its slides (``bonds.add_bond_motors``) through which ``GrainBonds``
    applies the bonds' pull."""
    body = spec.worldbody.add_body(name=name, pos=list(map(float, position)))
    if bond_n > 0.0:  # MuJoCo keeps actuated bodies awake unless they are allowed to sleep
        body.sleep = mujoco.mjtSleepPolicy.mjSLEEP_ALLOWED
    for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        body.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=list(axis))
    geom = {
        "type": mujoco.mjtGeom.mjGEOM_SPHERE,
        "size": [radius_m, 0.0, 0.0],
        "condim": CONTACT_CONDIM,
        "priority": PARTICLE_PRIORITY,
        "friction": [friction, 0.0, 0.0],
        "rgba": list(PARTICLE_RGBA),
        **contact,
    }
    if not bond_n > 0.0:
        body.add_geom(
            mass=mass_kg, contype=PARTICLE_CONTYPE, conaffinity=PARTICLE_CONAFFINITY, **geom
        )
        return body
    body.add_geom(
        mass=mass_kg,
        contype=COHESIVE_GRAIN_CONTYPE,
        conaffinity=COHESIVE_GRAIN_CONAFFINITY,
        **geom,
    )
    unbonded = body.add_body(name=f"{name}_unbonded")
    unbonded.add_geom(
        mass=UNBONDED_MASS_KG,
        contype=0,
        conaffinity=UNBONDED_CONAFFINITY,
        group=WALL_GROUP,
        **geom,
    )
    add_bond_motors(spec, body, name)  # GrainBonds sets their force every physics step
    return body


def contact_parameters(
    mass_kg: float, stiffness_n_m: float, friction: float, timeconst_s: float
) -> tuple[float, float]:
    """MuJoCo's time constant [s] and impedance d (``solref`` (tau, 1), ``solimp`` with
    d0 = dmax = d) that give a body of ``mass_kg`` pressed against a fixed one the static
    normal stiffness ``stiffness_n_m`` [N/m], with this module's friction cone (pyramidal,
    condim 3, sliding ``friction``). tau is ``timeconst_s`` unless even the softest
    impedance (``CONTACT_IMPEDANCE_RANGE[0]``) is too stiff at it; then it is longer.

    MuJoCo solves contacts in acceleration: at rest under a normal force F the penetration
    is (1 - d) tau^2 F / (c m), where c = 2 / (mu^2 (1 + mu^2)) for the pyramidal cone
    (MuJoCo's mj_makeImpedance scales the regulariser of its four edges by 2 mu^2 to match
    the elliptic cone's friction; c = 1 for an elliptic cone;
    tests/envs/test_particle_contacts.py measures it), so K = c m / ((1 - d) tau^2). Two
    grains of mass m in contact have half the stiffness (MuJoCo adds their inverse masses).
    Raises ValueError where the stiffness needs an impedance above
    ``CONTACT_IMPEDANCE_RANGE``."""
    if not friction > 0.0:
        raise ValueError(f"contact_parameters: friction must be > 0, got {friction!r}")
    low, high = CONTACT_IMPEDANCE_RANGE
    compliance = 2.0 / (friction**2 * (1.0 + friction**2)) * mass_kg / stiffness_n_m  # [s^2]
    timeconst_s = max(timeconst_s, math.sqrt(compliance / (1.0 - low)))
    impedance = 1.0 - compliance / timeconst_s**2
    if impedance > high:
        raise ValueError(
            f"ParticleSoil.contact_modulus_pa: a grain of {mass_kg:.3g} kg (friction "
            f"{friction:.2f}) needs a MuJoCo impedance of {impedance:.4f}, above {high}, for "
            f"a contact stiffness of {stiffness_n_m:.3g} N/m with a {timeconst_s} s time "
            "constant: choose a lower contact_modulus_pa or a coarser pile"
        )
    return timeconst_s, impedance


def pyramid_stiffening(friction: float) -> float:
    """The factor c = 2 / (mu^2 (1 + mu^2)) by which MuJoCo's pyramidal friction cone
    stiffens a contact of sliding ``friction`` mu against the elliptic cone's (its
    regulariser scaled by 2 mu^2 over the four edges; ``contact_parameters``)."""
    return 2.0 / (friction**2 * (1.0 + friction**2))


def steel_contact(friction: float) -> tuple[list[float], list[float]]:
    """The bucket plates' default ``solref`` and ``solimp`` for a steel friction ``friction``
    (tan of the material's soil-steel friction angle).

    At ``STEEL_REFERENCE_FRICTION_ANGLE_DEG`` they are MuJoCo's defaults (``MUJOCO_SOLREF``,
    ``MUJOCO_SOLIMP``). With the pyramidal cone a contact's static compliance is
    (1 - d) tau^2 / (c m) (``contact_parameters``), c = ``pyramid_stiffening(mu)``: on
    smoother steel MuJoCo's defaults would make the grain-steel contact c(mu) / c(mu_ref)
    times stiffer (3.4x at winter_c's tan 15 deg), nearly a hard constraint (effective
    impedance 0.998), which the pile's capped CG iterations leave unresolved: grains
    sank a whole radius into the 24 mm plates and shot out at tens of m/s
    (docs/soil_models.md). Here the impedance's complement (1 - d) is scaled by
    c(mu) / c(mu_ref) instead, so the compliance is the reference's; where that takes
    ``dmin`` below ``CONTACT_IMPEDANCE_RANGE[0]`` the time constant grows instead (as in
    ``contact_parameters``). Both impedances are at most ``CONTACT_IMPEDANCE_RANGE[1]``."""
    if not friction > 0.0:
        raise ValueError(f"steel_contact: friction must be > 0, got {friction!r}")
    reference = math.tan(math.radians(STEEL_REFERENCE_FRICTION_ANGLE_DEG))
    scale = pyramid_stiffening(friction) / pyramid_stiffening(reference)
    timeconst_s, dampratio = MUJOCO_SOLREF
    dmin, dmax, width, midpoint, power = MUJOCO_SOLIMP
    low, high = CONTACT_IMPEDANCE_RANGE
    if scale == 1.0:
        return list(MUJOCO_SOLREF), list(MUJOCO_SOLIMP)
    longer = timeconst_s * math.sqrt(max(1.0, scale * (1.0 - dmin) / (1.0 - low)))
    factor = scale * (timeconst_s / longer) ** 2
    impedances = [min(1.0 - (1.0 - d) * factor, high) for d in (dmin, dmax)]
    return [longer, dampratio], [*impedances, width, midpoint, power]


def _add_bevel(spec: mujoco.MjSpec) -> None:
    """A steel strip on the front of the bucket's floor plate (``bucket_bevel``): its top face
    rises at ``BEVEL_ANGLE_DEG`` from the plate's underside, 4 cm ahead of the plate's front
    face, to the plate's top 5 mm behind it, so that the face lies under it but for its top
    3 mm. Contact parameters and friction are set with the other bucket plates'."""
    floor = spec.geom("bucket_floor")
    if floor is None:
        raise ValueError("ParticleSoil: the machine model has no bucket geom 'bucket_floor'")
    alpha = math.radians(BEVEL_ANGLE_DEG)
    front_x = floor.pos[0] + floor.size[0]
    bottom_z, top_z = floor.pos[2] - floor.size[2], floor.pos[2] + floor.size[2]
    tip = (front_x + (top_z - bottom_z) / math.tan(alpha), bottom_z)
    back = (front_x - BEVEL_HALF_THICKNESS_M, top_z)
    length = math.hypot(tip[0] - back[0], tip[1] - back[1]) + 0.01
    mid_x, mid_z = (tip[0] + back[0]) / 2, (tip[1] + back[1]) / 2
    spec.body("bucket").add_geom(
        name="bucket_bevel",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[
            mid_x - BEVEL_HALF_THICKNESS_M * math.sin(alpha),
            0.0,
            mid_z - BEVEL_HALF_THICKNESS_M * math.cos(alpha),
        ],
        size=[length / 2, floor.size[1], BEVEL_HALF_THICKNESS_M],
        quat=[math.cos(alpha / 2), 0.0, math.sin(alpha / 2), 0.0],
        mass=BEVEL_MASS_KG,
        contype=floor.contype,
        conaffinity=floor.conaffinity,
        condim=floor.condim,
        material="steel",
    )


def _refresh_static_bodies(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Make MuJoCo pick up a moved static body: with sleeping enabled it computes static
    poses and bounding boxes only in ``mj_resetData``. The simulation state is kept."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    mujoco.mj_resetData(model, data)
    mujoco.mj_setState(model, data, state, spec)
    mujoco.mj_forward(model, data)


def _vertical_extent(
    s: np.ndarray, s_poly: np.ndarray, z_poly: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest z [m] of the polygon (s_poly, z_poly) over each abscissa ``s``
    (floor +inf and roof -inf where the polygon does not reach)."""
    s_a, s_b = s_poly, np.roll(s_poly, -1)
    z_a, z_b = z_poly, np.roll(z_poly, -1)
    span = s_b - s_a
    safe_span = np.where(np.abs(span) < 1e-9, 1e-9, span)
    t = (s[:, None] - s_a) / safe_span
    on_edge = (t >= 0.0) & (t <= 1.0) & (np.abs(span) >= 1e-9)
    z_at = z_a + t * (z_b - z_a)
    return np.where(on_edge, z_at, np.inf).min(axis=1), np.where(on_edge, z_at, -np.inf).max(axis=1)


def _horizontal_distance(points: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Horizontal distances [m] (P, N) from the points (P, 2) to (x, y) (N,)."""
    return np.hypot(points[:, :1] - x[None, :], points[:, 1:] - y[None, :])


def _inside_polygon(u: np.ndarray, v: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule: which points (u, v) lie inside ``polygon`` (K, 2)."""
    inside = np.zeros(u.shape, dtype=bool)
    for (u0, v0), (u1, v1) in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        crosses = (v0 > v) != (v1 > v)
        with np.errstate(divide="ignore", invalid="ignore"):
            u_cross = u0 + (v - v0) * (u1 - u0) / (v1 - v0)
        inside ^= crosses & (u < u_cross)
    return inside
