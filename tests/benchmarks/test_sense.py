"""``uavloc bench sense``: its parsers read the same fields as the generator's truth (speed is the
benchmark's business, not a test's)."""

import numpy as np
import pytest

from benchmarks import sense
from uavloc_gcs.sense.synth import synthetic_capture


def test_the_three_parsers_agree_with_the_truth(capsys):
    pytest.importorskip("dpkt")
    pytest.importorskip("scapy")
    buf, truth = synthetic_capture(400, rng=np.random.default_rng(4))
    assert sense._agree(sense._uavloc(buf), truth, 400) == 400
    assert sense._agree(sense._dpkt(buf), truth, 400) == 400
    assert sense._agree(sense._scapy(buf, 100), truth, 100) == 100
    sense._radio_budget(buf)
    out = capsys.readouterr().out
    assert "UAVLOC_RSSI_BATCH2/s" in out and "% of a 57.6 kbit/s radio" in out


def test_the_ble_parsers_agree_with_the_truth_and_the_radio_share_is_reported(capsys):
    pytest.importorskip("scapy")
    from uavloc_gcs.sense.synth_ble import synthetic_ble_capture

    buf, truth = synthetic_ble_capture(400, rng=np.random.default_rng(4))
    assert sense._agree(sense._uavloc(buf), truth, 400) == 400
    assert sense._agree(sense._scapy_ble(buf, 100), truth, 100) == 100
    share = sense._radio_budget(buf)
    assert 0 < share < 1 and "% of a 57.6 kbit/s radio" in capsys.readouterr().out
