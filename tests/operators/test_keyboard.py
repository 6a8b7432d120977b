"""Keyboard teleoperation: key presses step and hold control levels."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from pilerl.operators.keyboard import (
    KEY_DOWN,
    KEY_LEFT,
    KEY_RIGHT,
    KEY_SPACE,
    KEY_UP,
    KEY_W,
    KeyboardOperator,
)


def test_presses_step_levels_which_are_held_and_clipped():
    op = KeyboardOperator()
    for key in (KEY_UP, KEY_UP, KEY_RIGHT, KEY_W, KEY_W, KEY_W, KEY_W, KEY_W):
        op.on_key(key)
    np.testing.assert_allclose(op.act({}), [0.5, 0.25, 1.0])  # throttle clipped at 1
    np.testing.assert_allclose(op.act({}), [0.5, 0.25, 1.0])  # held between presses
    op.on_key(KEY_DOWN)
    op.on_key(KEY_LEFT)
    op.on_key(KEY_LEFT)
    np.testing.assert_allclose(op.act({}), [0.25, -0.25, 1.0])
    op.on_key(999)  # unmapped keys change nothing
    np.testing.assert_allclose(op.act({}), [0.25, -0.25, 1.0])
    op.on_key(KEY_SPACE)
    np.testing.assert_allclose(op.act({}), [0.0, 0.0, 0.0])


def test_key_bindings_are_printed_for_every_mapped_key():
    from pilerl.operators.keyboard import key_bindings_text

    text = key_bindings_text()
    for words in ("Up / Down", "boom", "Right / Left", "bucket", "W / S", "throttle", "Space"):
        assert words in text


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (.ci/run has it)")
def test_the_viewer_closes_without_crashing_the_process_on_exit():
    """Teleop's viewer window, opened and closed on a virtual display, five times: the
    process must exit cleanly every time (it crashed on exit about every other time)."""
    code = (
        "import pilerl, gymnasium as gym, mujoco.viewer\n"
        "from pilerl.operators.keyboard import close_viewer\n"
        "sim = gym.make('pilerl/PileLoading-v0').unwrapped\n"
        "sim.reset(seed=0)\n"
        "viewer = mujoco.viewer.launch_passive(sim.model, sim.data)\n"
        "for _ in range(20):\n"
        "    sim.step([0.0, 0.0, 0.3])\n"
        "    viewer.sync()\n"
        "close_viewer(viewer)\n"
        "sim.close()\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    for _ in range(5):
        done = subprocess.run(
            ["xvfb-run", "-a", sys.executable, "-c", code],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr[-2000:]
