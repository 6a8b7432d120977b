"""PileLoading-v0: one scoop of a compact wheel loader into a gravel (or snow) pile.

## Description
An articulated-frame wheel loader of the Avant 635 class starts 1-5 m from a pile with its
bucket lowered, drives into the pile, and fills its bucket by raising the boom and curling
the bucket, as in Yang et al., "Neural Network Controller for Autonomous Pile Loading
Revised". The machine is a MuJoCo model; the pile is a pluggable soil model.

## Action Space
``Box(-1, 1, (3,), float32)``: u = <u_theta1, u_theta2, u_g>, normalised delta velocities.

| index | name     | meaning                                              |
|-------|----------|------------------------------------------------------|
| 0     | boom     | boom valve: fraction of full flow, + raises          |
| 1     | bucket   | bucket valve: fraction of full flow, + curls back    |
| 2     | throttle | HST pump displacement: fraction of full, + forward   |

Finite values outside [-1, 1] are clipped; NaN/inf or a wrong shape raise ``ValueError``.

## Observation Space
``Dict`` of seven ``Box(low, high, (1,), float32)`` sensors (``sensors.SENSORS``): boom_angle
[rad], bucket_angle [rad], drive_pressure [MPa], telescope_pressure [MPa], boom_pressure
[MPa], bucket_pressure [MPa], pump_angle [rad]. Additive Gaussian noise (``sensor_noise``).

## Rewards
The sum of the parts in ``info``: reward_fill, reward_spill, reward_time, reward_energy,
reward_success (``task.RewardWeights``).

## Episode End
Terminated when the bucket is curled back and raised (scoop finished; ``success`` if at
least half full) or when the machine tips. Truncated after ``max_episode_seconds``.

## Arguments
See ``PileLoadingEnv.__init__``.

## Version History
- v0: first release.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from .conditions import Condition, get_condition
from .latency import ActuationDelay
from .machine import Machine, MachineParameters, load_machine_spec
from .sensors import CONTROL_NAMES, SENSORS
from .soil import BucketGeometry, PileGeometry, get_soil_model
from .task import RewardWeights, ScoopTask, reward_parts

INITIAL_BOOM_ANGLE_RAD = -0.45  # bucket lowered: floor a few cm above the ground
SETTLE_SECONDS = 0.6  # simulated time to settle on the tyres after reset [s]
LATERAL_OFFSET_RANGE_M = (-0.3, 0.3)  # where along the pile face the bucket aims [m]
REWARD_PART_NAMES = (
    "reward_fill",
    "reward_spill",
    "reward_time",
    "reward_energy",
    "reward_success",
)


# MuJoCo's warnings for a bad state (it resets the data when one fires): qpos, qvel, qacc
_BAD_STATE_WARNINGS = slice(
    int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQACC) + 1
)


class PileLoadingEnv(gym.Env):
    """Gymnasium environment of one wheel-loader scoop (see module docstring).

    Args:
        condition: preset name, ``summer`` or ``winter_a`` .. ``winter_d``.
        soil: soil model name, ``heightfield`` (fast, default) or ``particles``.
        soil_options: keyword options of the soil model, e.g. ``{"max_particles": 350}``.
        control_hz: control rate [Hz] (20 default; the real machine ran at 3).
        physics_hz: physics rate [Hz], at least 500.
        soil_hz: soil-model update rate [Hz]: a whole number of updates per control step,
            or, when control is faster than that, one update every few control steps.
        sensor_noise: a multiplier of every sensor's default noise std (0 = noiseless), or
            a mapping ``{sensor name: std in the sensor's unit}`` for the sensors to change
            (the others keep their default).
        start_distance_range_m: cutting edge to pile toe at reset, drawn uniformly [m].
        approach_angle_range_deg: heading relative to the pile normal, drawn uniformly [deg].
        condition_overrides: replace preset fields, e.g. ``{"material": {"cohesion_pa": 0}}``.
        machine: hydraulic parameters; pile: pile shape; bucket: bucket shape.
        task: episode rules; reward_weights: reward part weights.
        render_mode: ``None`` or ``"rgb_array"``; render_size: (height, width) [px].
        camera: MJCF camera name for rendering (``side`` or ``overview``).
        actuation_latency_s: dead time from a command to the valves and the pump [s], or
            a range ``(low, high)`` drawn per episode; the real machine: 3 Hz control with
            0.1-0.3 s latency (``latency.ActuationDelay``). 0 (default) = none.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        condition: str | Condition = "summer",
        *,
        soil: str = "heightfield",
        soil_options: Mapping[str, object] | None = None,
        control_hz: float = 20.0,
        physics_hz: float = 500.0,
        soil_hz: float = 40.0,
        sensor_noise: float | Mapping[str, float] = 1.0,
        start_distance_range_m: Sequence[float] = (1.0, 5.0),
        approach_angle_range_deg: Sequence[float] = (-10.0, 10.0),
        condition_overrides: dict[str, dict[str, float]] | None = None,
        machine: MachineParameters | None = None,
        pile: PileGeometry | None = None,
        bucket: BucketGeometry | None = None,
        task: ScoopTask | None = None,
        reward_weights: RewardWeights | None = None,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (480, 640),
        camera: str = "side",
        actuation_latency_s: float | Sequence[float] = 0.0,
    ) -> None:
        super().__init__()
        base = condition if isinstance(condition, Condition) else get_condition(condition)
        self.condition = base.with_overrides(condition_overrides)
        _check_rates(control_hz, physics_hz, soil_hz)
        _check_range("start_distance_range_m", start_distance_range_m, 0.5, 20.0)
        _check_range("approach_angle_range_deg", approach_angle_range_deg, -45.0, 45.0)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode: must be None or 'rgb_array', got {render_mode!r}")

        self.start_distance_range_m = tuple(float(v) for v in start_distance_range_m)
        self.approach_angle_range_rad = tuple(math.radians(v) for v in approach_angle_range_deg)
        self.task = task or ScoopTask()
        self.reward_weights = reward_weights or RewardWeights()
        self.render_mode, self.render_size, self.camera = render_mode, render_size, camera

        # ---- model: machine + soil
        soil_cls = get_soil_model(soil)
        self.soil = soil_cls(
            self.condition.material,
            pile or PileGeometry(),
            bucket or BucketGeometry(),
            **_checked_soil_options(soil_cls, soil_options),
        )
        spec = load_machine_spec()
        spec.option.timestep = 1.0 / physics_hz
        load_x, load_z = self.soil.bucket.centroid_xz()  # the load sits at the inside's centroid
        spec.body("payload").pos = [load_x, 0.0, load_z]
        self.soil.add_to_spec(spec)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.machine = Machine(
            self.model,
            self.data,
            machine or MachineParameters(),
            speed_scale=self.condition.hydraulics.speed_scale,
        )
        self.model.geom_friction[self.model.geom("ground").id, 0] = (
            self.condition.ground.tyre_friction
        )
        self.machine_mass_kg = float(self.model.body_subtreemass[self.model.body("rear_frame").id])
        self.machine.set_rolling_resistance(
            self.condition.ground.rolling_resistance, machine_mass_kg=self.machine_mass_kg
        )
        self.soil.bind(self.model, self.data, self.machine)

        # ---- timing: control period = frame_skip physics steps, split into soil chunks
        self.frame_skip = max(1, round(physics_hz / control_hz))
        self.dt = self.frame_skip * self.model.opt.timestep  # control period [s]
        n_chunks = max(1, min(self.frame_skip, round(self.dt * soil_hz)))
        self._chunks = np.diff(np.linspace(0, self.frame_skip, n_chunks + 1).round().astype(int))
        self._chunk_steps = self._chunks.tolist()  # the same, as ints for the step loop
        self._timestep = float(self.model.opt.timestep)
        # physics steps between soil updates: after every chunk when control is slower than
        # the soil rate, else every few control steps (counted across steps)
        if self.dt * soil_hz >= 1.0:
            self._soil_period_steps = int(self._chunks.min())
        else:
            self._soil_period_steps = round(1.0 / (soil_hz * self.model.opt.timestep))
        self._steps_since_soil = 0
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dt}

        self._delay = ActuationDelay(
            actuation_latency_s,
            physics_dt=self.model.opt.timestep,
            frame_skip=self.frame_skip,
            n_controls=3,
        )
        self._delayed = self._delay.enabled  # else a command acts for the whole step
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Dict(
            {s.name: spaces.Box(s.low, s.high, shape=(1,), dtype=np.float32) for s in SENSORS}
        )
        self.sensor_units = {s.name: s.unit for s in SENSORS}  # for dataset writers
        self.control_names = CONTROL_NAMES
        self._noise_std = _noise_std(sensor_noise)
        self._noisy = bool(self._noise_std.any())
        # each sensor's (name, low, high), read with plain floats at every step
        self._sensor_ranges = [(s.name, float(s.low), float(s.high)) for s in SENSORS]
        self._sensor_names = [s.name for s in SENSORS]
        self._renderer: mujoco.Renderer | None = None
        self._boom_valve = self._bucket_valve = self._pump_fraction = 0.0
        # the valves' and the pump's first-order lag over a chunk of physics steps, by chunk
        # length (a handful of lengths recur: computed once, not at every chunk)
        self._lag_blends: dict[int, tuple[float, float]] = {}
        self._qpos, self._qvel = self.data.qpos, self.data.qvel  # views: see Machine
        self._xpos = self.data.xpos
        self._elapsed_s = 0.0
        self._episode_over = True  # no episode until reset(): step() refuses

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        rng = self.np_random
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        distance = rng.uniform(*self.start_distance_range_m)
        angle = rng.uniform(*self.approach_angle_range_rad)
        aim_y = rng.uniform(*LATERAL_OFFSET_RANGE_M)
        self._set_start_pose(distance, angle, aim_y)
        self.soil.reset(rng)
        self._delay.reset(rng)
        self._boom_valve = self._bucket_valve = self._pump_fraction = 0.0
        self._elapsed_s = 0.0
        self._episode_over = False
        self._energy_j = 0.0
        self._steps_since_soil = 0
        self._run_physics(round(SETTLE_SECONDS / m.opt.timestep))
        self._energy_j = 0.0
        self._last_fill = self.soil.fill_fraction
        self._last_spilled = self.soil.spilled_kg
        self._start = {
            "start_distance_m": distance,
            "approach_angle_rad": angle,
            "aim_offset_m": aim_y,
        }
        return self._observation(), self._info(scoop_finished=False, tipped=False, parts=None)

    def step(self, action):
        if self._episode_over:
            raise RuntimeError(
                "PileLoadingEnv.step: the episode has ended (terminated or truncated) or was "
                "never started; call reset() before stepping again"
            )
        u = _validate_action(action)
        energy_before = self._energy_j
        if self._delayed:
            for n_steps, command in self._delay.segments(np.array(u)):
                self._run_physics(n_steps, command=command)
        else:  # what ``segments`` gives without a delay: the command, the whole step
            self._run_physics(self.frame_skip, command=u)
        self._elapsed_s += self.dt

        fill = self.soil.fill_fraction
        rated_kg = self.soil.bucket.rated_volume_m3 * self.condition.material.density_kg_m3
        pitch, hinge_height = self.machine.bucket_pitch(), self._hinge_height()
        scoop_finished = (
            pitch >= self.task.curled_pitch_rad and hinge_height >= self.task.raised_hinge_height_m
        )
        tipped = self.machine.frame_tilt() > self.task.max_frame_tilt_rad
        succeeded = scoop_finished and fill >= self.task.success_fill_fraction
        parts = reward_parts(
            self.reward_weights,
            fill_gain=fill - self._last_fill,
            spilled_fraction_gain=(self.soil.spilled_kg - self._last_spilled) / rated_kg,
            seconds=self.dt,
            work_kj=(self._energy_j - energy_before) / 1e3,
            succeeded=succeeded,
        )
        self._last_fill, self._last_spilled = fill, self.soil.spilled_kg
        terminated = scoop_finished or tipped
        truncated = (not terminated) and self._elapsed_s >= self.task.max_episode_seconds - 1e-9
        self._episode_over = terminated or truncated
        info = self._info(
            scoop_finished=scoop_finished,
            tipped=tipped,
            parts=parts,
            bucket_pitch_rad=pitch,
            hinge_height_m=hinge_height,
            fill=fill,
        )
        return self._observation(), float(sum(parts.values())), terminated, truncated, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            height, width = self.render_size
            self._renderer = mujoco.Renderer(self.model, height=height, width=width)
            # offscreen rendering runs in software on machines without a GPU: reflections
            # double the cost of a frame and show little on a gravel site
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.soil.prepare_render(self._renderer)
        self._renderer.update_scene(self.data, camera=self.camera)
        return self._renderer.render()

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ internals
    def _set_start_pose(self, distance_m: float, angle_rad: float, aim_y_m: float) -> None:
        m, d = self.model, self.data
        boom = INITIAL_BOOM_ANGLE_RAD
        for joint, value in (
            ("boom", boom),
            ("bucket", -boom),
            ("telescope", self.machine.params.telescope_extension_m),
        ):
            d.qpos[m.joint(joint).qposadr[0]] = value
        d.act[m.actuator_actadr[self.machine.boom_actuator]] = boom
        d.act[m.actuator_actadr[self.machine.bucket_actuator]] = -boom
        mujoco.mj_kinematics(m, d)
        root = d.xpos[m.body("rear_frame").id]
        edge_ahead = d.site_xpos[self.machine.cutting_edge_site][0] - root[0]
        heading = np.array([math.cos(angle_rad), math.sin(angle_rad)])
        origin = np.array([self.soil.pile.toe_x_m, aim_y_m]) - (distance_m + edge_ahead) * heading
        d.qpos[0:2] = origin
        d.qpos[3:7] = [math.cos(angle_rad / 2), 0.0, 0.0, math.sin(angle_rad / 2)]
        mujoco.mj_forward(m, d)

    def _run_physics(self, n_steps: int, *, command: np.ndarray | None = None) -> None:
        """Advance ``n_steps`` physics steps in soil-update chunks, with valve/pump lag.

        Without ``command`` the valves and pump keep their state (used to settle at reset).
        """
        m, d, machine, soil = self.model, self.data, self.machine, self.soil
        timestep = self._timestep
        whole_step = n_steps == self.frame_skip
        chunks = self._chunk_steps if whole_step else _split(n_steps, self._chunks)
        if command is not None:
            boom, bucket, pump = map(float, command)
        # the valve and pump states and the tallies in locals through the loop, written
        # back after it (the same arithmetic, in the same order)
        boom_valve, bucket_valve, pump_fraction = (
            self._boom_valve,
            self._bucket_valve,
            self._pump_fraction,
        )
        steps_since_soil, soil_period, energy_j = (
            self._steps_since_soil,
            self._soil_period_steps,
            self._energy_j,
        )
        for steps in chunks:
            chunk_dt = steps * timestep
            if command is not None:
                blends = self._lag_blends.get(steps) or self._lag_blend(steps, chunk_dt)
                valve_blend, pump_blend = blends
                boom_valve += valve_blend * (boom - boom_valve)
                bucket_valve += valve_blend * (bucket - bucket_valve)
                pump_fraction += pump_blend * (pump - pump_fraction)
            machine.command(boom_valve, bucket_valve, pump_fraction)
            soil.advance(m, d, steps)
            steps_since_soil += steps
            if steps_since_soil >= soil_period:
                soil.update(steps_since_soil * timestep)
                steps_since_soil = 0
            energy_j += machine.hydraulic_power_w() * chunk_dt
        self._boom_valve, self._bucket_valve, self._pump_fraction = (
            boom_valve,
            bucket_valve,
            pump_fraction,
        )
        self._steps_since_soil, self._energy_j = steps_since_soil, energy_j
        machine.limit_cylinder_windup()
        # one check for both: a sum of squares is finite exactly when every entry is
        # finite and none is beyond ~1e154 (a state that large has diverged as well)
        qpos, qvel = self._qpos, self._qvel
        if not math.isfinite(np.dot(qpos, qpos) + np.dot(qvel, qvel)):
            raise RuntimeError(
                f"simulation diverged (non-finite state) at t={self._elapsed_s:.3f} s; "
                "check the condition overrides and machine parameters"
            )
        # MuJoCo itself resets a state with a NaN, Inf or huge qpos/qvel/qacc to the
        # model's initial pose (and warns): the episode would go on from there unnoticed
        if d.warning.number[_BAD_STATE_WARNINGS].any():
            raise RuntimeError(
                f"simulation diverged: MuJoCo found a non-finite or huge state and reset it, "
                f"at t={self._elapsed_s:.3f} s; check the condition overrides and machine "
                "parameters"
            )

    def _lag_blend(self, steps: int, chunk_dt: float) -> tuple[float, float]:
        """(valve, pump) fraction of the way to the command covered in ``chunk_dt`` [s]."""
        blends = self._lag_blends.get(steps)
        if blends is None:
            hydraulics = self.condition.hydraulics
            blends = (
                1.0 - math.exp(-chunk_dt / hydraulics.valve_lag_s),
                1.0 - math.exp(-chunk_dt / hydraulics.pump_lag_s),
            )
            self._lag_blends[steps] = blends
        return blends

    def _hinge_height(self) -> float:
        return self._xpos.item(self.machine.bucket_body, 2)

    def _observation(self) -> dict[str, np.ndarray]:
        """The sensors' readings: noise added, clipped to each sensor's range, float32."""
        mc = self.machine
        values = [
            mc.boom_angle(),
            mc.bucket_angle(),
            mc.drive_pressure_mpa(),
            mc.telescope_pressure_mpa(),
            mc.boom_pressure_mpa(),
            mc.bucket_pressure_mpa(),
            mc.pump_angle(self._pump_fraction),
        ]
        if self._noisy:
            noise = self.np_random.normal(0.0, self._noise_std).tolist()
            values = [value + n for value, n in zip(values, noise, strict=True)]
        # np.clip's rule on plain floats: NaN stays, below low gives low, above high high
        # (one difference: np.clip(-0.0, 0.0, ...) keeps -0.0, this gives 0.0; no sensor
        # reads exactly -0.0: pressures sit at least at the tank's, noise is never -0.0)
        clipped = []
        for value, (_, low, high) in zip(values, self._sensor_ranges, strict=True):
            value = value if (value != value or value > low) else low
            clipped.append(value if (value != value or value < high) else high)
        # one float32 array; each sensor gets its row, a (1,) view as a slice of it would be
        readings = np.array(clipped, dtype=np.float32).reshape(-1, 1)
        return dict(zip(self._sensor_names, readings, strict=True))

    def _info(
        self,
        *,
        scoop_finished: bool,
        tipped: bool,
        parts: dict[str, float] | None,
        bucket_pitch_rad: float | None = None,
        hinge_height_m: float | None = None,
        fill: float | None = None,
    ) -> dict:
        """The step's ``info``; ``bucket_pitch_rad``, ``hinge_height_m`` and ``fill`` (the
        fill fraction) if already read."""
        soil, mc = self.soil, self.machine
        if fill is None:
            fill = soil.fill_fraction
        forward_speed = mc.forward_speed()
        if bucket_pitch_rad is None:
            bucket_pitch_rad = mc.bucket_pitch()
        if hinge_height_m is None:
            hinge_height_m = self._hinge_height()
        info = {
            "fill_fraction": fill,
            "success": bool(scoop_finished and fill >= self.task.success_fill_fraction),
            "scoop_finished": scoop_finished,
            "tipped": tipped,
            "bucket_load_kg": soil.bucket_load_kg,
            "spilled_kg": soil.spilled_kg,
            "pile_mass_kg": soil.pile_mass_kg,
            "cutting_depth_m": soil.cutting_depth_m(),
            "wheel_slip_m_s": mc.wheel_slip_speed(forward_speed),
            "forward_speed_m_s": forward_speed,
            "bucket_pitch_rad": bucket_pitch_rad,
            "bucket_hinge_height_m": hinge_height_m,
            "hydraulic_energy_kj": self._energy_j / 1e3,
            "elapsed_s": self._elapsed_s,
            **self._start,
        }
        info.update(parts or dict.fromkeys(REWARD_PART_NAMES, 0.0))
        return info


def _validate_action(action) -> tuple[float, float, float]:
    """The action as three floats, clipped to [-1, 1] (np.clip's rule); a clear error for a
    wrong shape or a non-finite value."""
    # a float array's entries as floats directly: they convert exactly, as through
    # np.asarray(action, float64), without the copy
    floats = isinstance(action, np.ndarray) and action.dtype.kind == "f"
    u = action if floats else np.asarray(action, dtype=np.float64)
    if u.shape != (3,):
        raise ValueError(
            f"PileLoadingEnv.step: action must have shape (3,) = [boom, bucket, throttle], "
            f"got shape {u.shape}"
        )
    values = u.tolist()
    if not all(math.isfinite(v) for v in values):
        bad = [
            name
            for name, v in zip(("boom", "bucket", "throttle"), values, strict=True)
            if not math.isfinite(v)
        ]
        raise ValueError(
            f"PileLoadingEnv.step: action has non-finite values in {bad}: "
            f"{np.asarray(u, dtype=np.float64)}"
        )
    boom, bucket, throttle = (v if v > -1.0 else -1.0 for v in values)
    return (
        boom if boom < 1.0 else 1.0,
        bucket if bucket < 1.0 else 1.0,
        throttle if throttle < 1.0 else 1.0,
    )


def _checked_soil_options(soil_cls: type, options: Mapping[str, object] | None) -> dict:
    """``options`` if the soil model takes them all as keyword options, else a clear error."""
    options = dict(options or {})
    accepted = [
        name
        for name, p in inspect.signature(soil_cls.__init__).parameters.items()
        if p.kind is inspect.Parameter.KEYWORD_ONLY
    ]
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise ValueError(
            f"soil_options: soil model {soil_cls.name!r} has no option(s) "
            f"{unknown}; its options: {accepted}"
        )
    return options


def _noise_std(sensor_noise: float | Mapping[str, float]) -> np.ndarray:
    """Noise std per sensor, in ``SENSORS`` order, from a multiplier or a per-name mapping."""
    default = np.array([s.noise_std for s in SENSORS])
    if isinstance(sensor_noise, Mapping):
        names = [s.name for s in SENSORS]
        unknown = sorted(set(sensor_noise) - set(names))
        if unknown:
            raise ValueError(f"sensor_noise: unknown sensor(s) {unknown}; known: {names}")
        std = default.copy()
        for name, value in sensor_noise.items():
            std[names.index(name)] = value
    else:
        std = default * sensor_noise
    if not (np.isfinite(std).all() and (std >= 0).all()):
        raise ValueError(f"sensor_noise: every std must be finite and >= 0, got {sensor_noise}")
    return std


def _split(n_steps: int, like: np.ndarray) -> list[int]:
    """Split ``n_steps`` into chunks no longer than the control-step chunks."""
    size = int(like.max())
    return [size] * (n_steps // size) + ([n_steps % size] if n_steps % size else [])


def _check_rates(control_hz: float, physics_hz: float, soil_hz: float) -> None:
    if not (math.isfinite(physics_hz) and physics_hz >= 500.0):
        raise ValueError(f"physics_hz: must be >= 500 Hz, got {physics_hz}")
    if not (math.isfinite(control_hz) and 0.5 <= control_hz <= physics_hz):
        raise ValueError(
            f"control_hz: must lie in [0.5, physics_hz={physics_hz}], got {control_hz}"
        )
    if not (math.isfinite(soil_hz) and soil_hz > 0):
        raise ValueError(f"soil_hz: must be finite and > 0, got {soil_hz}")


def _check_range(name: str, value: Sequence[float], low: float, high: float) -> None:
    if len(value) != 2 or not all(math.isfinite(v) for v in value):
        raise ValueError(f"{name}: must be two finite numbers (low, high), got {value!r}")
    if not (low <= value[0] <= value[1] <= high):
        raise ValueError(f"{name}: must satisfy {low} <= low <= high <= {high}, got {value!r}")
