"""A real Bluetooth LE capture (Ubertooth, link type 256, from crackle's tests; BSD licence, see
``real/README.md``), frame by frame against tshark's dissection kept beside it, and against tshark
itself when it is installed."""

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from uavloc_gcs.sense import parse_capture
from uavloc_gcs.sense.ble import rf_to_channel_index

REAL = Path(__file__).parent / "real"
CAPTURE = REAL / "le_secure_connections.pcapng"
FIELDS = ["frame.number", "frame.time_epoch", "btle.advertising_header.pdu_type", "btle.advertising_address",
          "btle.advertising_header.randomized_tx", "btle_rf.signal_dbm", "btle_rf.channel", "btle_rf.flags"]
ADVERTISER_PDUS = {0, 1, 2, 4, 6}  # ADV_IND, ADV_DIRECT_IND, ADV_NONCONN_IND, SCAN_RSP, ADV_SCAN_IND


def _rows(lines: list[str]) -> list[list[str]]:
    return [line.split("\t") for line in lines if line and not line.startswith("#")]


def _check(rows: list[list[str]]) -> None:
    frames, skips = parse_capture(CAPTURE)
    adv = [r for r in rows if r[2] and int(r[2], 16) in ADVERTISER_PDUS]
    assert len(frames) == len(adv) == 42  # 40 ADV_IND + 2 SCAN_RSP
    for k, r in enumerate(adv):
        assert frames.t_s[k] == pytest.approx(float(r[1]), abs=1e-6)
        assert frames.address[k] == int(r[3].replace(":", ""), 16)
        assert frames.random[k] == int(r[4])
        assert frames.rssi_dbm[k] == int(r[5])
        assert frames.channel[k] == rf_to_channel_index(int(r[6]))
        assert frames.pdu[k] == int(r[2], 16)
    assert set(frames.radio.tolist()) == {1} and set(frames.channel.tolist()) == {37}
    # every other frame is counted: the SCAN_REQ, the CONNECT_IND and the data-channel PDUs
    assert skips.reasons == {"not_advertising": len(rows) - len(adv)} and skips.malformed == 0
    assert skips.read.records == len(rows) == 303


def test_real_ubertooth_capture_matches_tsharks_dissection_kept_beside_it():
    _check(_rows((REAL / "le_secure_connections.tshark.tsv").read_text().splitlines()))


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
def test_real_ubertooth_capture_matches_tshark_run_now():
    cmd = ["tshark", "-r", str(CAPTURE), "-T", "fields"] + [a for f in FIELDS for a in ("-e", f)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, timeout=120).stdout
    _check(_rows(out.splitlines()))


def test_signal_flags_of_the_real_capture_say_valid():
    """The pseudo-header's flags (0x0037 on advertising frames: dewhitened, signal valid, ...) are
    what makes the RSSI usable; a copy with the signal-valid bit cleared reads as no_signal."""
    from uavloc_gcs.sense import parse_capture_bytes

    buf = bytearray(CAPTURE.read_bytes())
    flags = [r[7] for r in _rows((REAL / "le_secure_connections.tshark.tsv").read_text().splitlines())]
    assert {"0x0037", "0x0027", "0x0023"} >= set(flags)
    cleared = bytes(buf).replace(b"\x37\x00\xd6\xbe\x89\x8e", b"\x35\x00\xd6\xbe\x89\x8e")
    frames, skips = parse_capture_bytes(cleared)
    assert len(frames) == 0 and skips.reasons["no_signal"] == 42
    assert np.all(skips.read.records == 303)
