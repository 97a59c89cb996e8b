"""Random scans and odometry never break the core: no exception, finite poses and weights."""
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam

reading = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                    st.floats(min_value=0.0, max_value=5.0))
coordinate = st.floats(min_value=-20.0, max_value=20.0)


@st.composite
def scans(draw):
    n = draw(st.integers(min_value=1, max_value=40))
    ranges = np.array(draw(st.lists(reading, min_size=n, max_size=n)), dtype=float)
    angle_min = draw(st.floats(min_value=-7.0, max_value=7.0))
    inc = draw(st.floats(min_value=-0.5, max_value=0.5).filter(lambda v: abs(v) > 1e-4))
    range_min = draw(st.floats(min_value=0.0, max_value=1.0))
    range_max = range_min + draw(st.floats(min_value=0.01, max_value=10.0))
    upside_down = draw(st.booleans())
    return Scan.from_laser(ranges, angle_min, inc, range_min, range_max,
                           mount=(0.1, -0.05, draw(st.floats(min_value=-4, max_value=4))),
                           upside_down=upside_down)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(scans(), coordinate, coordinate, st.floats(min_value=-10, max_value=10)),
                min_size=1, max_size=6),
       st.sampled_from(["assignment", "odometry"]))
def test_core_survives_random_input(steps, motion_model):
    cfg = SlamConfig(particles=4, seed=0, map_width=4.0, map_height=4.0, max_range=3.0,
                     motion_model=motion_model)
    slam = FastSlam(cfg)
    for t, (scan, x, y, th) in enumerate(steps):
        scan = Scan(ranges=scan.ranges, angles=scan.angles, range_min=scan.range_min,
                    range_max=scan.range_max, mount=scan.mount, stamp=float(t))
        info = slam.step(np.array([x, y, th]), scan)
        assert info.processed
        assert np.all(np.isfinite(slam.poses))
        w = slam.weights
        assert np.all(np.isfinite(w)) and abs(w.sum() - 1.0) < 1e-9
        assert np.all(np.abs(slam.poses[:, 2]) <= np.pi)
    assert slam.trajectory().shape == (len(steps), 4)
