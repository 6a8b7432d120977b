"""Every deployed run becomes data: demonstration episodes plus cycle, fault and summary logs.

Files in the run directory (written when the runtime stops; the episodes as they end):

- ``episodes/``: an ``EpisodeStore`` (schema v1). One episode per machine episode (from
  an ``EPISODE_START`` reading to its ``EPISODE_END``, or to the runtime's stop), one row
  per command sent: the readings it answered (the last good ones for a neutral
  command), the controls sent, ``time_s`` since the episode's first command [s], and the
  extra per-row keys ``faults`` (``Fault`` bits, 0 = controller in charge),
  ``latency_s`` (reading in -> command out), ``inference_s`` (NaN for neutral commands)
  and ``sensor_seq`` (-1 for repeated neutral commands). Rewards are NaN (unknown on a
  machine); filter rows with ``faults != 0`` before cloning from them.
- ``cycles.csv``: the same rows, every command, with wall-clock times.
- ``faults.csv``: each fault and re-arm with its time and detail.
- ``summary.json``: counts (commands, neutral commands, deadline misses, faults by kind,
  malformed packets by reason...) and latency / inference percentiles.
- ``layout.json``: the sensor layout (names, units, ranges) and its id.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from pilerl.data import EpisodeMeta, EpisodeStore, make_episode
from pilerl.io import write_text_atomic

from .loop import CycleRecord, LoopCounters
from .packets import SensorFlag, SensorLayout, SensorPacket
from .watchdog import Fault, fault_names

CONTROL_NAMES = ("boom", "bucket", "throttle")


class DeploymentLog:
    """Collects the loop's commands, faults and readings; see the module docstring.

    Args:
        run_dir: where the files go.
        layout: the machine's sensors (the episodes' sensor keys and units).
        controller_name: recorded in each episode's ``operator``.
        control_hz: the episodes' ``rate_hz``.
        max_rows: cycles kept in memory for ``cycles.csv`` (older ones are dropped).
    """

    def __init__(
        self,
        run_dir: str | Path,
        layout: SensorLayout,
        *,
        controller_name: str,
        control_hz: float,
        runtime_kind: str = "",
        max_rows: int = 1_000_000,
    ) -> None:
        self.run_dir = Path(run_dir)
        self.layout = layout
        self.controller_name, self.control_hz = controller_name, control_hz
        self.runtime_kind = runtime_kind
        self.max_rows = max_rows
        self.store = EpisodeStore.create(
            self.run_dir / "episodes",
            sensors=layout.units,
            controls=list(CONTROL_NAMES),
            description=f"deployed controller {controller_name}",
            exist_ok=True,
        )
        self.cycles: list[CycleRecord] = []
        self.fault_events: list[tuple[float, str, str]] = []
        self._episode: list[CycleRecord] = []
        self._episode_open = False
        self._machine_marks_episodes = False  # once an EPISODE_START is seen
        self.episodes_written = 0
        write_text_atomic(
            self.run_dir / "layout.json",
            json.dumps({"layout_id": layout.layout_id, "sensors": layout.to_json()}, indent=1),
        )

    # ------------------------------------------------------------------ loop observers
    def on_command(self, record: CycleRecord) -> None:
        if len(self.cycles) < self.max_rows:
            self.cycles.append(record)
        in_episode = self._episode_open or not self._machine_marks_episodes
        if record.readings is not None and in_episode:
            self._episode.append(record)

    def on_fault(self, now_s: float, faults: Fault, detail: str) -> None:
        names = "+".join(fault_names(faults)) or "rearm"
        self.fault_events.append((now_s, names, detail))

    def on_reading(self, packet: SensorPacket, now_s: float) -> None:
        if packet.flags & SensorFlag.EPISODE_START:
            self._finish(final=None, terminated=False)
            self._machine_marks_episodes = True
            self._episode_open = True
        if packet.flags & SensorFlag.EPISODE_END:
            final = packet.values if np.isfinite(packet.values).all() else None
            self._finish(final=final, terminated=bool(packet.flags & SensorFlag.TERMINATED))

    # ------------------------------------------------------------------ output
    def _finish(self, *, final: np.ndarray | None, terminated: bool) -> None:
        rows, self._episode = self._episode, []
        self._episode_open = False
        if not rows:
            return
        names = self.layout.names
        readings = np.stack([r.readings for r in rows])
        after = np.concatenate([readings[1:], (readings[-1] if final is None else final)[None]])
        start = rows[0].sent_s
        episode = make_episode(
            sensors={n: torch.from_numpy(readings[:, i].copy()) for i, n in enumerate(names)},
            next_sensors={n: torch.from_numpy(after[:, i].copy()) for i, n in enumerate(names)},
            actions=torch.from_numpy(np.stack([r.controls for r in rows])),
            time_s=torch.tensor([r.sent_s - start for r in rows], dtype=torch.float64),
            terminated=terminated,
            truncated=not terminated,
        )
        episode["faults"] = torch.tensor([r.faults for r in rows], dtype=torch.int64)
        episode["latency_s"] = torch.tensor([r.latency_s for r in rows], dtype=torch.float64)
        episode["inference_s"] = torch.tensor([r.inference_s for r in rows], dtype=torch.float64)
        episode["sensor_seq"] = torch.tensor([r.answered_seq for r in rows], dtype=torch.int64)
        meta = EpisodeMeta(
            rate_hz=self.control_hz,
            source=f"deploy:{self.controller_name}",
            condition="deployed",
            operator={
                "id": self.controller_name,
                "kind": "deployed",
                "runtime": self.runtime_kind,
                "neutral_rows": int(sum(r.faults != 0 for r in rows)),
            },
        )
        self.store.append(episode, meta)
        self.episodes_written += 1

    def close(self, counters: LoopCounters) -> dict:
        """Write the open episode (as truncated), ``cycles.csv``, ``faults.csv`` and
        ``summary.json``; returns the summary."""
        self._finish(final=None, terminated=False)
        self._write_cycles()
        self._write_faults()
        summary = summarize(counters, self.cycles)
        summary["episodes_written"] = self.episodes_written
        write_text_atomic(self.run_dir / "summary.json", json.dumps(summary, indent=1))
        return summary

    def _write_cycles(self) -> None:
        out = io.StringIO()
        writer = csv.writer(out)
        names = self.layout.names
        writer.writerow(
            [
                "sent_s",
                "sensor_seq",
                "latency_s",
                "inference_s",
                "faults",
                *CONTROL_NAMES,
                *names,
            ]
        )
        for r in self.cycles:
            readings = r.readings if r.readings is not None else [math.nan] * len(names)
            writer.writerow(
                [
                    f"{r.sent_s:.6f}",
                    r.answered_seq,
                    f"{r.latency_s:.6g}",
                    f"{r.inference_s:.6g}",
                    "+".join(fault_names(r.faults)),
                    *(f"{v:.6g}" for v in r.controls),
                    *(f"{v:.6g}" for v in readings),
                ]
            )
        write_text_atomic(self.run_dir / "cycles.csv", out.getvalue())

    def _write_faults(self) -> None:
        out = io.StringIO()
        writer = csv.writer(out)
        writer.writerow(["time_s", "fault", "detail"])
        for time_s, name, detail in self.fault_events:
            writer.writerow([f"{time_s:.6f}", name, detail])
        write_text_atomic(self.run_dir / "faults.csv", out.getvalue())


def percentiles_ms(values: list[float]) -> dict[str, float | None]:
    """p50, p99, max and std of ``values`` [s], in milliseconds (None when empty)."""
    finite = np.array([v for v in values if math.isfinite(v)])
    if finite.size == 0:
        return {"p50_ms": None, "p99_ms": None, "max_ms": None, "std_ms": None, "n": 0}
    return {
        "p50_ms": float(np.percentile(finite, 50) * 1e3),
        "p99_ms": float(np.percentile(finite, 99) * 1e3),
        "max_ms": float(finite.max() * 1e3),
        "std_ms": float(finite.std() * 1e3),
        "n": int(finite.size),
    }


def summarize(counters: LoopCounters, cycles: list[CycleRecord]) -> dict:
    """Counts and timing statistics of a run (what ``summary.json`` holds)."""
    acted = [r for r in cycles if r.faults == 0]
    summary = asdict(counters)
    summary["malformed"] = dict(counters.malformed)
    summary["faults"] = dict(counters.faults)
    summary["latency"] = percentiles_ms([r.latency_s for r in acted])
    summary["inference"] = percentiles_ms([r.inference_s for r in acted])
    intervals = np.diff([r.sent_s for r in acted]) if len(acted) > 1 else np.array([])
    summary["command_interval"] = percentiles_ms(list(intervals))
    return summary
