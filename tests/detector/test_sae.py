"""Surface of Active Events: explicit never-fired sentinel, per-polarity or shared, newest wins."""

import numpy as np
import pytest

from evedge.detector.sae import NEVER_US, SurfaceOfActiveEvents
from evedge.events import SensorSize, make_events

S = SensorSize(4, 3)


def test_never_fired_is_not_zero_and_newest_wins():
    sae = SurfaceOfActiveEvents(S)
    assert (sae.times_us == NEVER_US).all() and NEVER_US < 0
    sae.process(make_events([1, 1, 2, 1], [0, 0, 2, 0], [0, 5, 5, 7], [True, True, False, True]))
    assert sae.plane(True)[0, 1] == 7
    assert sae.plane(False)[2, 2] == 5
    assert sae.plane(False)[0, 1] == NEVER_US
    assert sae.fired().sum() == 2
    # an event at t = 0 is a real event
    sae.reset()
    sae.process(make_events([3], [1], [0], [False]))
    assert sae.fired()[0, 1, 3] and sae.plane(False)[1, 3] == 0


def test_shared_surface_and_random_against_loop(random_events):
    ev = random_events(500, S.width, S.height, rng=3)
    for per_pol in (True, False):
        sae = SurfaceOfActiveEvents(S, per_polarity=per_pol)
        for chunk in np.array_split(ev, 7):
            sae.process(chunk)
        want = np.full(sae.times_us.shape, NEVER_US)
        for e in ev:
            want[int(e["p"]) if per_pol else 0, e["y"], e["x"]] = e["t"]
        np.testing.assert_array_equal(sae.times_us, want)


def test_errors():
    with pytest.raises(TypeError, match="per_polarity"):
        SurfaceOfActiveEvents(S, per_polarity="yes")
    sae = SurfaceOfActiveEvents(S)
    with pytest.raises(ValueError, match="outside the sensor"):
        sae.process(make_events([4], [0], [0], [True]))
    sae.process(make_events([0], [0], [10], [True]))
    with pytest.raises(ValueError, match="previous chunk"):
        sae.process(make_events([0], [0], [9], [True]))
