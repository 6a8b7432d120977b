"""A scripted operator that loads a pile the way a person does, from sensors only.

Phases, as in the paper's Fig. 5 (approach, impact, filling, finished):

1. ``approach``: drive at the pile with the bucket lowered and flat.
2. ``fill``: on impact (the trigger sensor rises past a threshold), after a reaction
   delay, cycle through short single actions: push (throttle), lift (boom), curl (bucket),
   like people, who mostly move one control at a time (the paper counts 88 % of samples
   with one active control). An ``overlap`` operator keeps pushing while lifting and
   curling instead. When the boom stalls against the pile the operator eases off.
3. ``finish``: curl the bucket back, then raise the boom (both at once for an
   ``overlap`` operator), until the scoop ends.

Styles (``OperatorStyle``) make operators differ; ``sample_style`` draws one per episode,
including the two mistakes the paper reports: raising the boom too early (a timed boom
rise that ignores the pile) and never raising it (a trigger that never fires on ice).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PHASES = ("approach", "fill", "finish")


@dataclass
class OperatorStyle:
    """How one operator drives (also the ``operator`` config schema of the recipes).

    Attributes:
        approach_throttle: throttle while approaching [-1, 1].
        push_throttle: throttle of a push during filling.
        trigger_pressure_mpa: reading of ``trigger_sensor`` that signals impact [MPa].
        trigger_sensor: ``drive_pressure`` or ``telescope_pressure``.
        trigger_hold_s: how long the reading must stay above the threshold before the
            operator reacts [s]: people do not react to a 40 ms pressure blip (such as the
            HST's start-up peak), and this keeps the behaviour independent of the rate.
        reaction_delay_s: time from impact to the first filling action [s].
        lift: boom valve opening while lifting [0, 1].
        curl: bucket valve opening while curling [0, 1].
        push_s, lift_s, curl_s: durations of the push, lift and curl actions of one
            filling cycle [s].
        overlap: keep pushing while lifting and curling (several controls at once).
        boom_stall_pressure_mpa: boom pressure at which the boom is felt to stall and the
            operator stops pushing for the rest of the cycle [MPa].
        fill_boom_angle_rad: boom angle at which filling ends [rad].
        finish_curl_angle_rad: bucket angle reached before raising at the end [rad].
        early_boom_rise_s: if set, start filling this long after the start, impact or
            not [s] (the "raises the boom too early" mistake).
        max_fill_seconds: give up filling after this long and finish [s].
    """

    approach_throttle: float = 0.5
    push_throttle: float = 0.7
    trigger_pressure_mpa: float = 16.0
    trigger_sensor: str = "drive_pressure"
    trigger_hold_s: float = 0.15
    reaction_delay_s: float = 0.2
    lift: float = 0.7
    curl: float = 0.8
    push_s: float = 0.5
    lift_s: float = 0.5
    curl_s: float = 0.5
    overlap: bool = False
    boom_stall_pressure_mpa: float = 18.0
    fill_boom_angle_rad: float = 0.0
    finish_curl_angle_rad: float = 1.2
    early_boom_rise_s: float | None = None
    max_fill_seconds: float = 12.0

    def __post_init__(self) -> None:
        if self.trigger_sensor not in ("drive_pressure", "telescope_pressure"):
            raise ValueError(
                f"OperatorStyle.trigger_sensor: must be drive_pressure or "
                f"telescope_pressure, got {self.trigger_sensor!r}"
            )
        for name in ("push_s", "lift_s", "curl_s", "max_fill_seconds"):
            if not getattr(self, name) > 0:
                raise ValueError(f"OperatorStyle.{name}: must be > 0")


TRIGGER_RANGES_MPA = {"drive_pressure": (13.0, 20.0), "telescope_pressure": (1.5, 2.5)}


def sample_style(
    rng: np.random.Generator,
    *,
    mistake_rate: float = 0.28,
    overlap_rate: float = 0.6,
    trigger_sensor: str = "drive_pressure",
) -> OperatorStyle:
    """Draw an operator style: most operators sensible, varied in pace and timing.

    Args:
        rng: random generator (the recording seed makes the draw reproducible).
        mistake_rate: probability that the operator raises the boom too early.
        overlap_rate: probability of an operator who keeps pushing while lifting/curling.
        trigger_sensor: what tells the operator the bucket hit the pile. People feel the
            machine stall; on dry ground that coincides with the drive pressure rising
            (``drive_pressure``, the paper's summer cue). On ice the wheels spin instead,
            and the felt contact force is better modelled by the telescope pressure
            (``telescope_pressure``), e.g. for winter validation demonstrations.
    """
    early = rng.random() < mistake_rate
    low, high = TRIGGER_RANGES_MPA[trigger_sensor]
    return OperatorStyle(
        approach_throttle=float(rng.uniform(0.35, 0.7)),
        push_throttle=float(rng.uniform(0.4, 0.8)),
        trigger_sensor=trigger_sensor,
        trigger_pressure_mpa=float(rng.uniform(low, high)),
        reaction_delay_s=float(rng.uniform(0.1, 0.6)),
        lift=float(rng.uniform(0.4, 1.0)),
        curl=float(rng.uniform(0.5, 1.0)),
        push_s=float(rng.uniform(0.2, 0.8)),
        lift_s=float(rng.uniform(0.3, 1.0)),
        curl_s=float(rng.uniform(0.2, 0.7)),
        overlap=bool(rng.random() < overlap_rate),
        fill_boom_angle_rad=float(rng.uniform(-0.15, 0.15)),
        early_boom_rise_s=float(rng.uniform(0.3, 1.5)) if early else None,
    )


class ScriptedScoopOperator:
    """Acts from a dict of named sensor readings; call ``reset`` before each episode.

    Args:
        style: the operator's style.
        dt: control period [s].
    """

    def __init__(self, style: OperatorStyle | None = None, *, dt: float) -> None:
        self.style = style or OperatorStyle()
        self.dt = dt
        self.reset()

    def reset(self) -> None:
        self.phase = "approach"
        self._time_s = 0.0
        self._phase_time_s = 0.0
        self._stalled_cycle = -1
        self._above_trigger_s = 0.0

    def _enter(self, phase: str) -> None:
        self.phase, self._phase_time_s = phase, 0.0

    def act(self, sensors: dict[str, np.ndarray | float]) -> np.ndarray:
        """Action [boom, bucket, throttle] for the current sensor readings."""
        st = self.style
        reading = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in sensors.items()}
        if self.phase == "approach":
            above = reading[st.trigger_sensor] >= st.trigger_pressure_mpa
            self._above_trigger_s = self._above_trigger_s + self.dt if above else 0.0
            impact = self._above_trigger_s >= st.trigger_hold_s - 1e-9
            early = st.early_boom_rise_s is not None and self._time_s >= st.early_boom_rise_s
            if impact or early:
                self._enter("fill")
        elif self.phase == "fill":
            done = reading["boom_angle"] >= st.fill_boom_angle_rad
            if done or self._phase_time_s >= st.max_fill_seconds:
                self._enter("finish")

        if self.phase == "approach":
            action = (0.0, 0.0, st.approach_throttle)
        elif self.phase == "fill":
            action = self._fill_action(reading)
        elif st.overlap:
            action = (1.0, 1.0, 0.0)  # finish: curl back and raise together...
        elif reading["bucket_angle"] < st.finish_curl_angle_rad:
            action = (0.0, 1.0, 0.0)  # ...or curl back first,
        else:
            action = (1.0, 0.0, 0.0)  # then raise
        self._time_s += self.dt
        self._phase_time_s += self.dt
        return np.asarray(action, dtype=np.float32)

    def _fill_action(self, reading: dict[str, float]) -> tuple[float, float, float]:
        st = self.style
        t = self._phase_time_s - st.reaction_delay_s
        if t < 0:
            return (0.0, 0.0, 0.0)
        cycle_s = st.push_s + st.lift_s + st.curl_s
        cycle, in_cycle = divmod(t, cycle_s)
        if reading["boom_pressure"] >= st.boom_stall_pressure_mpa:
            self._stalled_cycle = int(cycle)
        throttle = 0.0 if self._stalled_cycle == int(cycle) else st.push_throttle
        if in_cycle < st.push_s:
            return (0.0, 0.0, throttle)
        if in_cycle < st.push_s + st.lift_s:
            return (st.lift, 0.0, throttle if st.overlap else 0.0)
        return (0.0, st.curl, throttle if st.overlap else 0.0)


def active_controls(actions: np.ndarray, *, threshold: float = 0.05) -> np.ndarray:
    """Number of controls with |u| > threshold in each row of ``actions`` (T, 3)."""
    return (np.abs(actions) > threshold).sum(axis=-1)


def phase_index(phase: str) -> int:
    return PHASES.index(phase)


__all__ = [
    "OperatorStyle",
    "ScriptedScoopOperator",
    "active_controls",
    "phase_index",
    "sample_style",
]
