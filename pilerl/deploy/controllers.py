"""Exported controllers as the runtime runs them: raw readings in, controls out.

Two kinds, chosen by file suffix:

- ``.onnx``: an ``export_onnx`` file run by onnxruntime on one thread. Its inputs are
  named after the sensors (raw physical units, shape [1, 1]); normalisation is inside.
- ``.pt``: a pilerl actor checkpoint (``best.pt``) run as its TorchRL ``TensorDictModule``,
  as the closed-loop evaluator runs it.

``scripted`` stands for the simulator's scripted expert (its plugin's): a controller with a
known success rate, for checking the runtime and the HIL bridge without a trained one.

All return ``action`` as float32 [boom, bucket, throttle]; clamping to [-1, 1] and the
check for non-finite output are the runtime's (the same rule as the simulator's
``step``: finite values are clipped, non-finite ones refused).
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np
import torch
from tensordict import TensorDict


class DeployedController(Protocol):
    """What the runtime needs from a controller."""

    name: str
    input_names: list[str]  # sensor names the controller reads, in its input order

    def act(self, readings: np.ndarray) -> np.ndarray:
        """float32 [len(input_names)] raw readings -> float32 [3] controls."""
        ...


class OnnxController:
    """An ONNX export run by onnxruntime with one intra- and one inter-op thread."""

    def __init__(self, path: str | Path) -> None:
        import onnxruntime

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such ONNX file")
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        options.execution_mode = onnxruntime.ExecutionMode.ORT_SEQUENTIAL
        try:
            self.session = onnxruntime.InferenceSession(
                str(path), options, providers=["CPUExecutionProvider"]
            )
        except Exception as error:  # noqa: BLE001 - onnxruntime raises its own kinds
            raise ValueError(f"{path}: not a loadable ONNX model ({error})") from error
        self.input_names = [i.name for i in self.session.get_inputs()]
        outputs = [o.name for o in self.session.get_outputs()]
        if "action" not in outputs:
            raise ValueError(f"{path}: the model has no 'action' output (outputs: {outputs})")
        self.name = path.name
        self._feeds = {name: np.zeros((1, 1), dtype=np.float32) for name in self.input_names}

    def act(self, readings: np.ndarray) -> np.ndarray:
        for i, feed in enumerate(self._feeds.values()):
            feed[0, 0] = readings[i]
        return self.session.run(["action"], self._feeds)[0][0]


class CheckpointController:
    """A pilerl actor checkpoint, run under ``inference_mode``: a neural controller as its
    ``inference_actor`` (traced, frozen; bit-identical outputs), the forest as its actor."""

    def __init__(self, path: str | Path) -> None:
        from pilerl.policies import RandomForestActor, load_actor
        from pilerl.policies.actors import inference_actor

        actor = load_actor(path)
        self.actor = actor if isinstance(actor, RandomForestActor) else inference_actor(actor)
        self.input_names = list(self.actor.in_keys)
        self.name = Path(path).name

    def act(self, readings: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            values = torch.from_numpy(np.asarray(readings, dtype=np.float32))
            td = TensorDict(
                {name: values[i : i + 1] for i, name in enumerate(self.input_names)}, []
            )
            return self.actor(td)["action"].numpy()


class ScriptedOperatorController:
    """The simulator's nominal scripted expert (its plugin's ``scripted_expert``), reading
    every sensor of the layout.

    It keeps time by counting calls (one per control period) and is reset at each
    episode start, as the evaluator resets it.
    """

    def __init__(self, sensors: list[str], *, control_hz: float, simulator: str) -> None:
        from pilerl.sim import get_simulator

        self.operator = get_simulator(simulator).make_expert(dt=1.0 / control_hz)
        self.input_names = list(sensors)
        self.name = SCRIPTED

    def reset(self) -> None:
        self.operator.reset()

    def act(self, readings: np.ndarray) -> np.ndarray:
        return self.operator.act(dict(zip(self.input_names, readings.tolist(), strict=True)))


SCRIPTED = "scripted"


def load_controller(
    path: str | Path,
    *,
    sensors: list[str] | None = None,
    control_hz: float = 20.0,
    simulator: str = "pile_loader",
) -> DeployedController:
    """``OnnxController`` for ``.onnx``, ``CheckpointController`` for ``.pt``, and the
    ``ScriptedOperatorController`` for ``scripted`` (``simulator``'s expert, which reads
    ``sensors``)."""
    if str(path) == SCRIPTED:
        if sensors is None:
            raise ValueError("the scripted operator needs the machine's sensor names")
        return ScriptedOperatorController(sensors, control_hz=control_hz, simulator=simulator)
    suffix = Path(path).suffix
    if suffix == ".onnx":
        return OnnxController(path)
    if suffix == ".pt":
        return CheckpointController(path)
    raise ValueError(
        f"{path}: unknown controller file type {suffix!r}; expected .onnx, .pt or 'scripted'"
    )
