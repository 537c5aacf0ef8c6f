"""The checked-in dialect module must be what mavgen makes of uavloc.xml today.

Compared message by message (id, name, CRC extra, field names, wire order, types, array lengths)
and enum by enum, not as text: the generator's formatting may differ between pymavlink versions,
the wire definitions must not.
"""

from __future__ import annotations

import importlib.util
import sys

import pytest

from uavloc_gcs.dialect import RSSI_BATCH2_ID, RSSI_BATCH_ID, RSSI_BATCH_MAX_ENTRIES, generate, mavlink


def _definitions(mod) -> dict:
    out = {}
    for msg_id, cls in mod.mavlink_map.items():
        out[msg_id] = (
            cls.msgname, cls.crc_extra, tuple(cls.fieldnames), tuple(cls.ordered_fieldnames),
            tuple(cls.fieldtypes), tuple(cls.array_lengths), cls.native_format.decode(),
        )
    return out


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    path = tmp_path_factory.mktemp("gen") / "regen_uavloc.py"
    generate.generate(path)
    spec = importlib.util.spec_from_file_location("regen_uavloc", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["regen_uavloc"] = mod
    try:
        spec.loader.exec_module(mod)
    finally:
        sys.modules.pop("regen_uavloc", None)
    return mod


def test_every_message_definition_matches_the_xml(regenerated):
    old, new = _definitions(mavlink), _definitions(regenerated)
    assert set(old) == set(new), f"message ids differ: {sorted(set(old) ^ set(new))}"
    diff = [mid for mid in old if old[mid] != new[mid]]
    assert not diff, f"definitions differ for ids {diff[:10]}; run python -m uavloc_gcs.dialect.generate"


def test_enums_match_the_xml(regenerated):
    old = {k: sorted((v, e.name) for v, e in d.items()) for k, d in mavlink.enums.items()}
    new = {k: sorted((v, e.name) for v, e in d.items()) for k, d in regenerated.enums.items()}
    assert old == new


def test_rssi_message_is_outside_allocated_ranges_and_has_the_documented_shape():
    cls = mavlink.mavlink_map[RSSI_BATCH_ID]
    assert cls.msgname == "UAVLOC_RSSI_BATCH"
    allocated = [(0, 255), (300, 10000), (10001, 10999), (11000, 11999), (8000, 8999), (42000, 42999),
                 (50000, 50099), (51000, 51999), (52000, 52099), (52100, 52499), (52500, 52619),
                 (53000, 53999), (60000, 60099)]
    assert not any(lo <= RSSI_BATCH_ID <= hi for lo, hi in allocated)
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))  # wire order
    assert {lengths[n] for n in ("dt_ms", "emitter_id", "rssi_cdbm", "n_samples")} == {RSSI_BATCH_MAX_ENTRIES}
    assert cls.unpacker.size == 125  # payload bytes; documented in RSSI_DIALECT.md


def test_rssi_batch2_fits_mavlink2_and_has_the_documented_shape():
    cls = mavlink.mavlink_map[RSSI_BATCH2_ID]
    assert cls.msgname == "UAVLOC_RSSI_BATCH2" and RSSI_BATCH2_ID == RSSI_BATCH_ID + 1
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
    per_entry = ("dt_ms", "addr_lo", "addr_hi", "fingerprint", "channel", "radio", "n_frames", "rssi_cdbm")
    assert {lengths[n] for n in per_entry} == {RSSI_BATCH_MAX_ENTRIES}
    types = dict(zip(cls.fieldnames, cls.fieldtypes))
    assert (types["addr_lo"], types["addr_hi"], types["fingerprint"], types["channel"], types["radio"]) == (
        "uint32_t", "uint16_t", "uint32_t", "uint8_t", "uint8_t")
    assert cls.unpacker.size == 221 <= 255  # payload bytes; documented in RSSI_DIALECT.md
    # the columns a sensor may not know come last on the wire (extensions), so zeros there are
    # trimmed: the radio last, so that a Wi-Fi-only message costs what it did before the field
    assert list(cls.ordered_fieldnames[-4:]) == ["addr_hi", "channel", "fingerprint", "radio"]
    assert list(cls.ordered_fieldnames[:-4]) == list(mavlink.mavlink_map[RSSI_BATCH_ID].ordered_fieldnames[:4]) + [
        "addr_lo", "vx", "vy", "vz", "slot_us", "rssi_cdbm", "count", "dt_ms", "n_frames"]
    # the old message keeps its definition, so old logs and companions decode
    assert mavlink.mavlink_map[RSSI_BATCH_ID].crc_extra == 221


def test_xml_parses_to_the_same_crc_extra_as_the_module():
    from pymavlink.generator import mavparse

    xml = mavparse.MAVXML(str(generate.XML), mavparse.PROTOCOL_2_0)
    (msg,) = [m for m in xml.message if m.id == RSSI_BATCH_ID]
    assert msg.crc_extra == mavlink.mavlink_map[RSSI_BATCH_ID].crc_extra
    assert [f.name for f in msg.fields] == list(mavlink.mavlink_map[RSSI_BATCH_ID].fieldnames)
