import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from uavloc_gcs.geo import LocalFrame
import pytest
from uavloc_gcs.errors import ConfigError


@settings(max_examples=60, deadline=None)
@given(
    lat0=st.floats(-80, 80),
    lon0=st.floats(-179, 179),
    e=st.floats(-20_000, 20_000),
    n=st.floats(-20_000, 20_000),
)
def test_round_trip_is_exact_to_a_millimetre(lat0, lon0, e, n):
    f = LocalFrame(lat0, lon0)
    lat, lon = f.to_wgs84(e, n)
    e2, n2 = f.to_local(lat, lon)
    assert abs(e2 - e) < 1e-3 and abs(n2 - n) < 1e-3


def test_distances_are_metric():
    f = LocalFrame(42.625, 13.283)
    # One minute of latitude is about 1852 m.
    e, n = f.to_local(42.625 + 1 / 60, 13.283)
    assert abs(e) < 1e-6
    assert n == pytest.approx(1850.0, rel=2e-3)


def test_array_helpers():
    f = LocalFrame(0.0, 0.0)
    xy = np.array([[0.0, 0.0], [1000.0, -500.0]])
    back = f.to_local_xy(f.to_wgs84_latlon(xy))
    assert np.allclose(back, xy, atol=1e-6)


def test_bad_origin():
    with pytest.raises(ConfigError, match="latitude"):
        LocalFrame(95.0, 0.0)
