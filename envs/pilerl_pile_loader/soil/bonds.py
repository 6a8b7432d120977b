"""The particle soil's cohesive bonds: MuJoCo's body adhesion, computed once per physics step.

A cohesive grain pulls each of its contacts closed with a constant force G spread evenly
over them: with n contacts, G / n along each contact's normal, on both bodies of the
contact, so a grain-grain contact is held by G / n_a + G / n_b (``particles.py``,
"Cohesion"). That is what a MuJoCo adhesion actuator with a body transmission does, and
what the pile used until session 34. MuJoCo computes such an actuator's moment by
zeroing and multiplying the whole constraint Jacobian once per actuator: with ~600 bonded
grains and ~1800 contacts, 5.6-6.0 ms of a 15.4 ms digging step (docs/soil_models.md,
"Speed").

Here the same forces come from one pass over the contacts (numpy, per physics step):
``mj_step1`` finds the step's contacts, ``GrainBonds.forces`` gives each grain the sum of
its bonds' pulls, three joint motors per grain (``add_bond_motors``, on its x, y and z
slides) apply them, and ``mj_step2`` finishes the step. The grains are spheres on three
slides: a contact normal passes through the grain's centre, so the pull is a force on its
slides and nothing else. A contact counts as MuJoCo's body adhesion counts it: both geoms
real (not flex), not excluded, or excluded only because it is in the margin's gap; and as
MuJoCo skips a sleeping actuator, a sleeping grain's bond pulls nothing (its share of a
contact with an awake grain included). The forces agree with MuJoCo's adhesion actuators
to rounding (``tests/envs/test_particle_bonds.py``).

Actuator forces, unlike applied forces (``qfrc_applied``), do not keep a tree awake, so a
bonded pile still falls asleep, as it did with the adhesion actuators.
"""

from __future__ import annotations

import mujoco
import numpy as np

AXES = ("x", "y", "z")
ASLEEP = int(mujoco.mjtSleepState.mjS_ASLEEP)


def add_bond_motors(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str) -> None:
    """Name ``body``'s three slide joints ``{name}_x|y|z`` and put a motor on each
    (``{name}_bond_x|y|z``: gain 1, the control is the force [N], unlimited)."""
    joints = list(body.joints)
    slides = [
        j.type == mujoco.mjtJoint.mjJNT_SLIDE and np.allclose(j.axis, np.eye(3)[i])
        for i, j in enumerate(joints[: len(AXES)])
    ]
    if len(joints) != len(AXES) or not all(slides):
        raise ValueError(
            f"add_bond_motors: {name} must move on three slides along x, y and z, in that "
            f"order (the bonds are forces along the world axes); it has {len(joints)} joints"
        )
    for axis, joint in zip(AXES, joints, strict=True):
        joint.name = f"{name}_{axis}"
        motor = spec.add_actuator(name=f"{name}_bond_{axis}", target=joint.name)
        motor.trntype = mujoco.mjtTrn.mjTRN_JOINT
        motor.gainprm[0] = 1.0
        motor.ctrllimited = 0


class GrainBonds:
    """The bonds of the grains ``grain_bodies`` (body ids) of ``model``, each of force
    ``bond_n`` [N] (``particles.bond_force_n``)."""

    def __init__(self, model: mujoco.MjModel, grain_bodies: np.ndarray, bond_n: float) -> None:
        if not bond_n > 0.0:
            raise ValueError(f"GrainBonds: the bond force must be > 0 N, got {bond_n!r}")
        if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            raise ValueError(
                "GrainBonds: the model integrates with RK4, which mj_step1 / mj_step2 cannot "
                "(they fall back to Euler); use Euler, implicit or implicitfast"
            )
        self.bond_n = float(bond_n)
        grain_bodies = np.asarray(grain_bodies, dtype=int)
        self._bodies = grain_bodies
        self.n_grains = len(grain_bodies)
        # a contact side that is not a bonded grain counts as the "sink", index n_grains:
        # only a grain's own geom bonds (its steel proxy is a child body: never), and a
        # flex's geom id -1 reads the appended last entry
        grain_of_body = np.full(model.nbody, self.n_grains)
        grain_of_body[grain_bodies] = np.arange(self.n_grains)
        self._grain_of_geom = np.append(grain_of_body[model.geom_bodyid], self.n_grains)
        names = [model.body(int(b)).name for b in grain_bodies]
        self._motors = np.array(
            [[model.actuator(f"{name}_bond_{axis}").id for axis in AXES] for name in names]
        )

    def forces(self, data: mujoco.MjData) -> np.ndarray:
        """Each grain's bond force [N], world x, y, z, from ``data``'s contacts: (grains, 3)."""
        n, sink = data.ncon, self.n_grains
        if n == 0:
            return np.zeros((self.n_grains, 3))
        contact = data.contact
        grain = self._grain_of_geom[contact.geom[:n]]  # (n, 2): grain index or the sink
        grain[contact.exclude[:n] > 1] = sink  # MuJoCo counts 0 (active) and 1 (in the gap)
        contacts = np.bincount(grain.ravel(), minlength=sink + 1)[:sink]
        per_contact = np.zeros(sink + 1)
        per_contact[:sink] = self.bond_n / np.maximum(contacts, 1)
        # a sleeping grain's bond pulls nothing, not even on an awake neighbour: MuJoCo skips
        # a sleeping actuator's transmission (its moment is zero)
        per_contact[:sink][data.body_awake[self._bodies] == ASLEEP] = 0.0
        pull = per_contact[grain].sum(axis=1)  # G / n of each side that is a bonded grain
        force = pull[:, None] * contact.frame[:n, :3]  # the normal points from geom 0 to 1
        out = np.zeros((sink + 1, 3))
        for side, sign in ((0, 1.0), (1, -1.0)):  # geom 0 pulled along it, geom 1 back
            for axis in range(3):
                out[:, axis] += sign * np.bincount(
                    grain[:, side], weights=force[:, axis], minlength=sink + 1
                )
        return out[:sink]

    def step(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int = 1) -> None:
        """``nstep`` physics steps, the bonds' forces set from each step's own contacts."""
        motors = self._motors
        for _ in range(nstep):
            mujoco.mj_step1(model, data)
            data.ctrl[motors] = self.forces(data)
            mujoco.mj_step2(model, data)


def step_physics(
    model: mujoco.MjModel, data: mujoco.MjData, nstep: int, bonds: GrainBonds | None
) -> None:
    """``nstep`` physics steps: ``mj_step``, or with ``bonds`` set from each step's contacts."""
    if bonds is None:
        mujoco.mj_step(model, data, nstep=nstep)
    else:
        bonds.step(model, data, nstep)
