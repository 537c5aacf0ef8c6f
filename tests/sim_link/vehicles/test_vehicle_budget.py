"""The paper scenario's telemetry fits a 57.6 kbit/s radio with margin (SPEC §4)."""

from __future__ import annotations

from uavloc_gcs.scenario import load_scenario
from sim_link.vehicles.budget import RADIO_BYTES_S, measure, report


def test_paper_scan_telemetry_fits_a_57k6_radio_with_margin():
    sc = load_scenario("examples/paper.toml")
    (b,) = measure(sc, vehicles=[2], signed=True)  # the vehicle that hears the most people
    assert 150 < b.flight_s < 400
    assert b.bytes_by_type["UAVLOC_RSSI_BATCH2"] > 0 and b.rssi_entries / b.rssi_messages > 8
    assert b.mean_bytes_s < 0.25 * RADIO_BYTES_S
    assert b.peak_bytes_s < 0.6 * RADIO_BYTES_S
    # position at 5 Hz: 28-byte payload + 12 bytes of MAVLink 2 framing (+13 signature)
    assert abs(b.bytes_by_type["GLOBAL_POSITION_INT"] - 5 * (28 + 12 + 13)) < 10
    assert "uav2" in report([b])


def test_rssi_beside_the_autopilot_splits_the_bytes_between_two_links():
    sc = load_scenario("examples/paper.toml")
    (b,) = measure(sc, vehicles=[2])
    ap, comp = b.mean_by_component[1], b.mean_by_component[191]
    assert abs(ap + comp - b.mean_bytes_s) < 1e-6 * b.mean_bytes_s
    assert comp >= b.bytes_by_type["UAVLOC_RSSI_BATCH2"] > 0  # the RSSI (+ the companion's heartbeat)
    assert b.peak_by_component[1] < b.peak_bytes_s and b.peak_by_component[191] < b.peak_bytes_s
    text = report([b], "beside")
    assert "RSSI link" in text and "uav2" in text


def test_the_new_message_costs_the_old_ones_bytes_in_the_paper_world():
    """The paper's world has no fingerprint, channel or address beyond 32 bits: UAVLOC_RSSI_BATCH2's
    extension fields are all zero and trimmed on the wire, so it costs what UAVLOC_RSSI_BATCH did."""
    sc = load_scenario("examples/paper.toml")
    (new,) = measure(sc, vehicles=[3])
    (old,) = measure(sc, vehicles=[3], message="UAVLOC_RSSI_BATCH")
    assert new.rssi_entries == old.rssi_entries > 0 and new.rssi_messages == old.rssi_messages
    assert new.bytes_by_type["UAVLOC_RSSI_BATCH2"] == old.bytes_by_type["UAVLOC_RSSI_BATCH"]
    assert new.peak_bytes_s == old.peak_bytes_s
