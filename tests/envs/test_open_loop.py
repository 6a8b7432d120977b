"""The open-loop scoop that the identity tests and the soil benchmark drive with."""

from __future__ import annotations

import numpy as np
from pilerl_pile_loader.open_loop import scripted_action

DRIVE_IN, LIFT, CURL = [0.0, 0.0, 0.8], [0.5, 0.3, 0.5], [0.8, 1.0, 0.1]


def test_the_script_drives_in_lifts_and_curls_on_its_20_hz_clock():
    parts = {0: DRIVE_IN, 59: DRIVE_IN, 60: LIFT, 119: LIFT, 120: CURL, 400: CURL}
    for step, want in parts.items():
        action = scripted_action(step)
        assert action.dtype == np.float32 and action.tolist() == np.float32(want).tolist(), step
    # a phase runs the script ahead; an earlier curl (the batched identity test's 5.5 s); a
    # later lift (benchmarks/same_actions.py's 4 s)
    assert scripted_action(52, phase=8).tolist() == np.float32(LIFT).tolist()
    assert scripted_action(109, curl_from_s=5.5).tolist() == np.float32(LIFT).tolist()
    assert scripted_action(110, curl_from_s=5.5).tolist() == np.float32(CURL).tolist()
    assert scripted_action(100, phase=10, curl_from_s=5.5).tolist() == np.float32(CURL).tolist()
    assert scripted_action(79, lift_from_s=4.0).tolist() == np.float32(DRIVE_IN).tolist()
    assert scripted_action(80, lift_from_s=4.0).tolist() == np.float32(LIFT).tolist()
