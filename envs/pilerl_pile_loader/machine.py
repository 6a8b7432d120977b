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


@dataclass(frozen=True)
class MachineParameters:
    """Hydraulic and drive parameters of an Avant 635-class loader (see docs/machine_model.md).

    Cylinders are modelled in joint space: a cylinder of piston area A acting at an
    effective moment arm r gives joint torque ``p * A * r`` at pressure p.
    """

    # Work hydraulics
    work_relief_pressure_mpa: float = 20.0  # relief valve setting of the work circuit [MPa]
    tank_pressure_mpa: float = 0.5  # return-line pressure, the floor of every reading [MPa]
    boom_piston_area_m2: float = math.pi * 0.070**2 / 4  # 70 mm bore [m^2]
    boom_moment_arm_m: float = 0.32  # effective lever of the boom cylinder [m]
    boom_max_speed_rad_s: float = 0.45  # full-flow boom speed [rad/s]
    bucket_piston_area_m2: float = math.pi * 0.060**2 / 4  # 60 mm bore [m^2]
    bucket_moment_arm_m: float = 0.20  # effective lever of the bucket cylinder [m]
    bucket_max_speed_rad_s: float = 0.80  # full-flow bucket speed [rad/s]
    telescope_piston_area_m2: float = math.pi * 0.050**2 / 4  # 50 mm bore [m^2]
    telescope_extension_m: float = 0.30  # held extension during a scoop [m]
    # Hydrostatic transmission (HST)
    drive_relief_pressure_mpa: float = 25.0  # HST high-pressure relief [MPa]
    drive_charge_pressure_mpa: float = 2.0  # HST charge pressure, the idle reading [MPa]
    wheel_motor_displacement_cm3: float = 200.0  # per wheel motor, per revolution [cm^3]
    max_pump_angle_rad: float = 0.31  # swash-plate angle at full displacement (~18 deg) [rad]
    max_wheel_speed_rad_s: float = 6.9  # wheel speed at full pump angle (~2 m/s) [rad/s]
    wheel_radius_m: float = 0.29  # tyre rolling radius [m]
    drive_servo_gain: float = 3000.0  # wheel-motor torque per rad/s of speed error [N m s]

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"MachineParameters.{name}: must be finite and > 0, got {value}")

    @property
    def motor_displacement_m3_rad(self) -> float:
        """Wheel-motor displacement per radian [m^3/rad]."""
        return self.wheel_motor_displacement_cm3 * 1e-6 / (2 * math.pi)

    @property
    def max_wheel_torque_nm(self) -> float:
        """Wheel-motor torque at the HST relief pressure [N m]."""
        delta_p = (self.drive_relief_pressure_mpa - self.drive_charge_pressure_mpa) * MPA
        return delta_p * self.motor_displacement_m3_rad

    @property
    def max_boom_torque_nm(self) -> float:
        return (
            self.work_relief_pressure_mpa * MPA * self.boom_piston_area_m2 * self.boom_moment_arm_m
        )

    @property
    def max_bucket_torque_nm(self) -> float:
        relief = self.work_relief_pressure_mpa * MPA
        return relief * self.bucket_piston_area_m2 * self.bucket_moment_arm_m

    @property
    def max_telescope_force_n(self) -> float:
        return self.work_relief_pressure_mpa * MPA * self.telescope_piston_area_m2


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
        self.boom_actuator = actuator("boom")
        self.bucket_actuator = actuator("bucket")
        self.telescope_actuator = actuator("telescope")
        self.wheel_actuators = np.array([actuator(w) for w in WHEELS])
        self.front_frame_body = model.body("front_frame").id
        self.bucket_body = model.body("bucket").id
        self.cutting_edge_site = model.site("cutting_edge").id
        self._write_hydraulics()

    # ------------------------------------------------------------------ set-up
    def _write_hydraulics(self) -> None:
        m, p = self.model, self.params
        m.actuator_forcerange[self.boom_actuator] = (-p.max_boom_torque_nm, p.max_boom_torque_nm)
        m.actuator_forcerange[self.bucket_actuator] = (
            -p.max_bucket_torque_nm,
            p.max_bucket_torque_nm,
        )
        m.actuator_forcerange[self.telescope_actuator] = (
            -p.max_telescope_force_n,
            p.max_telescope_force_n,
        )
        for a in self.wheel_actuators:
            m.actuator_forcerange[a] = (-p.max_wheel_torque_nm, p.max_wheel_torque_nm)
            m.actuator_gainprm[a, 0] = p.drive_servo_gain
            m.actuator_biasprm[a, 2] = -p.drive_servo_gain
            m.actuator_ctrlrange[a] = (-p.max_wheel_speed_rad_s, p.max_wheel_speed_rad_s)
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
            pump_fraction: HST pump displacement in [-1, 1] (+ drives forward).
        """
        p, d, s = self.params, self.data, self.speed_scale
        d.ctrl[self.boom_actuator] = boom * p.boom_max_speed_rad_s * s
        d.ctrl[self.bucket_actuator] = bucket * p.bucket_max_speed_rad_s * s
        d.ctrl[self.telescope_actuator] = p.telescope_extension_m
        d.ctrl[self.wheel_actuators] = pump_fraction * p.max_wheel_speed_rad_s * s

    def limit_cylinder_windup(self) -> None:
        """Keep each cylinder's integrated flow within the oil-column deflection of its joint.

        When a cylinder stalls at relief pressure the oil goes over the relief valve; the
        cylinder must not "remember" the flow and jump once the load drops.
        """
        m, d = self.model, self.data
        for act, q in ((self.boom_actuator, self._boom_q), (self.bucket_actuator, self._bucket_q)):
            slack = m.actuator_forcerange[act, 1] / m.actuator_gainprm[act, 0]
            adr = m.actuator_actadr[act]
            d.act[adr] = np.clip(d.act[adr], d.qpos[q] - slack, d.qpos[q] + slack)

    # ------------------------------------------------------------------ readings
    def boom_angle(self) -> float:
        """theta1: boom joint angle [rad], 0 = boom horizontal, + raised."""
        return float(self.data.qpos[self._boom_q])

    def bucket_angle(self) -> float:
        """theta2: bucket joint angle relative to the boom [rad], + curled."""
        return float(self.data.qpos[self._bucket_q])

    def telescope_extension(self) -> float:
        return float(self.data.qpos[self._telescope_q])

    def articulation_angle(self) -> float:
        return float(self.data.qpos[self._articulation_q])

    def bucket_pitch(self) -> float:
        """Angle of the bucket floor above horizontal in the world [rad], + mouth up."""
        x_axis = self.data.xmat[self.bucket_body].reshape(3, 3)[:, 0]
        return float(math.atan2(x_axis[2], math.hypot(x_axis[0], x_axis[1])))

    def heading(self) -> np.ndarray:
        """Unit horizontal forward direction of the front frame (world x, y)."""
        xmat = self.data.xmat[self.front_frame_body]  # row-major 3x3: x axis = column 0
        x, y = float(xmat[0]), float(xmat[3])
        norm = max(math.hypot(x, y), 1e-9)
        return np.array([x / norm, y / norm])

    def frame_tilt(self) -> float:
        """Tilt of the front frame from upright [rad] (roll and pitch together)."""
        z_axis = self.data.xmat[self.front_frame_body].reshape(3, 3)[:, 2]
        return float(math.acos(np.clip(z_axis[2], -1.0, 1.0)))

    def forward_speed(self) -> float:
        """Ground speed of the front frame along its heading [m/s]."""
        vel = np.empty(6)
        mujoco.mj_objectVelocity(
            self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self.front_frame_body, vel, 0
        )
        return float(vel[3:5] @ self.heading())

    def wheel_speeds(self) -> np.ndarray:
        """Wheel angular speeds [rad/s], order fl, fr, rl, rr."""
        return self.data.qvel[self._wheel_v]

    def wheel_slip_speed(self) -> float:
        """Mean rim speed minus ground speed of the four wheels [m/s]; > 0 when spinning."""
        rim_speed = self.wheel_speeds() * self.params.wheel_radius_m
        return float(np.mean(rim_speed) - self.forward_speed())

    def drive_pressure_mpa(self) -> float:
        """p_d: HST high-side pressure [MPa] from the wheel-motor torques (traction)."""
        torque = np.abs(self.data.actuator_force[self.wheel_actuators]).mean()
        p = self.params
        return p.drive_charge_pressure_mpa + torque / p.motor_displacement_m3_rad / MPA

    def boom_pressure_mpa(self) -> float:
        """p_l: boom cylinder load pressure [MPa] from the cylinder torque."""
        p = self.params
        force = abs(self.data.actuator_force[self.boom_actuator]) / p.boom_moment_arm_m
        return p.tank_pressure_mpa + force / p.boom_piston_area_m2 / MPA

    def bucket_pressure_mpa(self) -> float:
        """p_b: bucket cylinder load pressure [MPa] from the cylinder torque."""
        p = self.params
        force = abs(self.data.actuator_force[self.bucket_actuator]) / p.bucket_moment_arm_m
        return p.tank_pressure_mpa + force / p.bucket_piston_area_m2 / MPA

    def telescope_pressure_mpa(self) -> float:
        """p_t: telescope cylinder pressure [MPa] from the force along the boom."""
        p = self.params
        force = abs(self.data.actuator_force[self.telescope_actuator])
        return p.tank_pressure_mpa + force / p.telescope_piston_area_m2 / MPA

    def pump_angle(self, pump_fraction: float) -> float:
        """a: HST swash-plate angle [rad] for a displacement fraction."""
        return pump_fraction * self.params.max_pump_angle_rad

    def hydraulic_power_w(self) -> float:
        """Mechanical power delivered by all cylinders and wheel motors [W] (>= 0)."""
        d = self.data
        power = np.abs(d.actuator_force * d.actuator_velocity)
        own = [
            self.boom_actuator,
            self.bucket_actuator,
            self.telescope_actuator,
            *self.wheel_actuators,
        ]
        return float(power[own].sum())
