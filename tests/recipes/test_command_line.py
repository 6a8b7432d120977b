"""The ``python -m`` command lines start from the library's settings, as the recipes do."""

from __future__ import annotations

import socket
from pathlib import Path

from hydra import compose, initialize_config_dir

from pilerl.config import register_configs
from pilerl.deploy.__main__ import ENV, build_parser
from pilerl.deploy.__main__ import main as deploy_main
from pilerl.deploy.hil import simulator_layout
from pilerl.deploy.packets import RearmPacket, decode
from pilerl.sweeps.summary import AVERAGED_KEYS, summarize_sweep

CONF = Path(__file__).resolve().parents[2] / "conf"

register_configs()


def test_deploy_command_line_defaults_are_the_deploy_recipes():
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        recipe = compose(config_name="deploy", overrides=["controller=x.onnx"])
    runtime = build_parser().parse_args(["runtime", "x.onnx"])
    assert (runtime.host, runtime.port) == (recipe.runtime.host, recipe.runtime.port)
    assert runtime.max_seconds == recipe.runtime.max_seconds
    assert runtime.episodes == recipe.runtime.episodes
    assert runtime.max_sensor_age == recipe.runtime.max_sensor_age_s
    assert runtime.speedup == recipe.runtime.speedup
    assert (runtime.control_hz, runtime.condition) == (recipe.env.control_hz, recipe.env.condition)
    bridge = build_parser().parse_args(["bridge"])
    assert (bridge.port, bridge.seed) == (recipe.runtime.port, recipe.hil.seed)


def test_deploy_rearm_reaches_a_listening_runtime():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as runtime:
        runtime.bind(("127.0.0.1", 0))
        runtime.settimeout(30)
        assert deploy_main(["rearm", "--port", str(runtime.getsockname()[1])]) == 0
        packet, _ = runtime.recvfrom(4096)
    layout, _ = simulator_layout(ENV.simulator, {"condition": ENV.condition})
    rearm = decode(packet, layout_id=layout.layout_id, n_sensors=len(layout.names))
    assert isinstance(rearm, RearmPacket)


def test_summary_averages_over_the_seed_by_default():
    assert AVERAGED_KEYS == ("seed",)
    assert summarize_sweep.__kwdefaults__["average_over"] is AVERAGED_KEYS
