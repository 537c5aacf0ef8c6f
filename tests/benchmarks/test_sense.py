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
