"""Keyboard teleoperation: key presses set held control levels.

MuJoCo's viewer reports key presses (GLFW key codes), not releases, so each press steps
a control's level by ``STEP`` and the level is held until changed; space stops all.

| key | control |
|---|---|
| Up / Down | boom raise / lower |
| Right / Left | bucket curl / dump |
| W / S | throttle forward / back |
| Space | all controls to zero |
"""

from __future__ import annotations

import threading

import numpy as np

STEP = 0.25  # change of a control level per key press
# GLFW key codes (glfw.KEY_*), as passed to mujoco.viewer's key_callback
KEY_UP, KEY_DOWN, KEY_RIGHT, KEY_LEFT = 265, 264, 262, 263
KEY_W, KEY_S, KEY_SPACE = 87, 83, 32
KEYMAP = {
    KEY_UP: (0, +STEP),
    KEY_DOWN: (0, -STEP),
    KEY_RIGHT: (1, +STEP),
    KEY_LEFT: (1, -STEP),
    KEY_W: (2, +STEP),
    KEY_S: (2, -STEP),
}


KEY_BINDINGS = (
    ("Up / Down", "boom raise / lower"),
    ("Right / Left", "bucket curl / dump"),
    ("W / S", "throttle forward / back"),
    ("Space", "all controls to zero"),
)
VIEWER_CLOSE_TIMEOUT_S = 10.0


def key_bindings_text() -> str:
    """The keys as a small table for the terminal (printed when teleoperation starts)."""
    width = max(len(key) for key, _ in KEY_BINDINGS)
    lines = [f"  {key:<{width}}  {action}" for key, action in KEY_BINDINGS]
    return "\n".join([f"Keys (each press steps a level by {STEP:g}; levels are held):", *lines])


def close_viewer(viewer) -> None:
    """Close a ``mujoco.viewer.launch_passive`` window and wait for its thread to end.

    The passive viewer renders in a daemon thread that destroys its window after the
    loop ends; a process that exits meanwhile runs ``glfw.terminate`` at the same time,
    which crashed at random (SIGSEGV on exit). Joining the thread first avoids the race.
    """
    viewer.close()
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and "_launch_internal" in thread.name:
            thread.join(timeout=VIEWER_CLOSE_TIMEOUT_S)


class KeyboardOperator:
    """Holds [boom, bucket, throttle] levels changed by ``on_key``; ``act`` returns them."""

    def __init__(self) -> None:
        self.levels = np.zeros(3, dtype=np.float32)

    def reset(self) -> None:
        self.levels[:] = 0.0

    def on_key(self, keycode: int) -> None:
        if keycode == KEY_SPACE:
            self.levels[:] = 0.0
        elif keycode in KEYMAP:
            index, delta = KEYMAP[keycode]
            self.levels[index] = np.clip(self.levels[index] + delta, -1.0, 1.0)

    def act(self, sensors: dict) -> np.ndarray:
        del sensors  # a person looks at the scene, not at the sensor values
        return self.levels.copy()
