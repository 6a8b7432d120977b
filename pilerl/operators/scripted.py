"""A scripted operator that loads a pile the way a person does, from sensors only.

Phases, as in the paper's Fig. 5 (approach, impact, filling, finished):

1. ``approach``: drive at the pile with the bucket lowered and flat.
2. ``fill``: on impact (drive or telescope pressure rises past a trigger) keep pushing,
   raise the boom and pulse the bucket curl.
3. ``finish``: stop driving, curl the bucket back and raise the boom until the scoop ends.

Styles (``OperatorStyle``) make operators differ: approach speed, trigger pressure, reaction
delay, how hard they lift and pulse, and a timed boom rise that ignores the trigger
(the "raises the boom too early" mistake). ``lift=0, finish_curl=False`` never raises the
boom at all (the other mistake the paper reports).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OperatorStyle:
    """How one operator drives.

    Attributes:
        approach_throttle: throttle while approaching [-1, 1].
        push_throttle: throttle while filling.
        trigger_pressure_mpa: drive or telescope pressure that signals impact [MPa].
        trigger_sensor: ``drive_pressure`` or ``telescope_pressure``.
        reaction_delay_s: time from impact to the first boom/bucket motion [s].
        lift: boom valve opening while filling [0, 1].
        curl_pulse: bucket valve opening during a pulse [0, 1].
        pulse_period_s: one curl pulse every this many seconds [s] (0 = curl continuously).
        pulse_duty: fraction of each period spent curling.
        boom_stall_pressure_mpa: boom pressure at which the operator feels the boom stall
            against the pile and eases off the throttle [MPa].
        stall_throttle: throttle while the boom is stalled.
        fill_boom_angle_rad: boom angle at which filling ends and finishing starts [rad].
        early_boom_rise_s: if set, start raising the boom this long after the start,
            impact or not [s].
        finish_curl: whether the operator curls back and raises at the end.
        max_fill_seconds: give up filling after this long and finish [s].
    """

    approach_throttle: float = 0.5
    push_throttle: float = 0.6
    trigger_pressure_mpa: float = 16.0
    trigger_sensor: str = "drive_pressure"
    reaction_delay_s: float = 0.2
    lift: float = 0.6
    curl_pulse: float = 0.8
    pulse_period_s: float = 1.0
    pulse_duty: float = 0.4
    boom_stall_pressure_mpa: float = 18.0
    stall_throttle: float = 0.15
    fill_boom_angle_rad: float = 0.0
    early_boom_rise_s: float | None = None
    finish_curl: bool = True
    max_fill_seconds: float = 12.0


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

    def _enter(self, phase: str) -> None:
        self.phase, self._phase_time_s = phase, 0.0

    def act(self, sensors: dict[str, np.ndarray | float]) -> np.ndarray:
        """Action [boom, bucket, throttle] for the current sensor readings."""
        st = self.style
        reading = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in sensors.items()}
        boom_angle = reading["boom_angle"]
        if self.phase == "approach":
            impact = reading[st.trigger_sensor] >= st.trigger_pressure_mpa
            early = st.early_boom_rise_s is not None and self._time_s >= st.early_boom_rise_s
            if impact or early:
                self._enter("fill")
        elif self.phase == "fill":
            done_filling = boom_angle >= st.fill_boom_angle_rad
            if st.finish_curl and (done_filling or self._phase_time_s >= st.max_fill_seconds):
                self._enter("finish")

        if self.phase == "approach":
            action = (0.0, 0.0, st.approach_throttle)
        elif self.phase == "fill":
            if self._phase_time_s < st.reaction_delay_s:
                action = (0.0, 0.0, st.push_throttle)
            else:
                t = self._phase_time_s - st.reaction_delay_s
                pulsing = st.pulse_period_s <= 0 or math.fmod(t, st.pulse_period_s) < (
                    st.pulse_duty * st.pulse_period_s
                )
                stalled = reading["boom_pressure"] >= st.boom_stall_pressure_mpa
                throttle = st.stall_throttle if stalled else st.push_throttle
                action = (st.lift, st.curl_pulse if pulsing else 0.0, throttle)
        else:
            action = (1.0, 1.0, 0.0)
        self._time_s += self.dt
        self._phase_time_s += self.dt
        return np.asarray(action, dtype=np.float32)
