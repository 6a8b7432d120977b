"""The wheel loader: hydraulic parameters, model loading, and named physical readings.

The MJCF in ``assets/wheel_loader.xml`` holds the rigid-body geometry. This module holds the
hydraulic numbers (bores, moment arms, relief pressures, flows) in one dataclass, writes them
into the compiled model, and exposes the machine's readings by name (``boom_angle()``,
``drive_pressure_mpa()``...), dm_control-``Physics`` style.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

ASSETS = Path(__file__).parent / "assets"
MACHINE_XML = ASSETS / "wheel_loader.xml"

WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")
MPA = 1e6  # Pa per MPa


def _circle_area_m2(diameter_m: float) -> float:
    return math.pi * diameter_m**2 / 4


@dataclass(frozen=True)
class MachineParameters:
    """Hydraulic and drive parameters of an Avant 635-class loader (see docs/machine_model.md).

    Cylinders are modelled in joint space: a cylinder force F at an effective moment arm r
    gives joint torque ``F * r``. A cylinder has a piston (bore-side) chamber of area
    ``pi bore^2 / 4`` that pushes it out and a rod (annulus) chamber of area
    ``pi (bore^2 - rod^2) / 4`` that pulls it in; the pressure sensors sit on the piston
    side (the side that carries the load when lifting, curling, or pushing into the pile).
    """

    # Work hydraulics
    work_relief_pressure_mpa: float = 20.0  # relief valve setting of the work circuit [MPa]
    tank_pressure_mpa: float = 0.5  # return-line pressure, the floor of every reading [MPa]
    boom_bore_m: float = 0.070  # boom (lift) cylinder bore [m]
    boom_rod_m: float = 0.040  # boom cylinder rod diameter [m]
    boom_moment_arm_m: float = 0.32  # effective lever of the boom cylinder [m]
    boom_max_speed_rad_s: float = 0.45  # full-flow boom speed [rad/s]
    bucket_bore_m: float = 0.060  # bucket (tilt) cylinder bore [m]
    bucket_rod_m: float = 0.035  # bucket cylinder rod diameter [m]
    bucket_moment_arm_m: float = 0.20  # effective lever of the bucket cylinder [m]
    bucket_max_speed_rad_s: float = 0.80  # full-flow bucket speed [rad/s]
    telescope_bore_m: float = 0.050  # telescope cylinder bore [m]
    telescope_rod_m: float = 0.028  # telescope cylinder rod diameter [m]
    telescope_extension_m: float = 0.30  # held extension during a scoop [m]
    # Hydrostatic transmission (HST): one pump; on each side the front and rear wheel
    # motors in series, the two sides in parallel
    drive_relief_pressure_mpa: float = 25.0  # HST high-pressure relief [MPa]
    drive_charge_pressure_mpa: float = 2.0  # HST charge pressure, the low side [MPa]
    wheel_motor_displacement_cm3: float = 400.0  # per wheel motor, per revolution [cm^3]
    max_pump_angle_rad: float = 0.31  # swash-plate angle at full displacement (~18 deg) [rad]
    max_wheel_speed_rad_s: float = 6.9  # wheel speed at full pump flow, no load (~2 m/s)
    wheel_radius_m: float = 0.29  # tyre rolling radius [m]
    drive_volumetric_efficiency: float = 0.95  # motor flow / pump flow at relief pressure

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"MachineParameters.{name}: must be finite and > 0, got {value}")
        for part in ("boom", "bucket", "telescope"):
            bore, rod = getattr(self, f"{part}_bore_m"), getattr(self, f"{part}_rod_m")
            if rod >= bore:
                raise ValueError(
                    f"MachineParameters.{part}_rod_m: must be smaller than {part}_bore_m "
                    f"({bore} m), got {rod}"
                )
        if self.drive_volumetric_efficiency >= 1.0:
            raise ValueError(
                "MachineParameters.drive_volumetric_efficiency: must lie in (0, 1), got "
                f"{self.drive_volumetric_efficiency}"
            )
        if self.tank_pressure_mpa >= self.work_relief_pressure_mpa:
            raise ValueError("MachineParameters.tank_pressure_mpa: must be below the relief")
        if self.drive_charge_pressure_mpa >= self.drive_relief_pressure_mpa:
            raise ValueError("MachineParameters.drive_charge_pressure_mpa: must be below relief")

    # ---- cylinder areas
    def piston_area_m2(self, part: str) -> float:
        """Piston-side (bore) area of the ``boom``, ``bucket`` or ``telescope`` cylinder."""
        return _circle_area_m2(getattr(self, f"{part}_bore_m"))

    def annulus_area_m2(self, part: str) -> float:
        """Rod-side (annulus) area of the ``boom``, ``bucket`` or ``telescope`` cylinder."""
        return self.piston_area_m2(part) - _circle_area_m2(getattr(self, f"{part}_rod_m"))

    def cylinder_force_range_n(self, part: str) -> tuple[float, float]:
        """(most pulling, most pushing) cylinder force [N]: one chamber at the relief
        pressure, the other at the tank pressure."""
        relief, tank = self.work_relief_pressure_mpa * MPA, self.tank_pressure_mpa * MPA
        piston, annulus = self.piston_area_m2(part), self.annulus_area_m2(part)
        return -(relief * annulus - tank * piston), relief * piston - tank * annulus

    def piston_pressure_mpa(self, part: str, force_n: float) -> float:
        """Pressure in the piston chamber [MPa] of a cylinder pushing with ``force_n``.

        A held cylinder carries its load on one chamber while the other drains to the
        tank line: pushing (force > 0) raises the piston side above the tank pressure,
        pulling leaves it at the tank pressure (the rod side takes the load). Signed, so a
        pull never reads as a push (the old |force| reading did).
        """
        tank = self.tank_pressure_mpa * MPA
        pressure = (force_n + tank * self.annulus_area_m2(part)) / self.piston_area_m2(part)
        return max(tank, pressure) / MPA

    # ---- drive
    @property
    def motor_displacement_m3_rad(self) -> float:
        """Wheel-motor displacement per radian [m^3/rad]."""
        return self.wheel_motor_displacement_cm3 * 1e-6 / (2 * math.pi)

    @property
    def max_pump_flow_m3_s(self) -> float:
        """Pump flow at full displacement [m^3/s]: both sides' series pairs (one motor's
        flow each) at ``max_wheel_speed_rad_s``."""
        return 2 * self.motor_displacement_m3_rad * self.max_wheel_speed_rad_s

    @property
    def max_drive_pressure_difference_pa(self) -> float:
        """Loop pressure difference at the HST relief [Pa]."""
        return (self.drive_relief_pressure_mpa - self.drive_charge_pressure_mpa) * MPA

    @property
    def drive_leakage_gain_pa_s_m3(self) -> float:
        """Pressure per unit of flow lost to leakage [Pa s/m^3]: at the relief pressure the
        loop loses ``1 - drive_volumetric_efficiency`` of full pump flow."""
        leak_m3_s = (1.0 - self.drive_volumetric_efficiency) * self.max_pump_flow_m3_s
        return self.max_drive_pressure_difference_pa / leak_m3_s

    @property
    def max_side_torque_nm(self) -> float:
        """Torque of one side's series pair at the HST relief pressure [N m], shared by its
        front and rear wheel as their grip allows (their pressure drops add up to the
        loop's)."""
        return self.max_drive_pressure_difference_pa * self.motor_displacement_m3_rad

    @property
    def max_boom_torque_nm(self) -> float:
        return self.cylinder_force_range_n("boom")[1] * self.boom_moment_arm_m

    @property
    def max_bucket_torque_nm(self) -> float:
        return self.cylinder_force_range_n("bucket")[1] * self.bucket_moment_arm_m

    @property
    def max_telescope_force_n(self) -> float:
        return self.cylinder_force_range_n("telescope")[1]


def load_machine_spec() -> mujoco.MjSpec:
    """The machine's editable model spec; soil models add the pile to it before compiling."""
    return mujoco.MjSpec.from_file(str(MACHINE_XML))


class Machine:
    """Named readings and commands of a compiled wheel-loader model.

    Args:
        model, data: the compiled MuJoCo model and its data.
        params: hydraulic parameters, written into the model's actuators here.
        speed_scale: fraction of rated cylinder/drive speed (cold oil < 1).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        params: MachineParameters,
        *,
        speed_scale: float = 1.0,
    ) -> None:
        self.model, self.data, self.params = model, data, params
        self.speed_scale = speed_scale

        def joint(name: str) -> tuple[int, int]:
            jid = model.joint(name).id
            return int(model.jnt_qposadr[jid]), int(model.jnt_dofadr[jid])

        def actuator(name: str) -> int:
            return model.actuator(name).id

        self._boom_q, self._boom_v = joint("boom")
        self._bucket_q, self._bucket_v = joint("bucket")
        self._telescope_q, self._telescope_v = joint("telescope")
        self._articulation_q, _ = joint("articulation")
        self._wheel_v = np.array([joint(w)[1] for w in WHEELS])
        self._tyre_joints = np.array([model.joint(f"tyre_{w[6:]}").id for w in WHEELS])
        self._tyre_q = np.array([joint(f"tyre_{w[6:]}")[0] for w in WHEELS])
        self._tyre_v = np.array([joint(f"tyre_{w[6:]}")[1] for w in WHEELS])
        self.boom_actuator = actuator("boom")
        self.bucket_actuator = actuator("bucket")
        self.telescope_actuator = actuator("telescope")
        self.drive_actuator = actuator("hst")
        self.front_frame_body = model.body("front_frame").id
        self.bucket_body = model.body("bucket").id
        self.cutting_edge_site = model.site("cutting_edge").id
        self._write_hydraulics()
        # MuJoCo's array attributes build a new NumPy view at every access (~1 us each, a
        # few dozen per control step): keep the views, they share the model's memory
        self._qpos, self._qvel, self._act = data.qpos, data.qvel, data.act
        self._ctrl, self._xmat = data.ctrl, data.xmat
        self._actuator_force, self._actuator_velocity = data.actuator_force, data.actuator_velocity
        self._own_actuators = (
            self.boom_actuator,
            self.bucket_actuator,
            self.telescope_actuator,
            self.drive_actuator,
        )
        self._forcerange, self._gainprm = model.actuator_forcerange, model.actuator_gainprm
        self._actadr = model.actuator_actadr
        self._wheel_dofs = self._wheel_v.tolist()
        self._velocity = np.empty(6)  # mj_objectVelocity's output
        self._ground_velocity = self._velocity[3:5]  # its linear x, y
        self._max_pump_flow_m3_s = params.max_pump_flow_m3_s  # a property: computed once
        # per cylinder: (tank pressure, tank pressure x annulus area, piston area), the
        # terms of ``MachineParameters.piston_pressure_mpa``
        tank = params.tank_pressure_mpa * MPA
        self._chambers = {
            part: (tank, tank * params.annulus_area_m2(part), params.piston_area_m2(part))
            for part in ("boom", "bucket", "telescope")
        }

    # ------------------------------------------------------------------ set-up
    def _write_hydraulics(self) -> None:
        m, p = self.model, self.params
        pull, push = p.cylinder_force_range_n("boom")
        m.actuator_forcerange[self.boom_actuator] = (
            pull * p.boom_moment_arm_m,
            push * p.boom_moment_arm_m,
        )
        pull, push = p.cylinder_force_range_n("bucket")
        m.actuator_forcerange[self.bucket_actuator] = (
            pull * p.bucket_moment_arm_m,
            push * p.bucket_moment_arm_m,
        )
        m.actuator_forcerange[self.telescope_actuator] = p.cylinder_force_range_n("telescope")
        # the drive: actuator force = loop pressure difference [Pa], gear = displacement
        hst, gain = self.drive_actuator, p.drive_leakage_gain_pa_s_m3
        m.actuator_gear[hst, 0] = p.motor_displacement_m3_rad
        m.actuator_gainprm[hst, 0] = gain
        m.actuator_biasprm[hst, 2] = -gain
        dp = p.max_drive_pressure_difference_pa
        m.actuator_forcerange[hst] = (-dp, dp)
        m.actuator_ctrlrange[hst] = (-p.max_pump_flow_m3_s, p.max_pump_flow_m3_s)
        m.actuator_ctrlrange[self.boom_actuator] = (-p.boom_max_speed_rad_s, p.boom_max_speed_rad_s)
        m.actuator_ctrlrange[self.bucket_actuator] = (
            -p.bucket_max_speed_rad_s,
            p.bucket_max_speed_rad_s,
        )

    def set_rolling_resistance(self, coefficient: float, *, machine_mass_kg: float) -> None:
        """Rolling resistance as a constant friction torque on each wheel hinge [N m]."""
        torque = coefficient * machine_mass_kg * 9.81 / len(WHEELS) * self.params.wheel_radius_m
        for name in WHEELS:
            self.model.dof_frictionloss[self.model.joint(name).dofadr[0]] = torque

    # ------------------------------------------------------------------ commands
    def command(self, boom: float, bucket: float, pump_fraction: float) -> None:
        """Set valve flows and the HST pump displacement.

        Args:
            boom, bucket: valve openings in [-1, 1] (fraction of full flow; + raises / curls).
            pump_fraction: HST pump displacement in [-1, 1] (+ drives forward); the pump
                flow goes to the two sides in parallel, through each side's front and rear
                wheel motors in series.
        """
        p, ctrl, s = self.params, self._ctrl, self.speed_scale
        ctrl[self.boom_actuator] = boom * p.boom_max_speed_rad_s * s
        ctrl[self.bucket_actuator] = bucket * p.bucket_max_speed_rad_s * s
        ctrl[self.telescope_actuator] = p.telescope_extension_m
        ctrl[self.drive_actuator] = pump_fraction * self._max_pump_flow_m3_s * s

    def limit_cylinder_windup(self) -> None:
        """Keep each cylinder's integrated flow within the oil-column deflection of its joint.

        When a cylinder stalls at relief pressure the oil goes over the relief valve; the
        cylinder must not "remember" the flow and jump once the load drops.
        """
        act_state, qpos = self._act, self._qpos
        forcerange, gainprm, actadr = self._forcerange, self._gainprm, self._actadr
        for act, q in ((self.boom_actuator, self._boom_q), (self.bucket_actuator, self._bucket_q)):
            # ``.item``: the entry as a float, without a NumPy scalar (the same value)
            slack = forcerange.item(act, 1) / gainprm.item(act, 0)
            adr = actadr.item(act)
            position = qpos.item(q)
            act_state[adr] = min(max(act_state.item(adr), position - slack), position + slack)

    # ------------------------------------------------------------------ readings
    def boom_angle(self) -> float:
        """theta1: boom joint angle [rad], 0 = boom horizontal, + raised."""
        return self._qpos.item(self._boom_q)

    def bucket_angle(self) -> float:
        """theta2: bucket joint angle relative to the boom [rad], + curled."""
        return self._qpos.item(self._bucket_q)

    def telescope_extension(self) -> float:
        return float(self._qpos[self._telescope_q])

    def articulation_angle(self) -> float:
        return float(self._qpos[self._articulation_q])

    def bucket_pitch(self) -> float:
        """Angle of the bucket floor above horizontal in the world [rad], + mouth up."""
        xmat, body = self._xmat, self.bucket_body  # row-major 3x3: x axis = column 0
        x, y, z = xmat.item(body, 0), xmat.item(body, 3), xmat.item(body, 6)
        return math.atan2(z, math.hypot(x, y))

    def heading(self) -> np.ndarray:
        """Unit horizontal forward direction of the front frame (world x, y)."""
        return np.array(self.heading_xy())

    def heading_xy(self) -> tuple[float, float]:
        """``heading()`` as two floats (x, y)."""
        xmat, body = self._xmat, self.front_frame_body  # row-major 3x3: x axis = column 0
        x, y = xmat.item(body, 0), xmat.item(body, 3)
        norm = max(math.hypot(x, y), 1e-9)
        return x / norm, y / norm

    def frame_tilt(self) -> float:
        """Tilt of the front frame from upright [rad] (roll and pitch together)."""
        up = self._xmat.item(self.front_frame_body, 8)  # z axis = column 2: its z is [8]
        return math.acos(min(max(up, -1.0), 1.0))

    def forward_speed(self) -> float:
        """Ground speed of the front frame along its heading [m/s]."""
        vel = self._velocity
        mujoco.mj_objectVelocity(
            self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self.front_frame_body, vel, 0
        )
        # np.dot: the product of ``@`` (a BLAS dot: its last bit follows the kernel)
        return float(np.dot(self._ground_velocity, self.heading()))

    def wheel_loads_n(self) -> np.ndarray:
        """Normal load on each tyre [N], order fl, fr, rl, rr, from its radial spring-damper
        (the wheel's own weight not included)."""
        m, d = self.model, self.data
        deflection = d.qpos[self._tyre_q] - m.qpos_spring[self._tyre_q]
        return (
            m.jnt_stiffness[self._tyre_joints] * deflection
            + m.dof_damping[self._tyre_v] * d.qvel[self._tyre_v]
        )

    def wheel_speeds(self) -> np.ndarray:
        """Wheel angular speeds [rad/s], order fl, fr, rl, rr."""
        return self._qvel[self._wheel_v]

    def wheel_slip_speed(self, forward_speed_m_s: float | None = None) -> float:
        """Mean rim speed minus ground speed of the four wheels [m/s]; > 0 when spinning.

        ``forward_speed_m_s``: ``forward_speed()`` if the caller already has it.
        """
        radius, qvel = self.params.wheel_radius_m, self._qvel
        if forward_speed_m_s is None:
            forward_speed_m_s = self.forward_speed()
        # np.mean's arithmetic on plain floats: the rim speeds added one by one to 0.0
        # (NumPy's order for a few terms), divided by their number
        total = 0.0
        for dof in self._wheel_dofs:
            total += qvel.item(dof) * radius
        return total / len(self._wheel_dofs) - forward_speed_m_s

    def drive_pressure_mpa(self) -> float:
        """p_d: HST high-side pressure [MPa].

        The two sides' motor pairs sit in parallel on the loop, so they share one pressure
        difference (the drive actuator's force), which a side's series front and rear motor
        divide between them; the high side reads it above the charge pressure whichever way
        the loop is loaded (a shuttle valve picks the higher line).
        """
        p = self.params
        loop_pa = abs(self._actuator_force.item(self.drive_actuator))
        return p.drive_charge_pressure_mpa + loop_pa / MPA

    def boom_pressure_mpa(self) -> float:
        """p_l: boom (lift) cylinder piston-side pressure [MPa]; + torque raises the boom."""
        force = self._actuator_force.item(self.boom_actuator) / self.params.boom_moment_arm_m
        return self._piston_pressure_mpa("boom", force)

    def bucket_pressure_mpa(self) -> float:
        """p_b: bucket cylinder piston-side pressure [MPa]; the piston side curls (+ theta2)."""
        force = self._actuator_force.item(self.bucket_actuator) / self.params.bucket_moment_arm_m
        return self._piston_pressure_mpa("bucket", force)

    def telescope_pressure_mpa(self) -> float:
        """p_t: telescope cylinder piston-side pressure [MPa].

        The piston side holds the telescope out against a push along the boom (the bucket
        driven into the pile); the pull of gravity on a lowered telescope and bucket is
        carried by the rod side and leaves the reading at the tank pressure.
        """
        force = self._actuator_force.item(self.telescope_actuator)
        return self._piston_pressure_mpa("telescope", force)

    def _piston_pressure_mpa(self, part: str, force_n: float) -> float:
        """``MachineParameters.piston_pressure_mpa`` with the chamber areas computed once."""
        tank, tank_annulus, piston = self._chambers[part]
        return max(tank, (force_n + tank_annulus) / piston) / MPA

    def pump_angle(self, pump_fraction: float) -> float:
        """a: HST swash-plate angle [rad] for a displacement fraction."""
        return pump_fraction * self.params.max_pump_angle_rad

    def hydraulic_power_w(self) -> float:
        """Mechanical power delivered by all cylinders and wheel motors [W] (>= 0)."""
        force, velocity = self._actuator_force, self._actuator_velocity
        # NumPy's arithmetic on plain floats: |force x velocity| added one by one to 0.0
        # (its order for a few terms), without four small arrays per call
        boom, bucket, telescope, drive = self._own_actuators
        return (
            0.0
            + abs(force.item(boom) * velocity.item(boom))
            + abs(force.item(bucket) * velocity.item(bucket))
            + abs(force.item(telescope) * velocity.item(telescope))
            + abs(force.item(drive) * velocity.item(drive))
        )
