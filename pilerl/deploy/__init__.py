"""Deployment: a real-time controller runtime over UDP with a watchdog, and the simulator
bridge that tests it hardware-in-the-loop (see docs/deployment.md).

| module | job |
|---|---|
| ``packets`` | the versioned binary wire format and the sensor layout |
| ``watchdog`` | when controls must be neutral, and why (latched faults) |
| ``controllers`` | ONNX or checkpoint controllers: readings in, controls out |
| ``loop`` | the control loop's timing rules, without sockets |
| ``runtime`` | the loop on UDP, bounded, with logs |
| ``episode_log`` | every run written as demonstration episodes plus cycle/fault logs |
| ``link`` | the machine's side of the link, with fault injection |
| ``bridge`` | the simulator as the machine |
| ``hil`` | one hardware-in-the-loop run (runtime here, bridge in a forked process) |
| ``faults`` | the fault-injection scenarios and their table |
"""

from .bridge import BridgeSettings, run_bridge
from .controllers import CheckpointController, OnnxController, load_controller
from .link import FAULT_KINDS, LinkFault, MachineLink
from .loop import ControlLoop, RuntimeSettings
from .packets import PACKET_VERSION, PacketError, SensorLayout, decode
from .runtime import ControlRuntime
from .watchdog import NEUTRAL, Fault, Watchdog

__all__ = [
    "FAULT_KINDS",
    "NEUTRAL",
    "PACKET_VERSION",
    "BridgeSettings",
    "CheckpointController",
    "ControlLoop",
    "ControlRuntime",
    "Fault",
    "LinkFault",
    "MachineLink",
    "OnnxController",
    "PacketError",
    "RuntimeSettings",
    "SensorLayout",
    "Watchdog",
    "decode",
    "load_controller",
    "run_bridge",
]
