"""Headless rendering: chosen before MuJoCo is imported, checked before any work."""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pilerl import rendering

ROOT = Path(__file__).resolve().parents[2]
PLAIN_SHELL = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
PLAIN_SHELL.pop("WAYLAND_DISPLAY", None)


@pytest.mark.parametrize(
    "imports", ["import pilerl, torchrl.envs", "import torchrl.envs, mujoco; import pilerl"]
)
def test_a_plain_shell_renders_whatever_was_imported_first(imports):
    """No MUJOCO_GL, no display: a frame renders even when MuJoCo came in before pilerl."""
    code = (
        f"{imports}\n"
        "import gymnasium as gym, os\n"
        "env = gym.make('pilerl/PileLoading-v0', render_mode='rgb_array', render_size=(48, 64))\n"
        "env.reset(seed=0)\n"
        "frame = env.render()\n"
        "env.close()\n"
        "print(os.environ['MUJOCO_GL'], frame.shape, int(frame.std() > 0), sep='|')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], env=PLAIN_SHELL, capture_output=True, text=True, timeout=240
    )
    assert done.returncode == 0, done.stderr[-2000:]
    backend, shape, not_blank = done.stdout.strip().splitlines()[-1].split("|")
    assert backend in rendering.HEADLESS_BACKENDS  # egl, or osmesa where only Mesa's is
    assert (shape, not_blank) == ("(48, 64, 3)", "1")


def test_videos_auto_goes_on_without_videos_when_the_machine_cannot_render(monkeypatch, caplog):
    monkeypatch.setattr(rendering, "rendering_available", lambda: (False, "no EGL"))
    assert rendering.resolve_videos("auto") is False
    assert "cannot render offscreen (no EGL)" in caplog.text
    assert rendering.resolve_videos("False") is False  # Hydra's str of a bool
    with pytest.raises(rendering.RenderingUnavailable, match="videos=true.*no EGL"):
        rendering.resolve_videos("True")
    with pytest.raises(ValueError, match="true, false or auto"):
        rendering.resolve_videos("sometimes")


@pytest.mark.skipif(
    ctypes.util.find_library("OSMesa") is not None, reason="needs a machine without OSMesa"
)
def test_a_machine_without_the_backend_is_detected_before_any_work(tmp_path):
    """With MUJOCO_GL=osmesa and no OSMesa library, no frame can be rendered: video=true
    refuses before the scoop, auto warns once and goes on without videos."""
    env = {**PLAIN_SHELL, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1"}
    scoop = [sys.executable, "recipes/scoop.py", "conditions=[summer]"]
    args = {"cwd": ROOT, "env": env, "capture_output": True, "text": True, "timeout": 300}
    refused = subprocess.run([*scoop, "video=true", f"hydra.run.dir={tmp_path / 'a'}"], **args)
    assert refused.returncode != 0
    assert "video=true, but this machine cannot render offscreen" in refused.stderr
    assert not (tmp_path / "a" / "trace_summer.csv").exists()  # refused before any work
    ran = subprocess.run([*scoop, "video=auto", f"hydra.run.dir={tmp_path / 'b'}"], **args)
    assert ran.returncode == 0, ran.stderr[-2000:]
    output = ran.stdout + ran.stderr
    assert output.count("cannot render offscreen") == 1
    assert (tmp_path / "b" / "report.md").exists()
    assert not list((tmp_path / "b").glob("*.mp4"))
