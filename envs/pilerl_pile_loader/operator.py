"""The pile loader's scripted expert: an operator who reacts to what the machine feels like.

People load a pile by feel, not by the clock (Yang et al., "Neural Network Controller for
Autonomous Pile Loading Revised", Fig. 5: drive toward the pile, impact, filling, finished).
This operator acts only on the machine's sensor readings, and every change of what it does
is triggered by something it senses:

1. ``approach``: drive at the pile with the boom at rest and the bucket held level (small
   corrections when the boom or the bucket floor drifts, as a person keeps the bucket flat).
2. ``fill``: the *impact* is felt as the drive (or telescope) pressure rising well above the
   level felt while driving. The operator starts lifting while still pushing, and keeps
   crowding the pile until the boom has risen a little; when the boom stalls against the
   pile (its relief valve opens, or it does not rise), or the bucket floor lags behind the
   boom's rise, it curls the bucket, with its foot off the gas (people rarely work two
   controls at once), until the floor has turned a step and the boom is free again (the
   push has relaxed, or the boom's relief valve has closed); when the wheels slip (the drive
   pressure collapses under a push) it eases off the throttle. Once the boom has risen far
   enough, or the bucket is curled back, the scoop is filled.
3. ``finish``: curl the bucket back, back off out of the pile until the machine rolls back
   steadily (the drive pressure has settled after the set-off surge), then raise the boom
   (some operators raise while they curl), until the scoop ends. A scoop that came up
   *light* (the boom rose out of the pile before the bucket was curled full) is not
   finished: the operator backs off, lowers the boom, levels the bucket (one control at a
   time) and drives at the pile again, as often as it takes or until time runs out.

With ``OperatorStyle.crowd_fill`` the operator fills the way a person does through the
bucket mouth: it keeps crowding the pile while the boom rises through the face (lift and
push together while the edge is in the face, felt on the telescope pressure), takes its foot
off while a boom pinned by the push (lifting, and it does not rise) comes up a step, curls a
step to break out when it does not come up once the push has relaxed, and fills with the
wrist (lift while curling, gentle push) when the wheels slip; a scoop whose bucket never bit
into the face is light. Every cue of its filling is felt on the four controller sensors
(boom and bucket angle, drive and telescope pressure). Driving, it also takes the machine
stopping with its wheels turning (the drive pressure well up and flat: on ice it tops out
short of the impact rise) for the impact. Off by default.

With ``OperatorStyle.impact_cue="stall"`` the rise is not enough: the operator drives in
until the machine stops pushing forward (the drive pressure held at its relief, or flat
well above what rolling took: the wheels turning on ice), so a granular face's brief
impact spike is not taken for the impact; with ``OperatorStyle.push_again`` it crowds
again once the boom is free after a curl that found the boom and the bucket both held.
Both on by default since session 33 (docs/operators.md, "Stall cue and pushing again");
``impact_cue="rise"`` and ``push_again=False`` give the operator the demonstrations were
recorded with until then.

Styles (``OperatorStyle``) make operators differ (pace, valve openings, how far they push
and lift, how much they curl per lift), and ``sample_style`` draws one per episode. The
paper's mistakes are behaviours, triggered by what the operator senses like everything
else: a *jumpy* operator takes the surge of the drive pressure when the machine sets off
for the impact and lifts early; a *hesitant* operator stops at the impact and waits for the
felt pressure to relax before lifting, without pushing; a *timid* operator curls early
and lifts out of the pile soon, which leaves the bucket under-filled.

Recording option ``executed_noise`` (DART, Laskey et al. 2017): a slowly varying random
perturbation is added to the *executed* boom and bucket commands while the operator's own
clean command stays the label (``last_label``), so demonstrations show how the operator
corrects drifts it never makes itself.

**Decision rate.** A person corrects a joystick a few times a second, not 500 times: at a
control rate faster than 20 Hz (the paper's 500 Hz recordings) the operator reads the
sensors and decides on every k-th step only, k = floor(``DECISION_PERIOD_S`` / dt) with
``DECISION_PERIOD_S`` = 0.05 s (the env's default 20 Hz control period), and holds its
command in between, as a hand holds a lever. Its felt levels, windows and timers run on
that decision clock. Where 0.05 s is a whole number of control steps (500, 100, 60 Hz) it
decides exactly at 20 Hz, so a 500 Hz recording is the 20 Hz operator sampled finer;
elsewhere it decides a little faster (every step below 40 Hz, every 0.04 s at 50 Hz). At
20 Hz and slower it decides on every step, as before.

Controls are ``[boom, bucket, throttle]`` in [-1, 1] (see ``env``); sensor readings in rad
and MPa (``sensors.SENSORS``). This module depends on numpy only.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from .machine import MachineParameters

PHASES: tuple[str, ...] = ("approach", "fill", "finish")
TRIGGER_SENSORS: tuple[str, ...] = ("drive_pressure", "telescope_pressure")
# what makes a rise of the trigger sensor the impact (``OperatorStyle.impact_cue``)
IMPACT_CUES: tuple[str, ...] = ("rise", "stall")
# the default operator drives in until the machine stops and pushes again once the boom is
# free (docs/operators.md, "Stall cue and pushing again": the cue a granular face's brief
# impact burst does not fool, so that both soil models are read alike)
DEFAULT_IMPACT_CUE = "stall"
DEFAULT_PUSH_AGAIN = True

# How far above the felt driving level the trigger sensor must rise to be felt as impact,
# drawn per operator [MPa]: the drive pressure climbs to its relief (~25 MPa) within a
# few tenths of a second of contact in summer; the telescope pressure by 3.4 MPa in summer
# and 0.7 MPa on ice (docs/machine_model.md, typical readings; sensor noise 0.1 MPa).
IMPACT_RISE_RANGES_MPA = {"drive_pressure": (5.0, 9.0), "telescope_pressure": (0.5, 1.0)}
JUMPY_RISE_FRACTION = 0.35  # a jumpy operator reacts to this fraction of a sensible rise

RELAXED_FRACTION = 0.5  # gas off while curling: the boom is free once p_d < this x the push's peak
BACK_STEADY_S = 0.5  # backing off ends when the drive pressure has been steady this long [s] ...
BACK_STEADY_MPA = 1.0  # ... within this band [MPa] (the set-off surge has passed)
GO_AGAIN_BACK_OFF = 0.3  # least reverse throttle to back off before going again
NOISE_CORRELATION_S = 0.4  # correlation time of the DART perturbation [s]
NOISED_CONTROLS = (0, 1)  # boom and bucket (the throttle stays clean)
LEVEL_RISE_S = 1.5  # how fast the felt driving level follows a rising reading [s]
LEVEL_FALL_S = 0.2  # ... and a falling one (quickly, but not every noise dip) [s]
# crowd fill (``OperatorStyle.crowd_fill``)
CROWD_LIFT_STEP_RAD = 0.03  # foot off while the pinned boom comes up this step [rad]
FACE_CONTACT_MPA = 0.5  # the edge is in the face while p_t reads this above its free reading
# the drive's relief, which a stalled push reads: the machine's (docs/machine_model.md)
DRIVE_RELIEF_MPA = MachineParameters.drive_relief_pressure_mpa
DRIVE_CHARGE_MPA = MachineParameters.drive_charge_pressure_mpa  # the loop's low side
TRACTION_CAP_FRACTION = 0.8  # a push flat below this x the relief: the wheels spin [MPa/MPa]
SPIN_RISE_FRACTION = 0.5  # driving: p_d flat this x the impact rise above driving: stopped
# stall cue: the push is held at the drive's relief while p_d is within this of it [MPa]
RELIEF_HELD_BAND_MPA = 1.0
AT_RELIEF_MPA = DRIVE_RELIEF_MPA - RELIEF_HELD_BAND_MPA
# stall cue with a telescope trigger: the drive-pressure rise the stop is measured by (the
# middle of a drive-pressure operator's impact rise) [MPa]
DRIVE_IMPACT_RISE_MPA = sum(IMPACT_RISE_RANGES_MPA["drive_pressure"]) / 2
DIG_LIFT_FRACTION = 0.5  # while still pushing, the boom is lifted gently (x ``lift``)
STALL_WINDOW_S = 0.3  # the boom is felt to stall when, lifting this long, ...
STALL_RISE_RAD = 0.01  # ... it has risen less than this [rad]
# push_again: the boom is felt free once its pressure has stayed below its stall this long
# (a person does not react to a 50 ms dip; the nominal ``impact_hold_s``) [s]
BOOM_FREE_HOLD_S = 0.15
DECISION_PERIOD_S = 0.05  # decide every floor(this / dt) control steps, hold between [s]


@dataclass(frozen=True)
class OperatorStyle:
    """How one operator drives. Angles in rad, pressures in MPa, valve openings in [0, 1].

    Attributes:
        trigger_sensor: what the impact is felt by: ``drive_pressure`` (the machine stalls,
            the paper's summer cue) or ``telescope_pressure`` (the bucket is pushed back).
        approach_throttle: throttle while driving to the pile.
        impact_rise_mpa: rise of the trigger sensor above the level felt while driving
            that is taken as the impact.
        impact_hold_s: how long the rise must last before the operator believes it [s]
            (a person does not react to a 50 ms blip; 0 for a jumpy operator).
        push_throttle: throttle while pushing into the pile.
        push_lift_rad: keep pushing until the boom has risen this far above rest.
        lift: boom valve opening while lifting.
        curl: bucket valve opening while curling.
        curl_per_lift: bucket-floor pitch wanted per rad of boom rise during filling: the
            bucket is curled whenever its floor lags behind this.
        curl_band_rad: how far the bucket floor may lag behind the wanted pitch.
        curl_step_rad: how far one curl turns the bucket floor.
        boom_stall_mpa: boom pressure felt as the boom stalling (the relief valve opens);
            not used by a crowding operator (it feels the boom angle instead).
        bucket_stall_mpa: bucket pressure felt as the bucket stalling: stop curling; not
            used by a crowding operator (it feels the bucket angle instead).
        slip_drop_fraction: while pushing, a drive pressure below this fraction of the
            highest one felt in this push is felt as the wheels slipping: ease off.
        ease_throttle: throttle after easing off.
        fill_lift_rad: boom rise above rest at which filling is done.
        finish_bucket_angle_rad: bucket joint angle reached before raising at the end.
        raise_speed: boom valve opening while raising at the end.
        finish_overlap: curl back and raise together at the end.
        hesitant: at the impact, stop pushing and wait until the drive pressure has relaxed
            to half the impact rise before lifting.
        jumpy: take a small rise of the trigger sensor as the impact (the early-lift mistake).
        hold_gain_per_rad: approach correction of the boom and bucket-floor drift [1/rad].
        hold_deadband_rad: drift left alone during the approach [rad].
        go_again: after a light scoop, back off and go again instead of finishing.
        push_while_curling: keep the throttle on while curling in the pile (otherwise the
            operator takes its foot off the gas while it curls, unless the wheels have
            slipped: then it keeps its gentle push on, or the machine would lose the pile).
        back_off_throttle: reverse throttle when backing off out of the pile before
            raising (0: raise in the pile).
        crowd_fill: fill by crowding through the face (``PileLoadingOperator._crowd_fill``,
            docs/operators.md "Crowd fill"): keep pushing while the boom rises, so the
            bucket mouth keeps passing through material; off by default (the operator the
            demonstrations were recorded with).
        impact_cue: what makes the trigger's rise the impact (``IMPACT_CUES``): ``rise``:
            the rise held ``impact_hold_s``; ``stall`` (the default): drive in until the
            machine stops pushing forward, then lift: the drive pressure held at the
            drive's relief (within ``RELIEF_HELD_BAND_MPA``) for ``impact_hold_s`` with
            the rise, or the machine stopped with its wheels turning (the drive pressure
            well up on the last rolling level and flat: on ice it tops out at what the
            tyres hold, short of the rise); with a telescope trigger, the rise held
            ``impact_hold_s`` as well (``PileLoadingOperator._felt_impact``). A jumpy
            operator takes its small rise at once with either cue.
        push_again: after a curl that ended with the boom and the bucket both held (the
            operator stopped crowding), crowd the pile again once the boom is free (lifting,
            its pressure below ``boom_stall_mpa`` for ``BOOM_FREE_HOLD_S``; after a first
            re-push, come up ``CROWD_LIFT_STEP_RAD`` since) while it is still below
            ``push_lift_rad``; on by default (off: the operator never pushes again in that
            scoop). Not used by a crowding operator.
    """

    trigger_sensor: str = "drive_pressure"
    approach_throttle: float = 0.4
    impact_rise_mpa: float = 7.0
    impact_hold_s: float = 0.15
    push_throttle: float = 0.6
    push_lift_rad: float = 0.08
    lift: float = 0.7
    curl: float = 0.7
    curl_per_lift: float = 1.8
    curl_band_rad: float = 0.08
    curl_step_rad: float = 0.2
    boom_stall_mpa: float = 19.0
    bucket_stall_mpa: float = 19.0
    slip_drop_fraction: float = 0.5
    ease_throttle: float = 0.2
    fill_lift_rad: float = 0.3
    finish_bucket_angle_rad: float = 1.2
    raise_speed: float = 0.8
    finish_overlap: bool = False
    hesitant: bool = False
    jumpy: bool = False
    hold_gain_per_rad: float = 5.0
    hold_deadband_rad: float = 0.01
    go_again: bool = True
    push_while_curling: bool = False
    back_off_throttle: float = 0.3
    crowd_fill: bool = False
    impact_cue: str = DEFAULT_IMPACT_CUE
    push_again: bool = DEFAULT_PUSH_AGAIN

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.type in (bool, "bool") and not isinstance(getattr(self, f.name), bool):
                raise ValueError(
                    f"OperatorStyle.{f.name}: must be true or false, got {getattr(self, f.name)!r}"
                )
        if self.trigger_sensor not in TRIGGER_SENSORS:
            raise ValueError(
                f"OperatorStyle.trigger_sensor: must be one of {TRIGGER_SENSORS}, "
                f"got {self.trigger_sensor!r}"
            )
        if self.impact_cue not in IMPACT_CUES:
            raise ValueError(
                f"OperatorStyle.impact_cue: must be one of {IMPACT_CUES}, got {self.impact_cue!r}"
            )
        for name in (
            "approach_throttle",
            "push_throttle",
            "lift",
            "curl",
            "ease_throttle",
            "raise_speed",
            "slip_drop_fraction",
            "back_off_throttle",
        ):
            _check(name, getattr(self, name), 0.0, 1.0)
        for name in (
            "impact_rise_mpa",
            "impact_hold_s",
            "push_lift_rad",
            "curl_per_lift",
            "curl_band_rad",
            "curl_step_rad",
            "boom_stall_mpa",
            "bucket_stall_mpa",
            "fill_lift_rad",
            "hold_gain_per_rad",
            "hold_deadband_rad",
        ):
            _check(name, getattr(self, name), 0.0, math.inf)
        _check("finish_bucket_angle_rad", self.finish_bucket_angle_rad, -math.pi, math.pi)


def _check(name: str, value: float, low: float, high: float) -> None:
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"OperatorStyle.{name}: must lie in [{low}, {high}], got {value}")


def sample_style(
    rng: np.random.Generator,
    *,
    trigger_sensor: str = "drive_pressure",
    mistake_rate: float = 0.28,
    crowd_fill: bool = False,
    impact_cue: str = DEFAULT_IMPACT_CUE,
    push_again: bool = DEFAULT_PUSH_AGAIN,
) -> OperatorStyle:
    """Draw one operator: varied in pace, valve openings, how they fill and how briskly
    they back off; with probability ``mistake_rate`` one who makes one of the paper's
    mistakes (jumpy: lifts early on a false impact cue; timid: curls early and lifts out,
    under-filling). Every operator goes again after a scoop that came up light.
    ``crowd_fill``: every operator fills by crowding (``OperatorStyle.crowd_fill``);
    ``impact_cue``, ``push_again``: every operator feels the impact by that cue and
    pushes again once the boom is free (``OperatorStyle``); the draws are the same
    whatever these are."""
    low, high = IMPACT_RISE_RANGES_MPA[trigger_sensor]
    mistake = rng.random() < mistake_rate
    kind = rng.choice(("jumpy", "timid")) if mistake else "none"
    timid = kind == "timid"
    return OperatorStyle(
        trigger_sensor=trigger_sensor,
        approach_throttle=float(rng.uniform(0.12, 0.3)),
        impact_rise_mpa=float(rng.uniform(low, high)),
        impact_hold_s=0.0 if kind == "jumpy" else float(rng.uniform(0.1, 0.25)),
        push_throttle=float(rng.uniform(0.4, 0.8)),
        push_lift_rad=float(rng.uniform(0.0, 0.03) if timid else rng.uniform(0.1, 0.2)),
        lift=float(rng.uniform(0.2, 0.45)),
        curl=float(rng.uniform(0.25, 0.55)),
        curl_per_lift=float(rng.uniform(3.0, 4.0)) if timid else 1.8,
        fill_lift_rad=0.15 if timid else 0.3,
        raise_speed=float(rng.uniform(0.4, 0.9)),
        finish_overlap=bool(rng.random() < 0.3),
        hesitant=bool(rng.random() < 0.15),
        jumpy=kind == "jumpy",
        back_off_throttle=float(rng.uniform(0.2, 0.4)),
        crowd_fill=crowd_fill,
        impact_cue=impact_cue,
        push_again=push_again,
    )


OPTIONS = (
    "trigger_sensor",
    "mistake_rate",
    "executed_noise",
    "crowd_fill",
    "impact_cue",
    "push_again",
)


def make_expert(
    *, dt: float, rng: np.random.Generator | None = None, **options: object
) -> PileLoadingOperator:
    """The pile loader's scripted expert (the plugin's ``scripted_expert``).

    Args:
        dt: control period [s].
        rng: ``None`` for the nominal operator (deterministic); else one operator style
            drawn from ``rng`` (one call per recorded episode).
        options: ``trigger_sensor`` (``drive_pressure`` | ``telescope_pressure``),
            ``mistake_rate`` (share of operators drawn with a mistake, in [0, 1]),
            ``executed_noise`` (std of the DART perturbation of the executed boom and
            bucket commands, in [0, 1]; 0 = off), ``crowd_fill`` (fill by crowding through
            the face, ``OperatorStyle.crowd_fill``; default off), ``impact_cue`` (``rise``
            or ``stall``, ``OperatorStyle.impact_cue``; default ``stall``), ``push_again``
            (``OperatorStyle.push_again``; default on); for the nominal operator
            also any ``OperatorStyle`` field (e.g. ``jumpy``, ``push_throttle``) to set its
            style.
    """
    style_fields = {f.name for f in fields(OperatorStyle)} - {"trigger_sensor"}
    # a drawn operator takes the mistake rate; the nominal one its style, field by field
    known = (
        OPTIONS if rng is not None else ("trigger_sensor", "executed_noise", *sorted(style_fields))
    )
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ValueError(
            f"pile_loader scripted expert: unknown option(s) {unknown}; known: {list(known)}"
        )
    trigger_sensor = str(options.get("trigger_sensor", "drive_pressure"))
    if trigger_sensor not in TRIGGER_SENSORS:
        raise ValueError(
            f"pile_loader scripted expert: trigger_sensor must be one of {TRIGGER_SENSORS}, "
            f"got {trigger_sensor!r}"
        )
    impact_cue = str(options.get("impact_cue", DEFAULT_IMPACT_CUE))
    if impact_cue not in IMPACT_CUES:
        raise ValueError(
            f"pile_loader scripted expert: impact_cue must be one of {IMPACT_CUES}, "
            f"got {impact_cue!r}"
        )
    mistake_rate = _fraction("mistake_rate", options.get("mistake_rate", 0.28))
    executed_noise = _fraction("executed_noise", options.get("executed_noise", 0.0))
    if rng is None:
        chosen = {k: v for k, v in options.items() if k in style_fields}
        # the impact is felt on the trigger sensor's own scale unless the rise is given
        low, high = IMPACT_RISE_RANGES_MPA[trigger_sensor]
        chosen.setdefault("impact_rise_mpa", (low + high) / 2)
        style, noise_seed = OperatorStyle(trigger_sensor=trigger_sensor, **chosen), 0
    else:
        style = sample_style(
            rng,
            trigger_sensor=trigger_sensor,
            mistake_rate=mistake_rate,
            crowd_fill=_flag("crowd_fill", options.get("crowd_fill", False)),
            impact_cue=impact_cue,
            push_again=_flag("push_again", options.get("push_again", DEFAULT_PUSH_AGAIN)),
        )
        noise_seed = int(rng.integers(2**63 - 1))
    return PileLoadingOperator(style, dt=dt, executed_noise=executed_noise, noise_seed=noise_seed)


def _flag(name: str, value: object) -> bool:
    """``value`` as a boolean (``true``/``false`` text too); anything else fails naming
    the option."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, str) and value.lower() in ("true", "false"):
        return value.lower() == "true"
    raise ValueError(f"pile_loader scripted expert: {name} must be true or false, got {value!r}")


def _fraction(name: str, value: object) -> float:
    """``value`` as a number in [0, 1]; anything else fails naming the option."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(
            f"pile_loader scripted expert: {name} must be a number in [0, 1], got {value!r}"
        ) from None
    if not (math.isfinite(number) and 0.0 <= number <= 1.0):
        raise ValueError(f"pile_loader scripted expert: {name} must lie in [0, 1], got {number}")
    return number


class PileLoadingOperator:
    """Acts from a mapping of named sensor readings; call ``reset`` before each episode.

    Args:
        style: how this operator drives.
        dt: control period [s]; the operator decides every ``steps_per_decision`` steps
            (every step below 40 Hz, see the module's "Decision rate").
        executed_noise: std of the DART perturbation of the executed boom and bucket
            commands (0 = off); ``last_label`` stays the clean command.
        noise_seed: seed of the perturbation (the same sequence after every ``reset``).

    Attributes:
        control_dt: the control period [s].
        steps_per_decision: control steps per decision (1 below 40 Hz).
        dt: the decision period [s] (``control_dt * steps_per_decision``), the clock of the
            operator's felt levels, windows and timers.
    """

    PHASES = PHASES

    def __init__(
        self,
        style: OperatorStyle | None = None,
        *,
        dt: float,
        executed_noise: float = 0.0,
        noise_seed: int = 0,
    ) -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"PileLoadingOperator.dt: must be > 0 s, got {dt}")
        self.style = style or OperatorStyle()
        self.control_dt = dt
        self.steps_per_decision = max(1, math.floor(DECISION_PERIOD_S / dt + 1e-9))
        self.dt = dt * self.steps_per_decision
        self.executed_noise = executed_noise
        self.noise_seed = noise_seed
        self.reset()

    @property
    def style_description(self) -> dict:
        """The style as plain values (for episode metadata)."""
        return dataclasses.asdict(self.style)

    def reset(self) -> None:
        self.phase = "approach"
        self.last_label = np.zeros(3, dtype=np.float32)
        self._steps_to_decision = 0  # control steps until the next decision
        self._rest_boom: float | None = None  # boom angle at rest, felt at the start [rad]
        self._rest_pitch = 0.0  # boom + bucket angle with the floor level [rad]
        self._free_telescope = 0.0  # telescope reading with the bucket free, felt at the start
        self._noise = np.zeros(3)
        self._noise_rng = np.random.default_rng(self.noise_seed)
        self._start_attempt()

    def _start_attempt(self) -> None:
        """Forget what was felt in the last scoop: drive at the pile (again)."""
        self._felt_level: float | None = None  # trigger reading felt while driving [MPa]
        self._above_s = 0.0  # how long the trigger has been above the impact level [s]
        self._relief_s = 0.0  # stall cue: how long the drive has been at its relief [s]
        self._pushed_back = False  # stall cue, telescope trigger: the p_t rise has been held
        self._impact_reading = 0.0
        self._waiting = False  # hesitant operator waiting after the impact
        self._action = "lift"  # in filling: lift or curl
        self._pushing = False  # in filling: still crowding the pile with the throttle
        self._held_off = False  # in filling: stopped crowding with boom and bucket both held
        self._repushed_at: float | None = None  # push_again: boom angle at the last re-push
        self._curl_from = 0.0  # bucket-floor pitch when the curl began [rad]
        # what the operator remembers, as long as its windows (in decisions)
        self._boom_trace: deque[float] = deque(maxlen=self._steps(STALL_WINDOW_S))  # lifting
        self._drive_trace: deque[float] = deque(maxlen=self._steps(BACK_STEADY_S))  # backing off
        self._push_peak = 0.0
        self._eased = False
        # crowd fill: the drive pressure while crowding in the face, while driving at the
        # pile, and while crowding out of the face; the highest telescope reading in this
        # push [MPa]; the boom angle where the pinned boom was freed [rad]; whether the
        # bucket has bitten into the face
        self._push_trace: deque[float] = deque(maxlen=self._steps(STALL_WINDOW_S))
        self._approach_trace: deque[float] = deque(maxlen=self._steps(BACK_STEADY_S))
        self._roll_trace: deque[float] = deque(maxlen=self._steps(BACK_STEADY_S))
        self._rolling = False  # driving: rolling steadily at a pressure it is used to
        self._rolling_level = 0.0  # stall cue: p_d when last rolling steadily [MPa]
        self._face_peak = 0.0
        self._free_from = 0.0
        self._bucket_trace: deque[float] = deque(maxlen=self._steps(STALL_WINDOW_S))  # curling
        self._breaking_out = False  # crowd fill: this curl breaks a held-down boom out
        self._bitten = False
        self._light = False  # finishing: the scoop came up light, go again after backing off
        self._curled_back = False
        self._set_off = False  # backing off: the machine has started to roll back
        self._backed_off = False
        self._posture_set = False  # approach: boom at rest and bucket level before driving

    # ------------------------------------------------------------------ acting
    def act(self, sensors: Mapping[str, object]) -> np.ndarray:
        """The executed command [boom, bucket, throttle] for these readings; the clean
        command is kept in ``last_label``. Between decisions the last one is held."""
        if self._steps_to_decision > 0:
            self._steps_to_decision -= 1
            return self._executed(self.last_label)
        self._steps_to_decision = self.steps_per_decision - 1
        reading = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in sensors.items()}
        if self._rest_boom is None:
            self._free_telescope = reading["telescope_pressure"]
            self._rest_boom = reading["boom_angle"]
            self._rest_pitch = reading["boom_angle"] + reading["bucket_angle"]
        self._update_phase(reading)
        if self.phase == "approach":
            command = self._approach(reading)
        elif self.phase == "fill":
            command = self._fill(reading)
        else:
            command = self._finish(reading)
        self.last_label = np.clip(np.asarray(command, dtype=np.float32), -1.0, 1.0)
        return self._executed(self.last_label)

    def _update_phase(self, reading: dict[str, float]) -> None:
        st = self.style
        if self.phase == "approach" and self._felt_impact(reading):
            self.phase = "fill"
            self._waiting = st.hesitant
            self._action, self._pushing = "lift", not st.hesitant
            self._push_peak = reading["drive_pressure"]
        if self.phase == "fill":
            risen = reading["boom_angle"] - self._rest_boom
            curled = reading["bucket_angle"] >= st.finish_bucket_angle_rad
            if risen >= st.fill_lift_rad or curled:
                self.phase = "finish"
                # a crowding operator brings the bucket up through the face before it curls
                # back: its scoop is light if the bucket never bit into the face
                light = not self._bitten if st.crowd_fill else not curled
                self._light = st.go_again and light

    def _felt_impact(self, reading: dict[str, float]) -> bool:
        """Impact: the trigger reading stays well above the level felt while driving.

        The felt level follows the reading down quickly (``LEVEL_FALL_S``) and up slowly
        (``LEVEL_RISE_S``), so the operator gets used to the pressure of driving at its own
        pace but not to the impact. A jumpy operator reacts at once to a small rise, such
        as the surge when the machine sets off.

        With ``impact_cue`` ``stall`` ("drive in until the machine stops pushing forward,
        then lift") the machine must have stopped pushing forward:

        - drive-pressure trigger: the rise with the drive pressure at its relief (within
          ``RELIEF_HELD_BAND_MPA``) for ``impact_hold_s``, or, without the rise, the
          machine stopped with its wheels turning (``_felt_stop`` from the last rolling
          level: on ice p_d tops out short of the rise);
        - telescope trigger: the rise held ``impact_hold_s`` (the bucket pushed back), and
          the drive pressure at its relief as long, or the machine stopped with its wheels
          turning.

        A bucket's impact on the face that drives the pressure to the relief for a few tens
        of milliseconds (a granular face) is not the machine stopping. A crowding operator
        also feels the stop with the default cue (drive-pressure trigger only). With the
        stall cue an operator that feels neither keeps pushing until the episode ends.
        """
        st = self.style
        value, drive = reading[st.trigger_sensor], reading["drive_pressure"]
        self._approach_trace.append(drive)
        if self._felt_level is None:
            self._felt_level = value
        else:
            settle_s = LEVEL_FALL_S if value < self._felt_level else LEVEL_RISE_S
            self._felt_level += (value - self._felt_level) * min(1.0, self.dt / settle_s)
        rise = st.impact_rise_mpa * (JUMPY_RISE_FRACTION if st.jumpy else 1.0)
        above = value - self._felt_level >= rise
        self._above_s = self._above_s + self.dt if above else 0.0
        self._relief_s = self._relief_s + self.dt if drive >= AT_RELIEF_MPA else 0.0
        held = above and self._above_s >= st.impact_hold_s - 1e-9
        stall_cue = st.impact_cue == "stall" and not st.jumpy
        if stall_cue:
            at_relief = self._relief_s >= st.impact_hold_s - 1e-9
            stopped = self._felt_stop(drive, from_rolling=True)
            if st.trigger_sensor == "drive_pressure":
                felt = (above and at_relief) or stopped
            else:  # the bucket pushed back (the p_t rise held once, remembered while the
                # felt level creeps up behind it), and the machine stopped pushing
                self._pushed_back = self._pushed_back or held
                felt = self._pushed_back and (at_relief or stopped)
        else:
            felt = held or (st.crowd_fill and self._felt_stop(drive))
        if felt:
            self._impact_reading = value
            return True
        return False

    def _felt_stop(self, drive: float, *, from_rolling: bool = False) -> bool:
        """Driving, the machine is felt to stop at the pile with its wheels turning: once
        rolling steadily at a pressure the operator is used to, the drive pressure
        ``drive`` [MPa] comes well up (``SPIN_RISE_FRACTION`` of the impact rise above the
        felt level) and stays flat (within ``BACK_STEADY_MPA`` over ``STALL_WINDOW_S``); on
        ice it tops out at what the tyres hold, below the rise the operator waits for.
        With a ``drive_pressure`` trigger (the felt level is the drive's); with a
        telescope trigger only ``from_rolling``.

        ``from_rolling`` (the stall cue): well up above the drive pressure when last
        steady (within ``BACK_STEADY_MPA`` over ``BACK_STEADY_S``: rolling, which the
        stop's flat ``STALL_WINDOW_S`` is too short to be) instead of the felt level now,
        which creeps up through a long, shaky push into a granular pile on ice (p_d 7-16
        MPa for about 1.5 s before the machine stops at ~11.5 MPa). Felt with either
        trigger; with a telescope trigger "well up" is ``SPIN_RISE_FRACTION`` of
        ``DRIVE_IMPACT_RISE_MPA``."""
        st = self.style
        by_drive = st.trigger_sensor == "drive_pressure"
        if not (by_drive or from_rolling):
            return False
        steady = self._steady(self._approach_trace, BACK_STEADY_S)
        if steady:
            self._rolling_level = drive
        rise = SPIN_RISE_FRACTION * (st.impact_rise_mpa if by_drive else DRIVE_IMPACT_RISE_MPA)
        if not self._rolling:  # with a telescope trigger, steady is rolling
            self._rolling = steady and (not by_drive or drive - self._felt_level < rise)
            return False
        level = self._rolling_level if from_rolling else self._felt_level
        return drive - level >= rise and self._steady(self._approach_trace, STALL_WINDOW_S)

    def _approach(self, reading: dict[str, float]) -> tuple[float, float, float]:
        """Drive on; keep the boom at rest and the bucket floor level."""
        st = self.style
        boom_drift = reading["boom_angle"] - self._rest_boom
        pitch_drift = reading["boom_angle"] + reading["bucket_angle"] - self._rest_pitch
        if not self._posture_set:  # after a light scoop: lower the boom, then level the bucket
            if abs(boom_drift) > st.hold_deadband_rad:
                return (self._hold(boom_drift), 0.0, 0.0)
            if abs(pitch_drift) > st.hold_deadband_rad:
                return (0.0, self._hold(pitch_drift), 0.0)
            self._posture_set = True
        return (self._hold(boom_drift), self._hold(pitch_drift), st.approach_throttle)

    def _hold(self, drift_rad: float) -> float:
        st = self.style
        if abs(drift_rad) <= st.hold_deadband_rad:
            return 0.0
        return float(np.clip(-st.hold_gain_per_rad * drift_rad, -0.5, 0.5))

    def _fill(self, reading: dict[str, float]) -> tuple[float, float, float]:
        """Dig (lift while pushing), then lift and curl in turn: curl when the boom stalls
        or the bucket floor lags behind the boom's rise; ease off the throttle when the
        wheels slip."""
        st = self.style
        drive = reading["drive_pressure"]
        if self._waiting:  # hesitant: stop, let the machine settle, then go on
            trigger = reading[st.trigger_sensor]
            if trigger > self._felt_level + 0.5 * (self._impact_reading - self._felt_level):
                return (0.0, 0.0, 0.0)
            self._waiting = False
        if st.crowd_fill:
            return self._crowd_fill(reading)
        boom, bucket = reading["boom_angle"], reading["bucket_angle"]
        risen = boom - self._rest_boom
        pitch = boom + bucket - self._rest_pitch
        self._boom_trace.append(boom)
        wanted = st.curl_per_lift * risen  # the bucket-floor pitch this boom rise calls for
        if self._pushing and risen >= st.push_lift_rad:
            self._pushing = False  # the bucket is lifting out: stop crowding the pile

        if self._action == "lift":
            stalled = self._boom_stalled() or reading["boom_pressure"] >= st.boom_stall_mpa
            if stalled or pitch < wanted - st.curl_band_rad:
                self._action, self._curl_from = "curl", pitch
            elif self._held_off and risen < st.push_lift_rad and self._repush_felt(boom):
                # the boom is free again and still low: crowd again, the push felt anew
                # (its peak; an eased throttle stays eased)
                self._pushing, self._held_off = True, False
                self._repushed_at, self._push_peak = boom, drive
        else:  # curling: on until the floor has turned and the boom is free again
            turned = pitch >= max(self._curl_from + st.curl_step_rad, wanted + st.curl_band_rad)
            boom_held = reading["boom_pressure"] >= st.boom_stall_mpa
            if not st.push_while_curling and drive < RELAXED_FRACTION * self._push_peak:
                boom_held = False  # the gas is off and the push has relaxed: the boom is free
            bucket_stalled = reading["bucket_pressure"] >= st.bucket_stall_mpa
            if (turned and not boom_held) or bucket_stalled:
                self._action = "lift"
                self._boom_trace.clear()
                if boom_held:
                    self._pushing = False  # boom and bucket both held: stop crowding
                    self._held_off = st.push_again  # ... until the boom is free again

        throttle = 0.0
        if self._pushing:
            self._push_peak = max(self._push_peak, drive)
            if drive < st.slip_drop_fraction * self._push_peak:
                self._eased = True  # the push collapsed: the wheels slip
            throttle = st.ease_throttle if self._eased else st.push_throttle
        if self._action == "curl":
            return (0.0, st.curl, throttle if st.push_while_curling or self._eased else 0.0)
        return ((DIG_LIFT_FRACTION if self._pushing else 1.0) * st.lift, 0.0, throttle)

    def _crowd_fill(self, reading: dict[str, float]) -> tuple[float, float, float]:
        """Crowd fill (``OperatorStyle.crowd_fill``): keep pushing while the boom rises
        through the face, so the mouth keeps passing through material.

        - lift and push together while the edge is in the face (the telescope pressure
          above its free reading); when the edge comes out, hold the boom and crowd it back
          in, unless the machine rolls on freely (nothing left to bite: lift on);
        - the boom pinned by the push (lifting, it has not risen 0.01 rad in 0.3 s): foot
          off, keep lifting until it has come up a step; if it does not come up once the
          push has relaxed (the drive pressure below half its peak: the material on the
          bucket holds it down), curl a step to break out, the foot off while the boom sags
          (pressed down through its relief valve), pushing once it holds its angle;
        - curl a step, the push kept on, when the bucket floor lags behind the boom's rise;
        - a curl step ends when the floor has turned the step or the bucket stops turning
          (0.01 rad in 0.3 s); then lift a step with the foot off before crowding again;
        - the wheels slip (the push collapses while the pile still holds the bucket, or the
          push tops out flat short of the drive's relief): ease the throttle and fill with
          the wrist, lifting gently while curling.
        """
        st = self.style
        drive, telescope = reading["drive_pressure"], reading["telescope_pressure"]
        boom, bucket = reading["boom_angle"], reading["bucket_angle"]
        risen = boom - self._rest_boom
        pitch = boom + bucket - self._rest_pitch
        wanted = st.curl_per_lift * risen  # the bucket-floor pitch this boom rise calls for
        self._boom_trace.append(boom)
        self._bucket_trace.append(bucket)
        in_face = telescope >= self._free_telescope + FACE_CONTACT_MPA
        self._bitten = self._bitten or in_face
        self._feel_slip(drive, telescope, in_face)

        if self._action == "lift":
            if pitch < wanted - st.curl_band_rad:
                self._start_curl(pitch, breaking_out=False)
            elif self._boom_stalled():  # lifting and the boom does not rise: the push pins it
                self._start_freeing(boom)
        elif self._action == "free":  # foot off, lifting: until the boom has come up a step
            if boom >= self._free_from + CROWD_LIFT_STEP_RAD:
                self._crowd_again(drive, telescope)
            elif self._boom_stalled() and self._push_relaxed(drive):
                # the push has relaxed and the boom still does not come up: the material on
                # the bucket holds it down, break out
                self._start_curl(pitch, breaking_out=True)
        else:  # curling a step
            turned = pitch >= max(self._curl_from + st.curl_step_rad, wanted + st.curl_band_rad)
            if turned or self._bucket_stalled():  # lift a step, foot off, before crowding
                self._start_freeing(boom)

        throttle = st.ease_throttle if self._eased else st.push_throttle
        if self._action == "curl":
            # breaking out, the foot stays off while the boom sags (held down at its relief)
            held = self._breaking_out and self._boom_sagging()
            return (0.0, st.curl, 0.0 if held else throttle)
        if self._action == "free":
            return (st.lift, 0.0, 0.0)
        if in_face:
            self._roll_trace.clear()
        else:  # out of the face: hold the boom and crowd the edge back in, unless the
            # machine rolls on freely (the drive pressure steady): nothing left to bite
            self._roll_trace.append(drive)
            if not self._steady(self._roll_trace, BACK_STEADY_S):
                self._boom_trace.clear()  # the boom held: not lifting
                return (0.0, 0.0, throttle)
            return (st.lift, 0.0, throttle)
        if self._eased:  # traction is the limit: fill with the wrist (lift while curling)
            return (DIG_LIFT_FRACTION * st.lift, st.curl, throttle)
        return (st.lift, 0.0, throttle)

    def _feel_slip(self, drive: float, telescope: float, in_face: bool) -> None:
        """Crowd fill: the wheels are felt to slip when the push collapses while the pile
        still holds the bucket (when the edge comes out of the face, the telescope
        pressure falls with the push), or when, crowding in the face, the push stays flat
        short of the drive's relief (traction tops out before the machine stalls)."""
        st = self.style
        self._push_peak = max(self._push_peak, drive)
        self._face_peak = max(self._face_peak, telescope)
        if (
            in_face
            and drive < st.slip_drop_fraction * self._push_peak
            and telescope >= st.slip_drop_fraction * self._face_peak
        ):
            self._eased = True
        if self._action == "lift" and in_face:
            self._push_trace.append(drive)
            capped = max(self._push_trace) < TRACTION_CAP_FRACTION * DRIVE_RELIEF_MPA
            if capped and self._steady(self._push_trace, STALL_WINDOW_S):
                self._eased = True
        else:
            self._push_trace.clear()

    def _start_curl(self, pitch: float, *, breaking_out: bool) -> None:
        """Crowd fill: curl a step from bucket-floor pitch ``pitch`` [rad]: to break a boom
        held down by the material out (``breaking_out``), or because the floor lags."""
        self._action, self._curl_from, self._breaking_out = "curl", pitch, breaking_out
        self._boom_trace.clear()
        self._bucket_trace.clear()

    def _start_freeing(self, boom: float) -> None:
        """Crowd fill: foot off, lift the boom a step from ``boom`` [rad]."""
        self._action, self._free_from = "free", boom
        self._boom_trace.clear()

    def _push_relaxed(self, drive: float) -> bool:
        """Crowd fill, foot off: the push is felt to have relaxed: the drive pressure
        ``drive`` [MPa] below half its peak in this push, or down to within
        ``BACK_STEADY_MPA`` of the charge pressure (a push that never rose far)."""
        return (
            drive < RELAXED_FRACTION * self._push_peak
            or drive <= DRIVE_CHARGE_MPA + BACK_STEADY_MPA
        )

    def _crowd_again(self, drive: float, telescope: float) -> None:
        """Crowd fill: back to lifting while pushing; the new push is felt anew."""
        self._action = "lift"
        self._push_peak, self._face_peak = drive, telescope
        self._boom_trace.clear()

    def _steady(self, trace: deque[float], window_s: float) -> bool:
        """The last ``window_s`` of ``trace`` lie within ``BACK_STEADY_MPA``."""
        window = self._steps(window_s)
        recent = list(trace)[-window:]
        return len(recent) >= window and max(recent) - min(recent) <= BACK_STEADY_MPA

    def _boom_sagging(self) -> bool:
        """Crowd fill, curling with the boom valve shut: the boom is felt to sag (pressed
        down through its relief valve) while it has fallen ``STALL_RISE_RAD`` or more in
        the last ``STALL_WINDOW_S``, and until that long has been felt."""
        moved = self._stall_window_change(self._boom_trace)
        return moved is None or -moved >= STALL_RISE_RAD

    def _repush_felt(self, boom: float) -> bool:
        """``push_again``: the boom (at ``boom`` [rad]) is felt free (``_boom_felt_free``)
        and has come up ``CROWD_LIFT_STEP_RAD`` since the last re-push, if any: a boom
        pinned by every push is not pulsed with the throttle."""
        stepped = self._repushed_at is None or boom >= self._repushed_at + CROWD_LIFT_STEP_RAD
        return stepped and self._boom_felt_free()

    def _boom_felt_free(self) -> bool:
        """Lifting after a curl, the boom is felt to be free: its pressure has stayed below
        ``boom_stall_mpa`` for ``BOOM_FREE_HOLD_S`` (every lifting decision since the curl
        read it below: a higher reading starts another curl, and the curl clears the
        boom's trace)."""
        return len(self._boom_trace) >= self._steps(BOOM_FREE_HOLD_S)

    def _boom_stalled(self) -> bool:
        """The boom is felt to stall: lifting for ``STALL_WINDOW_S`` and it has not risen
        by ``STALL_RISE_RAD``."""
        return self._stalled(self._boom_trace)

    def _bucket_stalled(self) -> bool:
        """Crowd fill: the bucket is felt to stall: curling for ``STALL_WINDOW_S`` and it
        has not turned by ``STALL_RISE_RAD``."""
        return self._stalled(self._bucket_trace)

    def _stalled(self, angles: deque[float]) -> bool:
        """``angles`` [rad] span ``STALL_WINDOW_S`` and grew less than ``STALL_RISE_RAD``."""
        moved = self._stall_window_change(angles)
        return moved is not None and moved < STALL_RISE_RAD

    def _stall_window_change(self, angles: deque[float]) -> float | None:
        """How far ``angles`` [rad] moved over the last ``STALL_WINDOW_S``; ``None`` until
        they span it."""
        window = self._steps(STALL_WINDOW_S)
        return angles[-1] - angles[-window] if len(angles) >= window else None

    def _finish(self, reading: dict[str, float]) -> tuple[float, float, float]:
        """Curl back until the bucket reaches the end angle, back off until the machine
        rolls back steadily, then raise (some operators raise while they curl). A scoop
        that came up light (the boom rose out of the pile before the bucket was curled
        full) is not finished: back off and go again."""
        st = self.style
        if self._light:
            if self._backing_off(reading):
                return (0.0, 0.0, -max(st.back_off_throttle, GO_AGAIN_BACK_OFF))
            self.phase = "approach"
            self._start_attempt()
            return self._approach(reading)
        if reading["bucket_angle"] >= st.finish_bucket_angle_rad:
            self._curled_back = True  # once curled back, leave it (a loaded bucket sags)
        curl = 0.0 if self._curled_back else 1.0
        if self._curled_back and st.back_off_throttle > 0 and self._backing_off(reading):
            return (0.0, 0.0, -st.back_off_throttle)
        raise_boom = st.raise_speed if (self._curled_back or st.finish_overlap) else 0.0
        return (raise_boom, curl, 0.0)

    def _backing_off(self, reading: dict[str, float]) -> bool:
        """Still backing off: until the machine has started to roll back (the pump has
        reversed) and the drive pressure has stayed steady for ``BACK_STEADY_S`` (the
        set-off surge has passed and the bucket is free of the pile)."""
        if self._backed_off:
            return False
        self._set_off = self._set_off or reading["pump_angle"] < 0.0
        if self._set_off:
            self._drive_trace.append(reading["drive_pressure"])
            self._backed_off = self._steady(self._drive_trace, BACK_STEADY_S)
        return not self._backed_off

    def _steps(self, window_s: float) -> int:
        """Decisions that span ``window_s`` (both ends included), at least 2."""
        return max(2, round(window_s / self.dt) + 1)

    def _executed(self, label: np.ndarray) -> np.ndarray:
        """The command the machine gets: the label, plus the DART perturbation if on."""
        if self.executed_noise <= 0:
            return label.copy()
        decay = math.exp(-self.control_dt / NOISE_CORRELATION_S)
        shock = self._noise_rng.normal(0.0, 1.0, size=3)
        self._noise = decay * self._noise + math.sqrt(1 - decay * decay) * shock
        executed = label.astype(np.float64)
        executed[list(NOISED_CONTROLS)] += self.executed_noise * self._noise[list(NOISED_CONTROLS)]
        return np.clip(executed, -1.0, 1.0).astype(np.float32)


__all__ = [
    "OPTIONS",
    "PHASES",
    "OperatorStyle",
    "PileLoadingOperator",
    "make_expert",
    "sample_style",
]
