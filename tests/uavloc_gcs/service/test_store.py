"""The store: batched commits at a bounded delay, crash survival, reload for resume."""

import math
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from uavloc_gcs.errors import ConfigError
from uavloc_gcs.mission import WireItem
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.service.store import EstimateRow, Store, StoreReader, TelemetryRow


def _batch(n, t0=0.0, vehicle=1):
    rng = np.random.default_rng(n)
    return SlotBatch.from_columns(
        t0 + np.arange(n) * 0.025, np.full(n, vehicle), rng.normal(size=(n, 3)),
        rng.integers(0, 10, n), rng.normal(-80, 5, n), np.full(n, 10))


def test_round_trip_of_every_table(tmp_path):
    path = tmp_path / "run.sqlite"
    b = _batch(50)
    items = [WireItem(0, 0, 16, 1, 1, 0.0, 0.0, 0.0, math.nan, 426250000, 132830000, 0.0),
             WireItem(1, 2, 20, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0)]
    with Store(path) as st:
        st.add_slots(b)
        st.add_telemetry([TelemetryRow(1.0, 1, 42.6, 13.2, 100.0, 97.5, "AUTO", 3, False)])
        st.add_estimates([EstimateRow(2.0, 7, 10.0, 20.0, 0.5, -0.5, 8.0, 12.0, True, False, "")])
        st.add_plan(3.0, {"tasks": [[1, [[0, 0], [10, 10]]]]})
        st.add_mission(3.0, 1, "replan", items)
        st.add_event("lost", "vehicle 2 silent for 5 s", t_s=4.0, vehicle=2)
        st.set_meta("scenario", {"name": "paper"})
    with StoreReader(path) as rd:
        got = rd.slots()
        np.testing.assert_array_equal(got.t_s, b.t_s)
        np.testing.assert_array_equal(got.emitter_id, b.emitter_id)
        np.testing.assert_allclose(got.xyz_m, b.xyz_m)
        assert rd.tracks()[1].tolist() == [[42.6, 13.2]]
        assert rd.latest_estimates()[7].located
        assert rd.latest_plan() == {"tasks": [[1, [[0, 0], [10, 10]]]]}
        purpose, wire = rd.latest_missions()[1]
        assert purpose == "replan" and all(a.same_as(b) for a, b in zip(wire, items))
        assert rd.events("lost")[0].vehicle == 2
        assert rd.meta() == {"scenario": {"name": "paper"}}


def test_slots_keep_address_fingerprint_and_channel(tmp_path):
    path = tmp_path / "run.sqlite"
    b = _batch(6)
    address = np.array([0xFFFFFFFFFFFF, 0x020000000001, 0xDA0000000000, 5, 6, 2**47 + 3])
    sensor = SlotBatch.from_columns(b.t_s, b.vehicle, b.xyz_m, address, b.rssi_dbm, b.n_samples, address=address,
                                    fingerprint=[2**32 - 1, 0, 7, 7, 8, 9], channel=[1, 6, 11, 0, 165, 1])
    with Store(path) as st:
        st.add_slots(sensor)
        st.add_slots(b)  # defaults: address = emitter id, fingerprint 0, channel 0
    with StoreReader(path) as rd:
        got = rd.slots()
    want = SlotBatch.concat([sensor, b])
    for col in ("emitter_id", "address", "fingerprint", "channel", "n_samples", "vehicle"):
        np.testing.assert_array_equal(getattr(got, col), getattr(want, col), err_msg=col)
    assert got.address.dtype == np.int64


_OLD_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE slots (
    t_s REAL NOT NULL, vehicle INTEGER NOT NULL, x_m REAL NOT NULL, y_m REAL NOT NULL,
    z_m REAL NOT NULL, emitter_id INTEGER NOT NULL, rssi_dbm REAL NOT NULL,
    n_samples INTEGER NOT NULL);
INSERT INTO slots VALUES (1.5, 2, 10.0, 20.0, 100.0, 4000000000, -75.5, 10);
INSERT INTO slots VALUES (1.525, 2, 11.0, 20.0, 100.0, 17, -80.0, 3);
"""


def _old_store(path):
    import sqlite3

    conn = sqlite3.connect(path)
    conn.executescript(_OLD_SCHEMA)
    conn.commit()
    conn.close()


def test_a_store_of_the_old_schema_reads_and_migrates(tmp_path):
    path = tmp_path / "old.sqlite"
    _old_store(path)
    with StoreReader(path) as rd:  # read-only: not migrated, defaults read
        got = rd.slots()
        assert got.emitter_id.tolist() == [4000000000, 17] and got.address.tolist() == [4000000000, 17]
        assert got.fingerprint.tolist() == [0, 0] and got.channel.tolist() == [0, 0]
        assert got.n_samples.tolist() == [10, 3] and got.vehicle.tolist() == [2, 2]
    with Store(path) as st:  # the daemon resuming on it: columns added, old rows kept
        st.add_slots(SlotBatch.from_columns([2.0], [2], [[0, 0, 100]], [0xDA0000000001], [-70.0], [4],
                                            fingerprint=[99], channel=[6]))
    with StoreReader(path) as rd:
        got = rd.slots()
        assert got.address.tolist() == [4000000000, 17, 0xDA0000000001]
        assert got.emitter_id.tolist() == [4000000000, 17, 0xDA0000000001]
        assert got.fingerprint.tolist() == [0, 0, 99] and got.channel.tolist() == [0, 0, 6]
        assert rd.slot_count() == 3


def test_commits_within_the_bounded_delay_without_close(tmp_path):
    path = tmp_path / "run.sqlite"
    st = Store(path, commit_interval_s=0.05)
    try:
        st.add_slots(_batch(10))
        time.sleep(0.3)
        with StoreReader(path) as rd:  # another connection sees it: it is committed
            assert rd.slot_count() == 10
        assert st.stats().max_commit_delay_s < 0.25
    finally:
        st.close()


def test_data_survive_kill_9_except_the_last_commit_window(tmp_path):
    path = tmp_path / "run.sqlite"
    code = textwrap.dedent(f"""
        import sys, time, numpy as np
        from uavloc_gcs.observations import SlotBatch
        from uavloc_gcs.service.store import Store
        st = Store({str(path)!r}, commit_interval_s=0.05)
        i = 0
        while True:
            st.add_slots(SlotBatch.from_columns([i * 0.025], [1], [[0, 0, 100]], [3], [-70.0], [10]))
            if i == 200:
                print("ready", flush=True)
            i += 1
            time.sleep(0.0005)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(0.3)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    with StoreReader(path) as rd:
        t = rd.slots().t_s
    assert len(t) > 200
    np.testing.assert_allclose(np.diff(t), 0.025)  # a prefix, nothing torn or out of order


def test_a_file_that_is_not_a_database_is_a_clear_error(tmp_path):
    bad = tmp_path / "x.sqlite"
    bad.write_text("hello, this is not sqlite" * 100)
    with pytest.raises(ConfigError, match="x.sqlite"):
        Store(bad)
