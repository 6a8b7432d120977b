"""Attention masks over the phases of a scoop (the paper's Fig. 5).

An attention controller (ANNet, DANNet) writes an input mask m (a softmax over its
controller inputs s, one weight per sensor) and DANNet also an output mask m_u (a
softmax over the controls). Here the masks are computed open loop on demonstrations
(each row's recorded readings, eval mode) and averaged per scoop phase: approach,
impact, filling, finished (``SCOOP_PHASES``; the mapping from the scripted operator's
phases is in ``pilerl.evaluation.control_signals``).

Averages pool the rows: every row of every episode in a phase counts once, so longer
episodes weigh more. A phase without rows has NaN means and ``n_rows`` 0.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule

from pilerl.figures import legend_outside, save_figure
from pilerl.policies import INPUT_MASK_KEY, OUTPUT_MASK_KEY, actor_policy
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator

from .control_signals import (
    IMPACT_WINDOW_S,
    SCOOP_PHASES,
    phase_legend_handles,
    run_open_loop,
    scoop_phases,
    shade_scoop_phases,
)

HEATMAP_COLORMAP = "viridis"


@dataclass
class MaskTrace:
    """The masks at every row of one demonstration.

    Attributes:
        time_s: time since the episode start [s], shape [T].
        phases: scoop phase of each row (index into ``SCOOP_PHASES``), shape [T].
        input_mask: m, one weight per controller input [T, n_s]; rows sum to 1.
        output_mask: m_u, one weight per control [T, n_u] (DANNet), else ``None``.
    """

    time_s: np.ndarray
    phases: np.ndarray
    input_mask: np.ndarray
    output_mask: np.ndarray | None


@dataclass
class PhaseMasks:
    """Masks averaged per scoop phase over one or more demonstrations.

    Attributes:
        controller: the actor's controller name (``annet``, ``dannet``).
        sensors: the controller inputs s that m weighs, in mask order.
        controls: the controls that m_u weighs, in mask order.
        input_mask: mean m per phase [len(SCOOP_PHASES), n_s] (NaN: no rows).
        output_mask: mean m_u per phase [len(SCOOP_PHASES), n_u], or ``None`` (ANNet).
        n_rows: rows per phase, pooled over the episodes.
        traces: the per-row masks of each episode, in the order given.
    """

    controller: str
    sensors: list[str]
    controls: list[str]
    input_mask: np.ndarray
    output_mask: np.ndarray | None
    n_rows: np.ndarray
    traces: list[MaskTrace]

    def input_table(self) -> dict[str, dict[str, float]]:
        """Phase -> sensor -> mean input-mask weight (the phase x sensor table)."""
        return _table(self.input_mask, self.sensors)

    def output_table(self) -> dict[str, dict[str, float]] | None:
        """Phase -> control -> mean output-mask weight, or ``None`` without m_u."""
        return None if self.output_mask is None else _table(self.output_mask, self.controls)

    def to_markdown(self) -> str:
        """Both tables as one Markdown table: a row per phase, a column per mask entry."""
        columns = [f"m: {s}" for s in self.sensors]
        values = self.input_mask
        if self.output_mask is not None:
            columns += [f"m_u: {c}" for c in self.controls]
            values = np.concatenate([values, self.output_mask], axis=1)
        lines = [
            "| phase | rows | " + " | ".join(columns) + " |",
            "|---|---:|" + "---:|" * len(columns),
        ]
        for p, phase in enumerate(SCOOP_PHASES):
            cells = " | ".join(f"{v:.3f}" for v in values[p])
            lines.append(f"| {phase} | {int(self.n_rows[p])} | {cells} |")
        return "\n".join(lines)


def _table(values: np.ndarray, names: Sequence[str]) -> dict[str, dict[str, float]]:
    return {
        phase: {name: float(values[p, i]) for i, name in enumerate(names)}
        for p, phase in enumerate(SCOOP_PHASES)
    }


def check_attention_actor(actor: TensorDictModule) -> None:
    """Raise ``ValueError`` unless ``actor`` writes an input mask (ANNet, DANNet)."""
    out_keys = list(getattr(actor, "out_keys", []))
    if INPUT_MASK_KEY not in out_keys:
        try:
            name = repr(actor_policy(actor).config.controller)
        except TypeError:
            name = type(actor).__name__
        raise ValueError(
            f"attention masks: the {name} actor has no attention (it writes {out_keys}, "
            f"no {INPUT_MASK_KEY!r}); use an attention controller (annet, dannet)"
        )


def mask_trace(
    actor: TensorDictModule,
    episode: TensorDictBase,
    *,
    impact_window_s: float = IMPACT_WINDOW_S,
    where: str = "episode",
    simulator: str = DEFAULT_SIMULATOR,
) -> MaskTrace:
    """The actor's masks at every row of one demonstration, with the scoop phases."""
    check_attention_actor(actor)
    phases = scoop_phases(
        episode, impact_window_s=impact_window_s, where=where, simulator=simulator
    )
    outputs = run_open_loop(actor, episode, where=where)
    output_mask = outputs.get(OUTPUT_MASK_KEY, None)
    return MaskTrace(
        time_s=episode["time_s"].numpy().astype(np.float64),
        phases=phases,
        input_mask=outputs[INPUT_MASK_KEY].numpy().astype(np.float64),
        output_mask=None if output_mask is None else output_mask.numpy().astype(np.float64),
    )


def phase_masks(
    actor: TensorDictModule,
    episodes: Iterable[TensorDictBase],
    *,
    controls: Sequence[str] | None = None,
    impact_window_s: float = IMPACT_WINDOW_S,
    simulator: str = DEFAULT_SIMULATOR,
) -> PhaseMasks:
    """Average an attention actor's masks per scoop phase over demonstrations.

    Args:
        actor: an ANNet or DANNet actor (``make_actor`` / ``load_actor``).
        episodes: demonstrations with the operator's phase per row (an ``EpisodeStore``
            iterates its episodes; pass ``[store.load(i) for i in ids]`` for a subset).
        controls: names of the controls, in action order (``EpisodeStore.controls``);
            ``None``: the simulator's declared controls.
        impact_window_s: length of the impact phase [s] (see ``scoop_phases``).
        simulator: the simulator the demonstrations were recorded in.
    """
    if controls is None:
        controls = get_simulator(simulator).controls
    check_attention_actor(actor)
    policy = actor_policy(actor)
    sensors = list(policy.config.sensors)
    traces = [
        mask_trace(
            actor,
            episode,
            impact_window_s=impact_window_s,
            where=f"episode {i}",
            simulator=simulator,
        )
        for i, episode in enumerate(episodes)
    ]
    if not traces:
        raise ValueError("phase_masks: no episodes given")
    phases = np.concatenate([trace.phases for trace in traces])
    input_mask = np.concatenate([trace.input_mask for trace in traces])
    if input_mask.shape[1] != len(sensors):
        raise ValueError(
            f"phase_masks: input mask has {input_mask.shape[1]} entries, the actor's "
            f"sensors are {sensors}"
        )
    output_mask = None
    if traces[0].output_mask is not None:
        output_mask = np.concatenate([trace.output_mask for trace in traces])
        if output_mask.shape[1] != len(controls):
            raise ValueError(
                f"phase_masks: output mask has {output_mask.shape[1]} entries, but "
                f"{len(controls)} controls were named ({list(controls)})"
            )
    n_rows = np.array([(phases == p).sum() for p in range(len(SCOOP_PHASES))])
    return PhaseMasks(
        controller=policy.config.controller,
        sensors=sensors,
        controls=list(controls),
        input_mask=_mean_per_phase(input_mask, phases),
        output_mask=None if output_mask is None else _mean_per_phase(output_mask, phases),
        n_rows=n_rows,
        traces=traces,
    )


def _mean_per_phase(values: np.ndarray, phases: np.ndarray) -> np.ndarray:
    """Mean of ``values`` [N, k] over the rows of each scoop phase; NaN for empty ones."""
    means = np.full((len(SCOOP_PHASES), values.shape[1]), np.nan)
    for p in range(len(SCOOP_PHASES)):
        rows = phases == p
        if rows.any():
            means[p] = values[rows].mean(axis=0)
    return means


def plot_attention_masks(
    masks: PhaseMasks, path: str | Path, *, episode: int = 0, title: str = ""
) -> Path:
    """The paper's Fig. 5: mean masks per phase (heatmaps), masks over one episode.

    Top: input mask (phase x sensor) and, for DANNet, output mask (phase x control),
    each cell annotated with its weight. Below: the masks of episode ``episode`` (index
    into ``masks.traces``) over time, scoop phases shaded.
    """
    if not 0 <= episode < len(masks.traces):
        raise IndexError(
            f"plot_attention_masks: episode {episode} not in 0..{len(masks.traces) - 1}"
        )
    dual = masks.output_mask is not None
    n_rows = 3 if dual else 2
    fig = plt.figure(figsize=(11, 3.2 * n_rows))
    grid = (
        fig.add_gridspec(n_rows, 2, width_ratios=[len(masks.sensors), len(masks.controls)])
        if dual
        else fig.add_gridspec(n_rows, 1)
    )
    phase_labels = [f"{p} ({int(n)} rows)" for p, n in zip(SCOOP_PHASES, masks.n_rows, strict=True)]
    _heatmap(
        fig.add_subplot(grid[0, 0] if dual else grid[0, :]),
        masks.input_mask,
        masks.sensors,
        phase_labels,
        "input mask m (mean per phase)",
    )
    if dual:
        _heatmap(
            fig.add_subplot(grid[0, 1]),
            masks.output_mask,
            masks.controls,
            phase_labels,
            "output mask m_u (mean per phase)",
        )
    trace = masks.traces[episode]
    over_time = [("input mask m", trace.input_mask, masks.sensors)]
    if dual:
        over_time.append(("output mask m_u", trace.output_mask, masks.controls))
    for row, (label, values, names) in enumerate(over_time, start=1):
        ax = fig.add_subplot(grid[row, :])
        shade_scoop_phases(ax, trace.time_s, trace.phases)
        for i, name in enumerate(names):
            ax.plot(trace.time_s, values[:, i], linewidth=1.2, label=name)
        ax.set_ylim(0.0, 1.0)
        ax.set_ylabel(f"{label} [0, 1]")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        handles, _ = ax.get_legend_handles_labels()
        legend_outside(ax, handles=handles + phase_legend_handles(trace.phases))
        ax.set_title(f"{label} over episode {episode}", fontsize=9)
    if title:
        fig.suptitle(f"{title} ({masks.controller})")
    return save_figure(fig, path)


def _heatmap(ax, values: np.ndarray, columns: Sequence[str], rows: Sequence[str], title: str):
    image = ax.imshow(values, cmap=HEATMAP_COLORMAP, vmin=0.0, vmax=1.0, aspect="auto")
    ax.set_xticks(range(len(columns)), labels=columns, rotation=30, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), labels=rows, fontsize=8)
    for r in range(values.shape[0]):
        for c in range(values.shape[1]):
            value = values[r, c]
            text = "no rows" if np.isnan(value) else f"{value:.2f}"
            color = "grey" if np.isnan(value) else "black" if value > 0.6 else "white"
            ax.text(c, r, text, ha="center", va="center", fontsize=7, color=color)
    ax.set_title(title, fontsize=9)
    ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.02)
