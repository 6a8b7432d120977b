"""Exported controllers compute what the PyTorch actor computes."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime
import pytest
import torch

from pilerl.policies import make_actor, save_actor
from pilerl.policies.checkpoint import read_provenance
from pilerl.policies.export import ExportError, export_onnx, export_program, main

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
EXTRA = ["boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {
    "sensors": {
        name: {"mean": 1.0 + i, "std": 0.5 + i, "min": -10.0, "max": 10.0}
        for i, name in enumerate(SENSORS + EXTRA)
    },
    "action": {"mean": [0.0] * 3, "std": [0.5] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
    "n_samples": 100,
}


@pytest.mark.parametrize(
    ("name", "attention"), [("nnet", None), ("nnetv2", None), ("annet", None), ("dannet", EXTRA)]
)
def test_onnx_matches_pytorch(tmp_path, name, attention):
    torch.manual_seed(0)
    actor = make_actor(
        name,
        sensors=SENSORS,
        stats=STATS,
        attention_sensors=None if attention is None else SENSORS + attention,
    )
    path, error = export_onnx(actor, tmp_path / f"{name}.onnx")
    assert error <= 1e-5
    session = onnxruntime.InferenceSession(str(path))
    assert [i.name for i in session.get_inputs()] == list(actor.in_keys)  # sensors by name
    readings = {k: np.full((3, 1), 2.0, np.float32) for k in actor.in_keys}  # any batch size
    action = session.run(["action"], readings)[0]
    expected = actor.module(*[torch.from_numpy(v) for v in readings.values()])[0]
    np.testing.assert_allclose(action, expected.detach().numpy(), atol=1e-5)


def test_torch_export_program_round_trips(tmp_path):
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=STATS)
    program = torch.export.load(export_program(actor, tmp_path / "dannet.pt2"))
    readings = tuple(torch.randn(5, 1) for _ in actor.in_keys)
    assert torch.equal(program.module()(*readings)[0], actor.module.eval()(*readings)[0])


def test_random_forest_is_refused_clearly(tmp_path):
    with pytest.raises(ExportError, match="random forest is not exported"):
        export_onnx(make_actor("rf", sensors=SENSORS, stats=STATS), tmp_path / "rf.onnx")
    assert not (tmp_path / "rf.onnx").exists()


def test_command_line(tmp_path, capsys):
    torch.manual_seed(0)
    save_actor(tmp_path / "best.pt", make_actor("nnetv2", sensors=SENSORS, stats=STATS))
    assert main([str(tmp_path / "best.pt"), "--onnx", str(tmp_path / "a.onnx")]) == 0
    assert "checked with onnxruntime" in capsys.readouterr().out
    metadata = onnxruntime.InferenceSession(str(tmp_path / "a.onnx")).get_modelmeta()
    assert "torch" in json.loads(metadata.custom_metadata_map["pilerl.provenance"])["packages"]
    assert read_provenance(tmp_path / "a.onnx") == read_provenance(tmp_path / "best.pt")
    assert main([str(tmp_path / "missing.pt"), "--onnx", str(tmp_path / "b.onnx")]) == 2
    assert "no such actor checkpoint" in capsys.readouterr().err


def test_onnx_file_is_self_contained_and_reexport_leaves_nothing_beside_it(tmp_path):
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=SENSORS + EXTRA)
    export_dir, copy_dir = tmp_path / "export", tmp_path / "copy"
    export_dir.mkdir()
    copy_dir.mkdir()
    for _ in range(2):  # a re-export replaces the file and adds nothing
        path, _ = export_onnx(actor, export_dir / "dannet.onnx")
    assert sorted(p.name for p in export_dir.iterdir()) == ["dannet.onnx"]  # no hidden .data
    copied = copy_dir / "dannet.onnx"
    copied.write_bytes(path.read_bytes())  # the .onnx alone, copied elsewhere
    session = onnxruntime.InferenceSession(str(copied))
    readings = {k: np.full((1, 1), 1.5, np.float32) for k in actor.in_keys}
    action = session.run(["action"], readings)[0]
    expected = actor.module(*[torch.from_numpy(v) for v in readings.values()])[0]
    np.testing.assert_allclose(action, expected.detach().numpy(), atol=1e-5)
