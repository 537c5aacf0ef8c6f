"""Slot CSV round trip (property-based): what dumps writes, loads reads back to the stated precision."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from uavloc_gcs.estimation.slots_csv import dumps_slots_csv, loads_slots_csv
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.observations import SlotBatch

FRAME = LocalFrame(42.625, 13.283)

row = st.tuples(
    st.floats(0, 1e5, allow_nan=False),  # t_s
    st.integers(0, 255),  # vehicle
    st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(0, 500),  # east, north, up
    st.integers(0, 2**32 - 1),  # emitter id
    st.floats(-130, 0),  # rssi
    st.integers(1, 1000),  # n_samples
)


@settings(max_examples=60, deadline=None)
@given(st.lists(row, min_size=0, max_size=30))
def test_dumps_then_loads_round_trip(rows):
    if rows:
        a = np.array(rows, dtype=float)
        slots = SlotBatch.from_columns(a[:, 0], a[:, 1].astype(int), a[:, 2:5], a[:, 5].astype(np.int64),
                                       a[:, 6], a[:, 7].astype(int))
    else:
        slots = SlotBatch.empty()
    back = loads_slots_csv(dumps_slots_csv(slots, FRAME), FRAME)
    s = slots.sorted_by_time()
    assert len(back) == len(s)
    assert np.array_equal(back.vehicle, s.vehicle) and np.array_equal(back.emitter_id, s.emitter_id)
    assert np.array_equal(back.n_samples, s.n_samples)
    assert np.allclose(back.t_s, s.t_s, atol=5e-4)
    assert np.allclose(back.rssi_dbm, s.rssi_dbm, atol=5e-3)
    assert np.allclose(back.xyz_m[:, :2], s.xyz_m[:, :2], atol=2e-3)  # 1e-8 degrees ~ 1 mm
    assert np.allclose(back.xyz_m[:, 2], s.xyz_m[:, 2], atol=5e-3)


sensor_row = st.tuples(
    st.floats(0, 1e5, allow_nan=False), st.integers(0, 255),
    st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(0, 500),
    st.integers(0, 2**48 - 1),  # address (= emitter id, as a sensor reports it)
    st.floats(-130, 0), st.integers(1, 255),
    st.integers(0, 2**32 - 1),  # fingerprint
    st.integers(0, 255),  # channel
)


@settings(max_examples=60, deadline=None)
@given(st.lists(sensor_row, min_size=1, max_size=30))
def test_sensor_columns_round_trip(rows):
    a = np.array(rows, dtype=object)
    address = a[:, 5].astype(np.int64)
    slots = SlotBatch.from_columns(a[:, 0].astype(float), a[:, 1].astype(int), a[:, 2:5].astype(float), address,
                                   a[:, 6].astype(float), a[:, 7].astype(int), address=address,
                                   fingerprint=a[:, 8].astype(np.int64), channel=a[:, 9].astype(int))
    back = loads_slots_csv(dumps_slots_csv(slots, FRAME), FRAME)
    s = slots.sorted_by_time()
    for col in ("emitter_id", "address", "fingerprint", "channel", "n_samples", "vehicle"):
        assert np.array_equal(getattr(back, col), getattr(s, col)), col
