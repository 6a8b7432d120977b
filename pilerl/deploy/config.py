"""The typed config of ``recipes/deploy.py`` (``conf/deploy.yaml`` is merged onto it)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pilerl.sim.settings import EnvConfig

from .bridge import BridgeSettings
from .loop import RuntimeSettings

MODES = ("serve", "hil")


@dataclass
class RuntimeConfig:
    """Runtime settings (see ``RuntimeSettings``) and how long to serve.

    Attributes:
        max_seconds: stop serving after this long [s] (every run is bounded).
        episodes: stop after this many machine episodes have ended (``None``: no limit).
    """

    max_sensor_age_s: float = 0.15
    max_inference_s: float | None = None
    speedup: float = 1.0
    host: str = "127.0.0.1"
    port: int = 47000
    max_seconds: float = 60.0
    episodes: int | None = None


@dataclass
class HilConfig:
    """The simulator bridge of ``mode=hil``.

    Attributes:
        episodes: seeded episodes (the evaluator's starts: ``seed * 100_000 + i``).
        seed: base seed.
        command_wait_s: machine time the bridge waits for each command (``None``: half a
            period); a long wait makes the run lockstep, as the in-process evaluator.
        max_steps: cut each episode after this many control steps (``None``: the env's limit).
    """

    episodes: int = 3
    seed: int = 1
    command_wait_s: float | None = None
    max_steps: int | None = None


@dataclass
class DeployConfig:
    """``mode``: ``serve`` (wait for a machine) or ``hil`` (the simulator is the machine)."""

    controller: str | None = None
    mode: str = "serve"
    env: EnvConfig = field(default_factory=EnvConfig)
    runtime: RuntimeConfig = field(default_factory=RuntimeConfig)
    hil: HilConfig = field(default_factory=HilConfig)
    output_dir: str = "outputs/deploy"

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"deploy: mode must be one of {MODES}, got {self.mode!r}")
        if not self.controller:
            raise ValueError("deploy: give controller=<file.onnx or best.pt>")

    def runtime_settings(self, control_hz: float | None = None) -> RuntimeSettings:
        """``control_hz``: the simulator's actual rate (a whole number of physics steps
        per period, e.g. 2.994 Hz for 3 Hz at 500 Hz physics); default ``env.control_hz``."""
        r = self.runtime
        return RuntimeSettings(
            control_hz=self.env.control_hz if control_hz is None else control_hz,
            max_sensor_age_s=r.max_sensor_age_s,
            max_inference_s=r.max_inference_s,
            speedup=r.speedup,
            host=r.host,
            port=0 if self.mode == "hil" else r.port,
        )

    def bridge_settings(self) -> BridgeSettings:
        return BridgeSettings(
            simulator=self.env.simulator,
            env_kwargs=self.env.make_kwargs(),
            seeds=tuple(self.hil.seed * 100_000 + i for i in range(self.hil.episodes)),
            speedup=self.runtime.speedup,
            command_wait_s=self.hil.command_wait_s,
            max_steps=self.hil.max_steps,
        )
