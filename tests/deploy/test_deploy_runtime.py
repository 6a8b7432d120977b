"""The runtime on real loopback UDP: address, bounds, and a machine that marks no episodes."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from pilerl.data import EpisodeStore, validate_episode
from pilerl.deploy import ControlRuntime, MachineLink, RuntimeSettings
from pilerl.deploy.packets import ControllerState, SensorChannel, SensorFlag, SensorLayout

LAYOUT = SensorLayout(
    (SensorChannel("angle", "rad", -1.0, 1.0), SensorChannel("pressure", "MPa", 0.0, 40.0))
)


class HalfAngle:
    name = "half_angle"
    input_names = ["angle"]

    def act(self, readings):
        return np.float32([readings[0] / 2, 0.0, 0.25])


def test_binds_to_loopback_by_default_and_stops_on_its_bounds(tmp_path):
    runtime = ControlRuntime(HalfAngle(), LAYOUT, RuntimeSettings(), run_dir=tmp_path)
    assert runtime.address[0] == "127.0.0.1"
    summary = runtime.run(max_seconds=0.2)
    assert summary["commands"] == 0 and summary["episodes_written"] == 0
    assert (tmp_path / "summary.json").exists() and (tmp_path / "layout.json").exists()


def test_a_machine_without_episode_marks_still_gives_one_episode(tmp_path):
    settings = RuntimeSettings(control_hz=20.0, max_sensor_age_s=5.0)
    runtime = ControlRuntime(HalfAngle(), LAYOUT, settings, run_dir=tmp_path)
    result = {}
    server = threading.Thread(
        target=lambda: result.update(runtime.run(max_seconds=20.0, max_idle_s=0.5))
    )
    server.start()
    link = MachineLink(LAYOUT, runtime.address)
    angles = [0.1, 0.2, 0.3, 0.4, 0.5]
    for step, angle in enumerate(angles):
        seq = link.send_sensors(step, np.float32([angle, 10.0]), SensorFlag.NONE)
        link.receive_until(time.monotonic() + 5.0, answered_seq=seq)
        time.sleep(0.06)  # one period apart: every reading is answered on arrival
    link.close()
    server.join(timeout=30)
    assert not server.is_alive()
    commands = [c.packet for c in link.received]
    assert [c.answered_seq for c in commands] == list(range(5))
    assert all(c.state == ControllerState.ARMED for c in commands)
    np.testing.assert_allclose([c.controls[0] for c in commands], np.float32(angles) / 2)
    store = EpisodeStore.open(tmp_path / "episodes")
    (episode,) = list(store)
    validate_episode(episode, ["angle", "pressure"], action_dim=3)
    assert bool(episode["next", "truncated"][-1]) and not bool(episode["next", "terminated"][-1])
    np.testing.assert_allclose(episode["angle"].squeeze(-1).numpy(), angles)
    assert result["commands"] == 5 and result["faults"] == {}


def test_a_controller_reading_an_unsent_sensor_is_refused():
    class NeedsSpeed(HalfAngle):
        input_names = ["angle", "speed"]

    with pytest.raises(ValueError, match=r"reads sensors \['speed'\]"):
        ControlRuntime(NeedsSpeed(), LAYOUT, RuntimeSettings())
