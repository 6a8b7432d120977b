"""The data-quality report of an import: Markdown plus one plot per episode.

What it measures, per episode and over the import:

* **rate** (declared and measured), **jitter** (std of the regular intervals) and **gaps**
  (intervals over ``timing.GAP_FACTOR`` nominal periods: dropped samples), and message signals
  whose messages stopped for longer than ``STALE_PERIODS`` grid periods;
* **frozen** sensors (the same reading for at least ``FROZEN_S`` seconds: a stuck or
  stale transducer) and **clipped** sensors (a flat run at the episode's extreme: a
  saturated transducer or logger limit);
* sensors **out of range** of a reference (the simulator's declared ranges, when given:
  the controller will see readings the simulator never produced);
* **episodes per condition**, with their outcomes;
* the **single-control share**: of the samples where a control is active (|u| >
  ``ACTIVE``), the share with exactly one active, the operator style the paper's
  controllers imitate; controls held active almost throughout (share >= ``HELD``, such as
  a throttle pedal) are left out and named;
* a **warning** for every sensor the chosen controller needs that the import lacks.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pilerl.io import atomic_path, write_text_atomic

from .episodes import ImportedEpisode

FROZEN_S = 2.0  # an unchanged reading for this long is reported as frozen [s]
CLIP_RUN = 3  # samples: a flat run at the episode's extreme at least this long is clipping
CLIP_SHARE = 0.02  # ... and covering at least this share of the episode
ACTIVE = 0.05  # |u| above this counts as an active control
HELD = 0.95  # a control active in this share of all samples (a throttle pedal held down)
# says nothing about one-control-at-a-time operation and is left out of that share
REFERENCE_TOLERANCE = 1e-4  # of the reference range's span: rounding in a log is not "outside"
STALE_PERIODS = 3.0  # message signals: a message gap longer than this many grid periods


NOT_SENSORS = ("action", "time_s", "step", "episode", "next")


def sensor_keys(episode) -> list[str]:  # noqa: ANN001 - TensorDict
    """The sensor keys of a schema-v1 episode, in their order."""
    return [k for k in episode.keys() if k not in NOT_SENSORS]  # noqa: SIM118


@dataclass
class EpisodeQuality:
    """The measured quality of one episode (see the module docstring)."""

    name: str
    rows: int
    rate_hz: float
    measured_hz: float
    jitter_ms: float
    gaps: list[tuple[int, float]]
    dropped: int
    frozen: dict[str, float] = field(default_factory=dict)  # sensor -> seconds unchanged
    clipped: dict[str, float] = field(default_factory=dict)  # sensor -> share at an extreme
    out_of_reference: dict[str, float] = field(default_factory=dict)  # sensor -> share
    single_control_share: float = float("nan")
    no_control_share: float = float("nan")
    stale_signals: dict[str, float] = field(default_factory=dict)  # column -> longest gap [s]


def counted_controls(episodes: Sequence[ImportedEpisode]) -> list[int]:
    """Indices of the controls the single-control share counts (those not held active in
    ``HELD`` of all samples)."""
    if not episodes:
        return []
    actions = np.concatenate([e.episode["action"].numpy() for e in episodes])
    active = np.mean(np.abs(actions) > ACTIVE, axis=0)
    return [k for k in range(actions.shape[-1]) if active[k] < HELD]


def episode_quality(
    episode: ImportedEpisode,
    name: str,
    *,
    reference_ranges: Mapping[str, tuple[float, float]] | None = None,
    controls: Sequence[int] | None = None,
) -> EpisodeQuality:
    td = episode.episode
    time_s = td["time_s"].numpy()
    s = episode.sampling
    measured = 1.0 / s.median_dt_s if s.median_dt_s and np.isfinite(s.median_dt_s) else float("nan")
    quality = EpisodeQuality(
        name=name,
        rows=s.n_rows,
        rate_hz=episode.meta.rate_hz,
        measured_hz=measured,
        jitter_ms=s.jitter_s * 1e3,
        gaps=list(s.gaps),
        dropped=s.dropped,
    )
    sensors = sensor_keys(td)
    for sensor in sensors:
        values = td[sensor].numpy()[:, 0]
        longest = _longest_constant_s(values, time_s)
        if longest >= FROZEN_S:
            quality.frozen[sensor] = longest
        share = _clipped_share(values)
        if share > 0:
            quality.clipped[sensor] = share
        if reference_ranges and sensor in reference_ranges:
            low, high = reference_ranges[sensor]
            slack = REFERENCE_TOLERANCE * (high - low) if np.isfinite(high - low) else 0.0
            outside = float(np.mean((values < low - slack) | (values > high + slack)))
            if outside > 0:
                quality.out_of_reference[sensor] = outside
    actions = td["action"].numpy()
    counted = list(range(actions.shape[-1])) if controls is None else list(controls)
    if counted:
        active = (np.abs(actions[:, counted]) > ACTIVE).sum(-1)
        quality.no_control_share = float(np.mean(active == 0))
        if (active > 0).any():
            quality.single_control_share = float(np.mean(active[active > 0] == 1))
    grid_dt = 1.0 / episode.meta.rate_hz
    quality.stale_signals = {
        column: gap for column, gap in episode.signal_gaps.items() if gap > STALE_PERIODS * grid_dt
    }
    return quality


def _longest_constant_s(values: np.ndarray, time_s: np.ndarray) -> float:
    """Longest time [s] over which the reading did not change."""
    if len(values) < 2:
        return 0.0
    changes = np.flatnonzero(np.diff(values) != 0) + 1
    bounds = np.concatenate([[0], changes, [len(values)]])
    longest = 0.0
    for start, end in zip(bounds[:-1], bounds[1:], strict=True):
        longest = max(longest, float(time_s[end - 1] - time_s[start]))
    return longest


def _clipped_share(values: np.ndarray) -> float:
    """Share of samples in flat runs (>= CLIP_RUN) at the episode's min or max, if that
    share reaches CLIP_SHARE; else 0."""
    if len(values) < CLIP_RUN or values.min() == values.max():
        return 0.0
    total = 0
    for extreme in (values.min(), values.max()):
        at = np.concatenate([[False], values == extreme, [False]])
        edges = np.flatnonzero(np.diff(at.astype(np.int8)))
        runs = edges[1::2] - edges[::2]
        total += int(runs[runs >= CLIP_RUN].sum())
    share = total / len(values)
    return share if share >= CLIP_SHARE else 0.0


@dataclass
class QualityReport:
    """The report's Markdown, where it was written, and the per-episode measurements."""

    markdown: str
    path: Path | None
    plots: list[Path]
    episodes: list[EpisodeQuality]
    warnings: list[str]


def quality_report(
    episodes: Sequence[ImportedEpisode],
    *,
    out_dir: str | Path | None = None,
    required_sensors: Sequence[str] = (),
    reference_ranges: Mapping[str, tuple[float, float]] | None = None,
    reference_name: str = "simulator",
    control_names: Sequence[str] | None = None,
    sensor_units: Mapping[str, str] | None = None,
    plots: bool = True,
) -> QualityReport:
    """Measure ``episodes`` and write ``report.md`` + ``episode_<id>.png`` into ``out_dir``.

    Args:
        episodes: the episodes of one import (ids set once stored).
        out_dir: where to write; None: build the Markdown only.
        required_sensors: the inputs of the controller that will be trained (``s`` and
            ``s'``); each one the import lacks is a warning.
        reference_ranges: sensor -> ``(low, high)`` to compare with (the simulator's).
        reference_name: what the reference ranges are, for the text.
        control_names: names of the action components, for the plots' legend.
        sensor_units: sensor -> unit, for the plots' axes.
        plots: draw the per-episode plots (needs ``out_dir``).
    """
    names = [_episode_name(e, i) for i, e in enumerate(episodes)]
    counted = counted_controls(episodes)
    measured = [
        episode_quality(e, n, reference_ranges=reference_ranges, controls=counted)
        for e, n in zip(episodes, names, strict=True)
    ]
    warnings = _warnings(episodes, measured, required_sensors, reference_name)
    out = Path(out_dir) if out_dir is not None else None
    plot_paths: list[Path] = []
    if out is not None and plots:
        for episode, quality in zip(episodes, measured, strict=True):
            plot_paths.append(
                plot_episode(
                    episode,
                    quality,
                    out / f"{quality.name}.png",
                    reference_ranges,
                    control_names,
                    sensor_units,
                )
            )
    markdown = _markdown(
        episodes, measured, warnings, plot_paths, out, reference_name, counted, control_names
    )
    path = None
    if out is not None:
        path = out / "report.md"
        write_text_atomic(path, markdown)
    return QualityReport(markdown, path, plot_paths, measured, warnings)


def _episode_name(episode: ImportedEpisode, index: int) -> str:
    return f"episode_{episode.meta.id:06d}" if episode.meta.id >= 0 else f"episode_{index:06d}"


def _warnings(
    episodes: Sequence[ImportedEpisode],
    measured: Sequence[EpisodeQuality],
    required_sensors: Sequence[str],
    reference_name: str,
) -> list[str]:
    out = []
    if episodes:
        have = set(episodes[0].episode.keys())
        missing = [s for s in required_sensors if s not in have]
        if missing:
            out.append(
                f"the controller needs sensors {missing}, which this import does not have: "
                "map them, or choose a controller whose inputs (s, s') the logs have"
            )
    for q in measured:
        if q.gaps:
            row, longest = max(q.gaps, key=lambda g: g[1])
            out.append(
                f"{q.name}: {len(q.gaps)} gap(s), about {q.dropped} dropped sample(s); the "
                f"longest is {longest * 1e3:.0f} ms before row {row}"
            )
        if np.isfinite(q.measured_hz) and abs(q.measured_hz - q.rate_hz) > 0.05 * q.rate_hz:
            out.append(
                f"{q.name}: the rows come at {q.measured_hz:.4g} Hz (median), the metadata says "
                f"{q.rate_hz:.4g} Hz"
            )
        for sensor, seconds in q.frozen.items():
            out.append(f"{q.name}: {sensor} does not change for {seconds:.1f} s (frozen?)")
        for sensor, share in q.clipped.items():
            out.append(
                f"{q.name}: {sensor} sits at its extreme for {share:.0%} of the episode (clipped?)"
            )
        for sensor, share in q.out_of_reference.items():
            out.append(
                f"{q.name}: {sensor} is outside the {reference_name}'s range "
                f"for {share:.0%} of samples"
            )
        for column, gap in q.stale_signals.items():
            out.append(f"{q.name}: no {column!r} message for {gap * 1e3:.0f} ms (held in between)")
    return out


def _fmt(value: float, spec: str) -> str:
    return "–" if not np.isfinite(value) else format(value, spec)


def _markdown(
    episodes: Sequence[ImportedEpisode],
    measured: Sequence[EpisodeQuality],
    warnings: Sequence[str],
    plot_paths: Sequence[Path],
    out: Path | None,
    reference_name: str,
    counted: Sequence[int],
    control_names: Sequence[str] | None,
) -> str:
    lines = ["# Import data-quality report", ""]
    files = list(dict.fromkeys(str(e.file) for e in episodes))
    lines += [
        f"{len(episodes)} episode(s) from {len(files)} file(s): "
        + ", ".join(f"`{f}`" for f in files),
        "",
    ]
    notes = list(dict.fromkeys(n for e in episodes for n in e.notes))
    notes += [
        f"{e.file}: resampled from {1 / e.sampling.median_dt_s:.4g} Hz "
        f"to {e.sampling.resampled_hz:g} Hz"
        for e in episodes
        if e.sampling.resampled_hz
    ]
    if notes:
        lines += ["Reading:", "", *(f"- {n}" for n in notes), ""]
    lines += ["## Warnings", ""]
    lines += [f"- {w}" for w in warnings] if warnings else ["None."]
    lines += ["", "## Episodes", ""]
    lines += [
        "| episode | source | rows | rate [Hz] | measured [Hz] | jitter [ms] | gaps | dropped "
        "| frozen | clipped | single-control | no control | success |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for e, q in zip(episodes, measured, strict=True):
        source = Path(e.file).name + (f"#{e.label}" if e.label else "")
        success = {True: "yes", False: "no", None: "?"}[e.meta.success]
        lines.append(
            f"| {q.name} | {source} | {q.rows} | {q.rate_hz:.4g} | {_fmt(q.measured_hz, '.4g')} "
            f"| {q.jitter_ms:.2f} | {len(q.gaps)} | {q.dropped} | {', '.join(q.frozen) or '–'} "
            f"| {', '.join(q.clipped) or '–'} | {_fmt(q.single_control_share, '.0%')} "
            f"| {_fmt(q.no_control_share, '.0%')} | {success} |"
        )
    lines += ["", "## Sensors", ""]
    if episodes:
        first = episodes[0].episode
        sensor_names = sensor_keys(first)
        lines += [
            "| sensor | min | max | frozen in | clipped in "
            f"| outside the {reference_name}'s range |",
            "|---|---|---|---|---|---|",
        ]
        for sensor in sensor_names:
            values = np.concatenate([e.episode[sensor].numpy()[:, 0] for e in episodes])
            frozen = sum(sensor in q.frozen for q in measured)
            clipped = sum(sensor in q.clipped for q in measured)
            outside = sum(sensor in q.out_of_reference for q in measured)
            lines.append(
                f"| {sensor} | {values.min():.4g} | {values.max():.4g} | {frozen} ep. "
                f"| {clipped} ep. | {outside} ep. |"
            )
    lines += [
        "",
        "## Episodes per condition",
        "",
        "| condition | episodes | success | failure | unknown |",
        "|---|---|---|---|---|",
    ]
    by_condition = Counter(e.meta.condition for e in episodes)
    for condition, count in sorted(by_condition.items()):
        outcomes = Counter(e.meta.success for e in episodes if e.meta.condition == condition)
        lines.append(
            f"| {condition} | {count} | {outcomes[True]} | {outcomes[False]} | {outcomes[None]} |"
        )
    shares = [q.single_control_share for q in measured if np.isfinite(q.single_control_share)]
    weights = [q.rows for q in measured if np.isfinite(q.single_control_share)]
    if episodes:
        n_controls = episodes[0].episode["action"].shape[-1]
        names = list(control_names or [f"u{k}" for k in range(n_controls)])
        held = [names[k] for k in range(n_controls) if k not in counted]
        overall = f"{np.average(shares, weights=weights):.0%}" if shares else "–"
        lines += [
            "",
            f"Single-control share: {overall} of the samples with an active control have "
            f"exactly one (|u| > {ACTIVE}), counting {[names[k] for k in counted]}"
            + (f"; {held} active almost throughout and not counted." if held else "."),
        ]
    if plot_paths:
        lines += ["", "## Plots", ""]
        for path in plot_paths:
            rel = path.relative_to(out) if out is not None else path
            lines.append(f"![{path.stem}]({rel})")
    return "\n".join(lines) + "\n"


def plot_episode(
    episode: ImportedEpisode,
    quality: EpisodeQuality,
    path: Path,
    reference_ranges: Mapping[str, tuple[float, float]] | None = None,
    control_names: Sequence[str] | None = None,
    sensor_units: Mapping[str, str] | None = None,
) -> Path:
    """Every sensor and the controls against time; gaps shaded, reference ranges dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    td = episode.episode
    time_s = td["time_s"].numpy()
    sensors = sensor_keys(td)
    fig, axes = plt.subplots(
        len(sensors) + 1, 1, figsize=(9, 1.3 * (len(sensors) + 1) + 0.8), sharex=True
    )
    axes = np.atleast_1d(axes)
    t0 = float(time_s[0])
    gap_spans = []
    for row, dt in quality.gaps:
        local = row - episode.first_row  # index within the episode of the row after the gap
        if episode.sampling.resampled_hz is None and 0 < local < len(time_s):
            gap_spans.append((time_s[local] - dt, time_s[local]))
        elif episode.sampling.resampled_hz is not None:
            pass  # positions moved by resampling; the table lists them
    for ax, sensor in zip(axes[:-1], sensors, strict=False):
        values = td[sensor].numpy()[:, 0]
        ax.plot(time_s - t0, values, lw=0.9)
        unit = (sensor_units or {}).get(sensor)
        label = f"{sensor}\n[{unit}]" if unit else sensor
        ax.set_ylabel(label, rotation=0, ha="right", va="center", fontsize=8)
        if reference_ranges and sensor in reference_ranges:
            for bound in reference_ranges[sensor]:
                if np.isfinite(bound):
                    ax.axhline(bound, color="grey", ls="--", lw=0.7)
        marks = []
        if sensor in quality.frozen:
            marks.append("frozen")
        if sensor in quality.clipped:
            marks.append("clipped")
        if sensor in quality.out_of_reference:
            marks.append("out of range")
        if marks:
            ax.text(
                0.99,
                0.85,
                ", ".join(marks),
                transform=ax.transAxes,
                ha="right",
                color="tab:red",
                fontsize=8,
            )
    controls = td["action"].numpy()
    for k in range(controls.shape[-1]):
        name = control_names[k] if control_names and k < len(control_names) else f"u{k}"
        axes[-1].plot(time_s - t0, controls[:, k], lw=0.9, label=name)
    axes[-1].set_ylim(-1.1, 1.1)
    axes[-1].set_ylabel("controls", rotation=0, ha="right", fontsize=8)
    axes[-1].legend(loc="upper right", fontsize=7, ncol=max(controls.shape[-1], 1))
    axes[-1].set_xlabel("time since episode start [s]")
    for ax in axes:
        for start, end in gap_spans:
            ax.axvspan(start - t0, end - t0, color="tab:red", alpha=0.25, lw=0)
        ax.tick_params(labelsize=7)
    title = f"{quality.name}: {Path(episode.file).name}" + (
        f" #{episode.label}" if episode.label else ""
    )
    title += f"  ({quality.rows} rows, {len(quality.gaps)} gaps, jitter {quality.jitter_ms:.1f} ms)"
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)
    return path
