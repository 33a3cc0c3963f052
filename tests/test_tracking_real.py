"""The tracker on real pedestrian trajectories (MOT15 TUD-Campus ground truth as noisy detections)."""

import pytest

from flowtrack.datasets import track_tud_campus


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tud_campus_centres_are_tracked(seed):
    m = track_tud_campus(seed=seed)
    assert m["frames"] == 71 and m["objects"] == 8
    assert m["mota"] >= 0.8, m
    assert m["idf1"] >= 0.75, m
    assert m["motp"] < 10.0  # pixels; the detections carry 3 px noise per axis


@pytest.mark.parametrize("kwargs, name", [({"noise_px": 0.0}, "noise_px"), ({"drop": 1.0}, "drop"),
                                          ({"q": -1.0}, "q")])
def test_bad_arguments(kwargs, name):
    with pytest.raises(ValueError, match=name):
        track_tud_campus(**kwargs)
