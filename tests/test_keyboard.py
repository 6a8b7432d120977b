"""Keyboard teleoperation: key presses step and hold control levels."""

from __future__ import annotations

import numpy as np

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
