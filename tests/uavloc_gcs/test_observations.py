import numpy as np
import pytest

from uavloc_gcs.observations import SlotBatch


def _batch(n, emitter):
    return SlotBatch.from_columns(np.arange(n) * 0.025, [1] * n, np.zeros((n, 3)), [emitter] * n,
                                  [-80.0] * n, [10] * n)


def test_concat_select_and_sort():
    b = SlotBatch.concat([_batch(3, 7), SlotBatch.empty(), _batch(2, 9)])
    assert len(b) == 5
    assert list(b.emitters()) == [7, 9]
    assert len(b.for_emitter(9)) == 2
    assert np.all(np.diff(b.sorted_by_time().t_s) >= 0)


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match="xyz_m"):
        SlotBatch(np.zeros(2), np.zeros(2, int), np.zeros((3, 3)), np.zeros(2, int), np.zeros(2), np.ones(2, int))

