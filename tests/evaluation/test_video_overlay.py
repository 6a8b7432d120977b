"""Videos carry an overlay: condition, time, fill, outcome and a gauge per sensor."""

from __future__ import annotations

import numpy as np

from pilerl.evaluation.episode import Episode
from pilerl.evaluation.video import annotate_frames

RANGES = {"drive_pressure": (0.0, 30.0), "telescope_pressure": (0.0, 10.0)}


def episode_with(drive_mpa: float, *, success: bool) -> Episode:
    steps = 4
    return Episode(
        time_s=np.arange(1, steps + 1) * 0.05,
        sensors={"drive_pressure": np.full(steps, drive_mpa), "telescope_pressure": np.ones(4)},
        actions=np.zeros((steps, 3)),
        rewards=np.zeros(steps),
        traces={"fill_fraction": np.linspace(0.1, 0.6, steps)},
        final_info={"success": success},
        start_info={},
        start_sensors={"drive_pressure": 0.0, "telescope_pressure": 0.0},
        frames=[np.full((120, 200, 3), 90, np.uint8) for _ in range(3)],
        frame_hz=10.0,  # every second step
    )


def test_the_overlay_draws_on_every_frame_and_shows_the_sensor_levels():
    low = annotate_frames(
        episode_with(3.0, success=True), condition="winter_c", sensor_ranges=RANGES
    )
    high = annotate_frames(
        episode_with(27.0, success=True), condition="summer", sensor_ranges=RANGES
    )
    assert len(low) == 3 and all(f.shape == (120, 200, 3) for f in low)
    assert all((f != 90).any() for f in low)  # every frame has the overlay
    # the drive-pressure gauge (first sensor, bottom left) is longer at 27 MPa than at 3 MPa
    gauge_row = slice(120 - 2 * 10, 120)
    blue = np.array([90, 170, 255])
    assert (high[-1][gauge_row] == blue).all(-1).sum() > (low[-1][gauge_row] == blue).all(-1).sum()


def test_the_outcome_shows_on_the_last_frame_only():
    kwargs = {"condition": "winter_c", "sensor_ranges": RANGES}
    failed = annotate_frames(episode_with(10.0, success=False), **kwargs)
    succeeded = annotate_frames(episode_with(10.0, success=True), **kwargs)
    assert np.array_equal(failed[-2], succeeded[-2])  # no outcome before the end
    assert not np.array_equal(failed[-1], succeeded[-1])  # FAILED vs SUCCESS at the end
