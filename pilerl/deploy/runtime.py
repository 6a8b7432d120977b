"""The controller runtime: UDP in, ``ControlLoop``, UDP out, logs in the run directory.

    runtime = ControlRuntime(load_controller("dannet.onnx"), layout, RuntimeSettings())
    summary = runtime.run(max_seconds=60)

Every run is bounded (``max_seconds``, and optionally a number of machine episodes or an
idle time), binds to loopback unless ``settings.host`` says otherwise, and never raises
on what arrives over the network: malformed datagrams are counted and dropped.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from pathlib import Path

from .controllers import DeployedController
from .episode_log import DeploymentLog, summarize
from .loop import ControlLoop, RuntimeSettings, check_inputs
from .packets import SensorFlag, SensorLayout, SensorPacket

MAX_DATAGRAM = 2048  # bytes; anything longer is truncated by the socket and then refused
POLL_S = 0.05  # longest wait without checking the stop conditions [s]
WARM_UP_CALLS = 5  # first inferences allocate and compile: not on the machine's time


def warm_up(controller: DeployedController, layout: SensorLayout) -> None:
    """Run the controller a few times on mid-range readings before serving."""
    middle = (layout.low + layout.high) / 2
    index = [layout.names.index(n) for n in controller.input_names if n in layout.names]
    for _ in range(WARM_UP_CALLS):
        controller.act(middle[index])
    if hasattr(controller, "reset"):
        controller.reset()


class ControlRuntime:
    """See the module docstring.

    Args:
        controller: from ``load_controller``.
        layout: the machine's sensor layout (``SensorLayout.from_env`` for the simulator).
        settings: rates, watchdog age, address.
        run_dir: where logs and episodes go (``None``: keep nothing but the summary).
        runtime_kind: a label for the logs (``onnx``, ``checkpoint``).
    """

    def __init__(
        self,
        controller: DeployedController,
        layout: SensorLayout,
        settings: RuntimeSettings,
        *,
        run_dir: str | Path | None = None,
        runtime_kind: str = "",
    ) -> None:
        check_inputs(controller, layout)  # before anything is written or bound
        self.settings = settings
        self.log = (
            DeploymentLog(
                run_dir,
                layout,
                controller_name=controller.name,
                control_hz=settings.control_hz,
                runtime_kind=runtime_kind,
            )
            if run_dir is not None
            else None
        )
        warm_up(controller, layout)
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind((settings.host, settings.port))
        self._rearm_requested = threading.Event()
        self._episodes_ended = 0
        self.loop = ControlLoop(
            controller,
            layout,
            settings,
            clock=time.monotonic,
            send=self._send,
            on_command=self.log.on_command if self.log else None,
            on_fault=self.log.on_fault if self.log else None,
            on_reading=self._on_reading,
        )

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the runtime listens on."""
        return self.socket.getsockname()

    def rearm(self) -> None:
        """Ask for a re-arm (thread-safe); applied at the loop's next wake-up."""
        self._rearm_requested.set()

    def _send(self, data: bytes, address) -> None:
        with contextlib.suppress(OSError):  # the machine's port is gone: it will go stale
            self.socket.sendto(data, address)

    def _on_reading(self, packet: SensorPacket, now_s: float) -> None:
        if packet.flags & SensorFlag.EPISODE_END:
            self._episodes_ended += 1
        if self.log is not None:
            self.log.on_reading(packet, now_s)

    def run(
        self,
        *,
        max_seconds: float,
        episodes: int | None = None,
        max_idle_s: float | None = None,
        stop: threading.Event | None = None,
    ) -> dict:
        """Serve until ``max_seconds`` pass, ``episodes`` machine episodes have ended,
        nothing arrived for ``max_idle_s`` (after the first datagram), or ``stop`` is set.
        Returns the run summary (also written to ``summary.json`` with a run directory)."""
        loop, sock = self.loop, self.socket
        start = time.monotonic()
        last_datagram = None
        try:
            while True:
                now = time.monotonic()
                if now - start >= max_seconds or (stop is not None and stop.is_set()):
                    break
                if episodes is not None and self._episodes_ended >= episodes:
                    break
                if (
                    max_idle_s is not None
                    and last_datagram is not None
                    and now - last_datagram > max_idle_s
                ):
                    break
                if self._rearm_requested.is_set():
                    self._rearm_requested.clear()
                    loop.rearm(now)
                loop.on_timer(now)
                wake = loop.next_wakeup()
                timeout = POLL_S if wake is None else min(POLL_S, max(wake - now, 0.0))
                sock.settimeout(timeout if timeout > 0 else 1e-6)
                try:
                    data, sender = sock.recvfrom(MAX_DATAGRAM)
                except (TimeoutError, BlockingIOError):
                    continue
                except ConnectionRefusedError:  # an ICMP error from an earlier send
                    continue
                last_datagram = time.monotonic()
                loop.on_datagram(data, last_datagram, sender)
        finally:
            self.socket.close()
        if self.log is not None:
            return self.log.close(loop.counters)
        return summarize(loop.counters, [])
