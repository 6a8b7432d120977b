"""Controllers against a demonstration, open loop (the paper's Fig. 3), and scoop phases.

Each controller reads the demonstration's own sensor readings row by row (teacher
forcing) and its controls are compared with the demonstrated ones. This is exactly what
the offline validation loss of behaviour cloning measures
(``pilerl.training.bc.validation_loss``): no closed loop, so errors do not compound.

The scoop phases of the paper's Fig. 5 (``SCOOP_PHASES``) are derived from the scripted
operator's phase, which ``pilerl.data.recorder`` stores per row under the key ``phase``
(an index into the recording simulator's expert's ``PHASES``,
``SimulatorPlugin.expert_phases``; the pile loader's: approach, fill, finish). The
mapping below is the paper's, for a scooping expert with those three phases; the
phase list itself is the simulator's:

| scoop phase | rows | paper |
|---|---|---|
| ``approach`` | operator phase ``approach`` | t_1, drive toward the pile |
| ``impact`` | the first ``impact_window_s`` (0.5 s) of ``fill`` | t_2, impact with the pile |
| ``filling`` | the rest of operator phase ``fill`` | t_3, bucket filling with the boom |
| ``finished`` | operator phase ``finish`` | t_4, finished |

The operator enters ``fill`` when it feels the impact (the pile loader's expert: a rise of
its trigger sensor held for its style's ``impact_hold_s``), so ``impact`` starts at the
felt impact and covers the operator's reaction delay and first filling action. For an
operator who raises the boom too early, ``fill`` starts without an impact; its ``impact``
rows are the premature start. The episode ends when the bucket is curled back and raised,
which usually happens while the operator is still in ``fill``: ``finished`` is then short
or empty."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import torch
from matplotlib.patches import Patch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule

from pilerl.figures import legend_outside, save_figure
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator

SCOOP_PHASES = ("approach", "impact", "filling", "finished")
# the paper's Fig. 5: the scoop phase of each phase of a scooping expert (the first rows of
# ``fill`` are ``impact``, see ``scoop_phases``)
SCOOP_PHASE_OF_EXPERT_PHASE = {"approach": "approach", "fill": "filling", "finish": "finished"}
IMPACT_WINDOW_S = 0.5  # length of the impact phase after the operator's impact cue [s]
TIME_TOLERANCE_S = 1e-9  # recorded times are multiples of the control period
OPERATOR_PHASE_KEY = "phase"  # per-row index into pilerl.operators.PHASES
PHASE_COLORS = {
    "approach": "tab:blue",
    "impact": "tab:red",
    "filling": "tab:orange",
    "finished": "tab:green",
}
PHASE_ALPHA = 0.12
DEMONSTRATION_COLOR = "black"


# ---------------------------------------------------------------------- scoop phases
def has_operator_phases(episode: TensorDictBase) -> bool:
    """Whether the episode carries the operator's phase per row (scripted recordings do)."""
    # .keys(): a TensorDict refuses ``in`` on itself
    return OPERATOR_PHASE_KEY in episode.keys()  # noqa: SIM118


def scoop_phases(
    episode: TensorDictBase,
    *,
    impact_window_s: float = IMPACT_WINDOW_S,
    where: str = "episode",
    simulator: str = DEFAULT_SIMULATOR,
) -> np.ndarray:
    """Scoop phase of every row, an index into ``SCOOP_PHASES`` (int64, shape [T]), of an
    episode recorded with ``simulator``'s scripted expert.

    See the module docstring for the mapping from the operator's phases. Raises
    ``ValueError`` naming ``where`` if the episode has no operator phase or an unknown one,
    and naming the simulator if its expert is no scooping expert (phases other than
    ``SCOOP_PHASE_OF_EXPERT_PHASE``'s).
    """
    operator_phases = get_simulator(simulator).expert_phases()
    if set(operator_phases) != set(SCOOP_PHASE_OF_EXPERT_PHASE):
        raise ValueError(
            f"{where}: scoop phases (the paper's Fig. 5) need a scooping expert with phases "
            f"{list(SCOOP_PHASE_OF_EXPERT_PHASE)}; simulator {simulator!r}'s expert has "
            f"{list(operator_phases)}"
        )
    if not impact_window_s >= 0:
        raise ValueError(f"scoop_phases: impact_window_s must be >= 0, got {impact_window_s}")
    if not has_operator_phases(episode):
        raise ValueError(
            f"{where}: no per-row {OPERATOR_PHASE_KEY!r} key; scoop phases come from the "
            "scripted operator's phase, which pilerl.data.recorder stores (imported logs "
            "and other operators have none)"
        )
    operator_phase = episode[OPERATOR_PHASE_KEY].numpy().astype(np.int64).reshape(-1)
    bad = (operator_phase < 0) | (operator_phase >= len(operator_phases))
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{where}: {OPERATOR_PHASE_KEY!r} is {int(operator_phase[row])} at row {row}, "
            f"not an index into the operator's phases {operator_phases}"
        )
    time_s = episode["time_s"].numpy().astype(np.float64).reshape(-1)
    named = np.asarray(operator_phases)[operator_phase]
    scoop_phase = {name: SCOOP_PHASES.index(p) for name, p in SCOOP_PHASE_OF_EXPERT_PHASE.items()}
    in_fill = named == "fill"
    fill_starts = in_fill & ~np.concatenate([[False], in_fill[:-1]])
    fill_start_time_s = np.maximum.accumulate(np.where(fill_starts, time_s, -np.inf))
    # half-open window [start, start + impact_window_s); the tolerance absorbs the rounding
    # of recorded times (0.5 - 0.3 < 0.2 in floating point)
    is_impact = in_fill & (time_s - fill_start_time_s < impact_window_s - TIME_TOLERANCE_S)

    phases = np.asarray([scoop_phase[name] for name in named.tolist()], dtype=np.int64)
    phases[is_impact] = SCOOP_PHASES.index("impact")
    return phases


def shade_scoop_phases(ax, time_s: np.ndarray, phases: np.ndarray) -> None:
    """Shade each run of equal scoop phase on ``ax`` (x = time [s]) in its phase colour."""
    if len(time_s) == 0:
        return
    step_s = float(time_s[1] - time_s[0]) if len(time_s) > 1 else 1.0
    edges_s = np.append(time_s, time_s[-1] + step_s)
    run_starts = np.flatnonzero(np.diff(phases, prepend=-1))
    run_ends = np.append(run_starts[1:], len(phases))
    for start, end in zip(run_starts, run_ends, strict=True):
        name = SCOOP_PHASES[int(phases[start])]
        ax.axvspan(edges_s[start], edges_s[end], color=PHASE_COLORS[name], alpha=PHASE_ALPHA, lw=0)


def phase_legend_handles(phases: np.ndarray) -> list[Patch]:
    """Legend patches for the scoop phases present in ``phases``."""
    present = sorted(set(phases.tolist()))
    return [
        Patch(color=PHASE_COLORS[SCOOP_PHASES[p]], alpha=3 * PHASE_ALPHA, label=SCOOP_PHASES[p])
        for p in present
    ]


# ---------------------------------------------------------------------- open loop
def run_open_loop(
    actor: TensorDictModule, episode: TensorDictBase, *, where: str = "episode"
) -> TensorDict:
    """The actor's outputs (``action``, masks...) on every row of a demonstration.

    The actor reads the demonstration's recorded sensor readings (teacher forcing), in
    eval mode (no dropout) and without gradients; its train/eval mode is restored after.
    Raises ``ValueError`` naming ``where`` if the episode lacks a sensor the actor reads.
    """
    in_keys = list(actor.in_keys)
    missing = [key for key in in_keys if key not in episode.keys()]  # noqa: SIM118
    if missing:
        raise ValueError(
            f"{where}: has no readings of {missing}, which the actor reads (it reads {in_keys})"
        )
    was_training = actor.training
    actor.eval()
    try:
        with torch.no_grad():
            outputs = actor(episode.select(*in_keys).to_tensordict())
    finally:
        actor.train(was_training)
    return outputs.exclude(*in_keys)


@dataclass
class ControlComparison:
    """Controllers' open-loop controls against one demonstration.

    Attributes:
        time_s: time of each row since the episode start [s], shape [T].
        controls: control names, in action order (boom, bucket, throttle).
        demonstration: demonstrated controls [T, n_u], each in [-1, 1].
        predictions: actor name -> its controls on the same rows [T, n_u].
        mse: actor name -> control name -> mean squared error over the rows, plus
            ``"all"``: the mean over controls and rows (the BC validation loss).
        phases: scoop phase of each row (index into ``SCOOP_PHASES``), or ``None`` when
            the demonstration carries no operator phase.
    """

    time_s: np.ndarray
    controls: list[str]
    demonstration: np.ndarray
    predictions: dict[str, np.ndarray]
    mse: dict[str, dict[str, float]]
    phases: np.ndarray | None = None


def compare_controls(
    episode: TensorDictBase,
    actors: Mapping[str, TensorDictModule],
    *,
    controls: Sequence[str] | None = None,
    impact_window_s: float = IMPACT_WINDOW_S,
    where: str = "episode",
    simulator: str = DEFAULT_SIMULATOR,
) -> ControlComparison:
    """Each actor's controls on a demonstration's own readings, and their errors.

    Args:
        episode: one demonstration (schema v1, e.g. ``EpisodeStore.load(i)``).
        actors: display name -> actor (from ``make_actor`` / ``load_actor``).
        controls: names of the action's columns (``EpisodeStore.controls``); ``None``:
            the simulator's declared controls.
        impact_window_s: see ``scoop_phases``; used only if the episode has phases.
        where: how errors name the episode (e.g. ``"d_ii_summer episode 3"``).
        simulator: the simulator the demonstration was recorded in.
    """
    if controls is None:
        controls = get_simulator(simulator).controls
    if not actors:
        raise ValueError("compare_controls: no actors given")
    demonstration = episode["action"].numpy().astype(np.float64)
    if demonstration.ndim != 2 or demonstration.shape[1] != len(controls):
        raise ValueError(
            f"{where}: action has shape {tuple(demonstration.shape)}, expected "
            f"(T, {len(controls)}) for controls {list(controls)}"
        )
    predictions, mse = {}, {}
    for name, actor in actors.items():
        predicted = run_open_loop(actor, episode, where=where)["action"].numpy()
        predicted = predicted.astype(np.float64)
        if predicted.shape != demonstration.shape:
            raise ValueError(
                f"{where}: actor {name!r} writes actions of shape {tuple(predicted.shape)}, "
                f"the demonstration has {tuple(demonstration.shape)}"
            )
        squared_error = (predicted - demonstration) ** 2
        predictions[name] = predicted
        mse[name] = {
            **{control: float(squared_error[:, i].mean()) for i, control in enumerate(controls)},
            "all": float(squared_error.mean()),
        }
    phases = (
        scoop_phases(episode, impact_window_s=impact_window_s, where=where, simulator=simulator)
        if has_operator_phases(episode)
        else None
    )
    return ControlComparison(
        time_s=episode["time_s"].numpy().astype(np.float64),
        controls=list(controls),
        demonstration=demonstration,
        predictions=predictions,
        mse=mse,
        phases=phases,
    )


def plot_control_signals(
    comparison: ControlComparison, path: str | Path, *, title: str = ""
) -> Path:
    """The paper's Fig. 3: each control over time, demonstration vs controllers.

    One panel per control; the demonstration in black, each controller in colour with
    its MSE on that control in the legend; scoop phases shaded when known.
    """
    n_controls = len(comparison.controls)
    fig, axes = plt.subplots(n_controls, 1, figsize=(8, 2.2 * n_controls + 0.6), sharex=True)
    axes = np.atleast_1d(axes)
    t = comparison.time_s
    for i, (ax, control) in enumerate(zip(axes, comparison.controls, strict=True)):
        if comparison.phases is not None:
            shade_scoop_phases(ax, t, comparison.phases)
        ax.plot(
            t,
            comparison.demonstration[:, i],
            color=DEMONSTRATION_COLOR,
            linewidth=1.6,
            label="demonstration",
        )
        for name, predicted in comparison.predictions.items():
            mse = comparison.mse[name][control]
            ax.plot(t, predicted[:, i], linewidth=1.1, label=f"{name} (MSE {mse:.3g})")
        ax.set_ylabel(f"{control} [-1, 1]")
        ax.set_ylim(-1.1, 1.1)
        ax.grid(alpha=0.3)
        handles, _ = ax.get_legend_handles_labels()
        if i == 0 and comparison.phases is not None:
            handles += phase_legend_handles(comparison.phases)
        legend_outside(ax, handles=handles)
    axes[-1].set_xlabel("time [s]")
    overall = ", ".join(f"{name} {mse['all']:.3g}" for name, mse in comparison.mse.items())
    heading = f"open-loop controls (MSE: {overall})"  # two lines: never wider than the axes
    axes[0].set_title(f"{title}\n{heading}" if title else heading, fontsize=9)
    return save_figure(fig, path)
