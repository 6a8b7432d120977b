"""The particle pile's bonds (``soil/bonds.py``) are MuJoCo's body adhesion, computed in numpy.

A small cluster of cohesive grains (``particles.add_grain``), one of them against a static
core sphere and all on the ground, carries both: the grains' bond motors, and a reference
MuJoCo adhesion actuator with a body transmission on each grain, the way the pile bonded
its grains until session 34. With the motors at zero, MuJoCo's actuator force on the grains'
slides is the adhesion's alone; ``GrainBonds.forces`` must give the same from the contacts.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from pilerl_pile_loader.soil.bonds import GrainBonds
from pilerl_pile_loader.soil.particles import (
    COHESIVE_CORE_CONAFFINITY,
    COHESIVE_CORE_CONTYPE,
    CONE,
    CONTACT_CONDIM,
    GROUND_CONTYPE,
    add_grain,
)

BOND_N = 52.0  # winter_c's bond at the default grain size
RADIUS_M = 0.05
# a triangle of grains, one on top, and one leaning on the static core: each pair overlaps
CENTRES_M = np.array(
    [
        [0.0, 0.0, 0.049],
        [0.097, 0.0, 0.049],
        [0.0485, 0.084, 0.049],
        [0.0485, 0.028, 0.127],
        [-0.097, 0.0, 0.049],
    ]
)
CORE_M = [-0.19, 0.0, 0.049]


def cluster(*, reference_adhesion: bool) -> tuple[mujoco.MjModel, np.ndarray]:
    spec = mujoco.MjSpec()
    spec.option.cone = CONE
    spec.worldbody.add_geom(
        name="ground",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[2.0, 2.0, 0.1],
        contype=GROUND_CONTYPE,
        conaffinity=GROUND_CONTYPE,
    )
    spec.worldbody.add_geom(
        name="core",
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        pos=CORE_M,
        size=[RADIUS_M, 0.0, 0.0],
        contype=COHESIVE_CORE_CONTYPE,
        conaffinity=COHESIVE_CORE_CONAFFINITY,
        condim=CONTACT_CONDIM,
    )
    for i, centre in enumerate(CENTRES_M):
        add_grain(spec, f"g{i}", centre, RADIUS_M, 0.5, 0.6, {}, BOND_N)
        if reference_adhesion:
            adhesion = spec.add_actuator(name=f"g{i}_adhesion", target=f"g{i}")
            adhesion.trntype = mujoco.mjtTrn.mjTRN_BODY
            adhesion.gainprm[0] = 0.0
            adhesion.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            adhesion.biasprm[0] = BOND_N
    model = spec.compile()
    grains = np.array([model.body(f"g{i}").id for i in range(len(CENTRES_M))])
    return model, grains


def test_the_bonds_are_mujocos_body_adhesion():
    model, grains = cluster(reference_adhesion=True)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # the motors' controls are 0: only the adhesion acts
    bonds = GrainBonds(model, grains, BOND_N)
    dofs = model.body_dofadr[grains][:, None] + np.arange(3)

    mujoco_force = data.qfrc_actuator[dofs]
    ours = bonds.forces(data)

    pairs = {tuple(sorted(model.geom_bodyid[g])) for g in data.contact.geom[: data.ncon]}
    assert len(pairs) >= 6  # grain-grain, grain-core, and the proxies on the ground
    assert np.abs(mujoco_force).max() > 0.5 * BOND_N  # the reference does pull
    np.testing.assert_allclose(ours, mujoco_force, rtol=0, atol=1e-9 * BOND_N)


def test_a_bonded_cluster_moves_as_with_mujocos_adhesion_sleeping_included():
    """2,000 physics steps with sleeping on: the cluster settles, falls asleep, and every
    grain is where MuJoCo's adhesion actuators put it."""
    reference, grains = cluster(reference_adhesion=True)
    ours, _ = cluster(reference_adhesion=False)
    sleep = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    reference.opt.enableflags |= sleep
    ours.opt.enableflags |= sleep
    bonds = GrainBonds(ours, grains, BOND_N)
    data_reference, data_ours = mujoco.MjData(reference), mujoco.MjData(ours)

    mujoco.mj_step(reference, data_reference, nstep=2000)
    bonds.step(ours, data_ours, 2000)

    moved = np.linalg.norm(data_ours.xpos[grains] - CENTRES_M, axis=1)
    assert moved.max() > 1e-3  # it did settle
    np.testing.assert_allclose(data_ours.qpos, data_reference.qpos, rtol=0, atol=1e-9)
    trees = ours.body_treeid[grains]
    np.testing.assert_array_equal(data_ours.tree_awake[trees], data_reference.tree_awake[trees])
    assert not data_ours.tree_awake[trees].all()  # the sleeping path was taken


def test_stepping_with_the_bonds_holds_a_pair_together():
    """Two grains pulled apart by the same force: bonded they part less than loose."""
    model, grains = cluster(reference_adhesion=False)
    bonds = GrainBonds(model, grains, BOND_N)
    a, b = model.body_dofadr[grains[0]], model.body_dofadr[grains[1]]

    def gap_after(bonded: bool) -> float:
        data = mujoco.MjData(model)
        for _ in range(50):
            data.qfrc_applied[a] = -1.0  # a gentle pull, below the bond
            data.qfrc_applied[b] = +1.0
            if bonded:
                bonds.step(model, data)
            else:
                mujoco.mj_step(model, data)
        return float(np.linalg.norm(data.xpos[grains[1]] - data.xpos[grains[0]]))

    assert gap_after(bonded=True) < gap_after(bonded=False) - 1e-3


def test_a_bond_force_must_be_positive():
    model, grains = cluster(reference_adhesion=False)
    with pytest.raises(ValueError, match="bond force must be > 0"):
        GrainBonds(model, grains, 0.0)
