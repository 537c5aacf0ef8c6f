"""``uavloc localize``: CSV and .tlog in, estimates.csv / .geojson / .png out; bad rows named."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim_link.world import World
from uavloc_gcs.estimation.slots_csv import COLUMNS, dumps_slots_csv, loads_slots_csv
from uavloc_gcs.errors import FileFormatError
from uavloc_gcs.observations import SlotBatch
from uavloc_gcs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "examples" / "small.toml"


def uavloc(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "uavloc_gcs", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or ROOT, timeout=120)


@pytest.fixture(scope="module")
def flight():
    """Two vehicles over examples/small.toml, three static people; slots + world."""
    sc = load_scenario(SMALL)
    world = World.with_people(sc, [[120.0, 90.0], [330.0, 200.0], [420.0, 60.0]], seed=2)

    def lanes(vehicle, pts):
        t, x = [], []
        t0 = 0.0
        for a, b in zip(pts[:-1], pts[1:]):
            a, b = np.asarray(a, float), np.asarray(b, float)
            n = int(np.linalg.norm(b - a) / 20.0 / 0.05)
            f = np.arange(n) / n
            t.append(t0 + f * n * 0.05)
            x.append(a + np.outer(f, b - a))
            t0 += n * 0.05
        t, xy = np.concatenate(t), np.vstack(x)
        return world.hear_track(vehicle, t, np.column_stack([xy, np.full(len(t), 100.0)]))

    slots = SlotBatch.concat([lanes(1, [(0, 50), (500, 50), (500, 150), (0, 150)]),
                              lanes(2, [(0, 250), (500, 250), (250, 300), (250, 0)])])
    return sc, world, slots


def _read_estimates(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_shipped_example_localizes(tmp_path):
    r = uavloc("localize", "examples/slots_small.csv", "--scenario", "examples/small.toml", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert len(_read_estimates(tmp_path / "o" / "estimates.csv")) == 3


def test_csv_and_tlog_in_estimates_out(tmp_path, flight):
    """The same flight as a slot CSV and as a .tlog of UAVLOC_RSSI_BATCH messages gives the same
    estimates, each covering the truth, plus the GeoJSON and the picture."""
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.dialect.rssi import encode_rssi_batches
    from uavloc_gcs.link.tlog import TlogWriter

    sc, world, slots = flight
    epoch = 1_700_000_000.0
    tlog = tmp_path / "flight.tlog"
    w = TlogWriter(tlog)
    for v in (1, 2):
        codec = mavlink.MAVLink(None, srcSystem=v, srcComponent=191)
        for m in encode_rssi_batches(slots.take(slots.vehicle == v), sc.frame, epoch_unix_s=epoch):
            w.write(m.pack(codec), t_us=int(m.time_usec))
    w.close()
    src = tmp_path / "slots.csv"
    src.write_text(dumps_slots_csv(slots, sc.frame))
    a = uavloc("localize", tlog, "--scenario", SMALL, "--out", tmp_path / "a")
    b = uavloc("localize", src, "--scenario", SMALL, "--out", tmp_path / "b")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    out = tmp_path / "b"
    assert {p.name for p in out.iterdir()} == {"estimates.csv", "estimates.geojson", "estimates.png"}
    ra, rb = _read_estimates(tmp_path / "a" / "estimates.csv"), _read_estimates(out / "estimates.csv")
    assert list(rb[0])[:11] == ["emitter_id", "lat_deg", "lon_deg", "vel_east_m_s", "vel_north_m_s", "radius95_m",
                                "annulus_bound_m", "t_ref_s", "ambiguous", "mirror_lat_deg", "mirror_lon_deg"]
    assert {int(r["emitter_id"]) for r in rb} == set(world.emitter_ids.tolist())
    assert [r["emitter_id"] for r in ra] == [r["emitter_id"] for r in rb]
    for x, y in zip(ra, rb):
        truth = world.positions(0.0)[world.index_of(int(y["emitter_id"]))]
        ex, nx = sc.frame.to_local(float(x["lat_deg"]), float(x["lon_deg"]))
        ey, ny = sc.frame.to_local(float(y["lat_deg"]), float(y["lon_deg"]))
        assert np.hypot(ey - truth[0], ny - truth[1]) <= float(y["radius95_m"])
        assert np.hypot(ex - ey, nx - ny) < 1.0  # the wire's cm/ms quantisation only
        assert float(x["radius95_m"]) == pytest.approx(float(y["radius95_m"]), rel=0.05)
    gj = json.loads((out / "estimates.geojson").read_text())
    kinds = [f["properties"]["kind"] for f in gj["features"]]
    assert kinds.count("estimate") == 3 and kinds.count("track") == 2
    assert (out / "estimates.png").read_bytes()[:4] == b"\x89PNG"
    assert str(world.emitter_ids[0]) in b.stdout


def test_slots_heard_below_the_airborne_floor_are_left_out_and_counted(tmp_path, flight):
    """As in the daemon: a vehicle climbing out or landing hears phones too, but those slots are
    not estimated from (estimation.airborne_slots below heights.airborne_floor_m: half the survey
    altitude, 50 m, when the scenario asks no lower look height); the table's title says how many."""
    sc, world, slots = flight
    low = slots.take(np.arange(0, len(slots), 7))
    low = SlotBatch.from_columns(low.t_s + 1000.0, low.vehicle, low.xyz_m * [1.0, 1.0, 0.2], low.emitter_id,
                                 low.rssi_dbm - 30.0, low.n_samples)  # 20 m up, and far "louder"
    both, alone = tmp_path / "both.csv", tmp_path / "alone.csv"
    both.write_text(dumps_slots_csv(SlotBatch.concat([slots, low]), sc.frame))
    alone.write_text(dumps_slots_csv(slots, sc.frame))
    a = uavloc("localize", both, "--scenario", SMALL, "--out", tmp_path / "a")
    b = uavloc("localize", alone, "--scenario", SMALL, "--out", tmp_path / "b")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    assert f"{len(slots)} slots, 3 emitter(s) ({len(low)} slots heard below 50 m, taking off or landing, " \
           "not used)" in a.stdout
    assert "not used" not in b.stdout
    ra, rb = _read_estimates(tmp_path / "a" / "estimates.csv"), _read_estimates(tmp_path / "b" / "estimates.csv")
    assert [(r["lat_deg"], r["radius95_m"]) for r in ra] == [(r["lat_deg"], r["radius95_m"]) for r in rb]


GOOD = ",".join(COLUMNS) + "\n1.0,1,47.3977,8.5456,100,42,-80.5,10\n"


@pytest.mark.parametrize("line, field", [
    ("1.0,1,47.3977,8.5456,100,42,-80.5,ten", "n_samples"),
    ("1.0,1,97.3977,8.5456,100,42,-80.5,10", "lat_deg"),
    ("1.0,1,47.3977,8.5456,100,42,nan,10", "rssi_dbm"),
    ("1.0,1,47.3977,8.5456,100,42,-80.5,0", "n_samples"),
    ("1.0,x,47.3977,8.5456,100,42,-80.5,10", "vehicle_id"),
])
def test_malformed_rows_are_named_by_line_and_field(line, field):
    with pytest.raises(FileFormatError, match=f"bad.csv, line 3, field '{field}'"):
        loads_slots_csv(GOOD + line + "\n", load_scenario(SMALL).frame, path="bad.csv")


def test_cli_reports_a_bad_row_in_one_sentence_and_writes_nothing(tmp_path):
    src = tmp_path / "bad.csv"
    src.write_text(GOOD + "1.0,1,47.3977,8.5456,100,42,-80.5,ten\n")
    out = tmp_path / "out"
    r = uavloc("localize", src, "--scenario", SMALL, "--out", out)
    assert r.returncode == 2
    assert "bad.csv, line 3, field 'n_samples'" in r.stderr
    assert r.stderr.count("\n") == 1  # one sentence, no traceback
    assert not out.exists()


def test_header_and_field_count_errors():
    frame = load_scenario(SMALL).frame
    with pytest.raises(FileFormatError, match="line 1.*header"):
        loads_slots_csv("t,vehicle\n", frame, path="x.csv")
    with pytest.raises(FileFormatError, match="line 3.*8 comma-separated fields, got 3"):
        loads_slots_csv(",".join(COLUMNS) + "\n\n1,2,3\n", frame, path="x.csv")
    with pytest.raises(FileFormatError, match="empty file"):
        loads_slots_csv("# only a comment\n", frame)
    assert len(loads_slots_csv(",".join(COLUMNS) + "\n", frame)) == 0


def test_csv_round_trip_keeps_the_slots(flight):
    sc, _, slots = flight
    back = loads_slots_csv(dumps_slots_csv(slots, sc.frame), sc.frame)
    s = slots.sorted_by_time()
    assert np.array_equal(back.emitter_id, s.emitter_id) and np.array_equal(back.vehicle, s.vehicle)
    assert np.allclose(back.xyz_m, s.xyz_m, atol=0.01) and np.allclose(back.rssi_dbm, s.rssi_dbm, atol=0.005)


SENSOR_HEADER = ",".join(COLUMNS) + ",address,fingerprint,channel\n"


def test_csv_with_the_sensor_columns_reads_addresses_in_both_spellings_and_defaults_empty_cells():
    frame = load_scenario(SMALL).frame
    text = (SENSOR_HEADER
            + "1.0,1,47.3977,8.5456,100,42,-80.5,10,da:0A:1b:2c:3d:4e,3735928559,6\n"
            + "1.1,1,47.3977,8.5456,100,43,-80.5,3,FFFFFFFFFFFF,0xdeadbeef,11\n"
            + "1.2,1,47.3977,8.5456,100,44,-80.5,3,02-00-00-00-00-01,,\n"
            + "1.3,1,47.3977,8.5456,100,45,-80.5,3,,,\n")
    b = loads_slots_csv(text, frame)
    assert b.address.tolist() == [0xDA0A1B2C3D4E, 0xFFFFFFFFFFFF, 0x020000000001, 45]
    assert b.fingerprint.tolist() == [0xDEADBEEF, 0xDEADBEEF, 0, 0] and b.channel.tolist() == [6, 11, 0, 0]
    assert b.emitter_id.tolist() == [42, 43, 44, 45]
    # the optional columns in another order, or only some of them
    some = loads_slots_csv(",".join(COLUMNS) + ",channel,address\n1.0,1,47.3977,8.5456,100,42,-80.5,10,1,"
                           "0a0b0c0d0e0f\n", frame)
    assert some.address.tolist() == [0x0A0B0C0D0E0F] and some.channel.tolist() == [1]
    assert some.fingerprint.tolist() == [0]
    # an old CSV: address = emitter id, fingerprint and channel unknown
    old = loads_slots_csv(GOOD, frame)
    assert old.address.tolist() == [42] and old.fingerprint.tolist() == [0] and old.channel.tolist() == [0]


@pytest.mark.parametrize("cell, field", [
    ("da:0a:1b:2c:3d,1,6", "address"),  # five octets
    ("da0a1b2c3d4e5f,1,6", "address"),  # 14 digits
    ("da:0a:1b:2c:3d:4g,1,6", "address"),
    ("da0a1b2c3d4e,x,6", "fingerprint"),
    ("da0a1b2c3d4e,1,256", "channel"),
])
def test_malformed_sensor_cells_are_named(cell, field):
    text = SENSOR_HEADER + "1.0,1,47.3977,8.5456,100,42,-80.5,10," + cell + "\n"
    with pytest.raises(FileFormatError, match=f"bad.csv, line 2, field '{field}'"):
        loads_slots_csv(text, load_scenario(SMALL).frame, path="bad.csv")


def test_header_with_unknown_or_repeated_optional_columns_is_refused():
    frame = load_scenario(SMALL).frame
    for extra in (",mac", ",channel,channel", ",address,fingerprint,channel,x"):
        with pytest.raises(FileFormatError, match="line 1.*optionally followed by"):
            loads_slots_csv(",".join(COLUMNS) + extra + "\n", frame, path="x.csv")


def _sensor_slots(slots, seed=3):
    """The flight as a Wi-Fi sensor reports it: each person under one 48-bit address (high bits
    set), a 32-bit fingerprint and a channel per slot."""
    rng = np.random.default_rng(seed)
    ids = np.unique(slots.emitter_id)
    addr = dict(zip(ids.tolist(), (0xDA0000000000 + rng.integers(0, 2**40, size=len(ids))).tolist()))
    address = np.array([addr[int(e)] for e in slots.emitter_id], dtype=np.int64)
    return SlotBatch.from_columns(slots.t_s, slots.vehicle, slots.xyz_m, address, slots.rssi_dbm, slots.n_samples,
                                  address=address, fingerprint=rng.integers(1, 2**32, size=len(slots)),
                                  channel=rng.choice([1, 6, 11], size=len(slots)))


def test_csv_round_trip_keeps_the_sensor_columns(flight):
    sc, _, slots = flight
    sensor = _sensor_slots(slots)
    text = dumps_slots_csv(sensor, sc.frame)
    assert text.splitlines()[0] == SENSOR_HEADER.strip() and ":" in text.splitlines()[1]
    back, s = loads_slots_csv(text, sc.frame), sensor.sorted_by_time()
    for col in ("emitter_id", "address", "fingerprint", "channel", "n_samples"):
        assert np.array_equal(getattr(back, col), getattr(s, col)), col
    # slots without sensor columns are written in the old 8-column format
    assert dumps_slots_csv(slots, sc.frame).splitlines()[0] == ",".join(COLUMNS)


def test_tlog_of_new_and_old_messages_replays_every_column(tmp_path, flight):
    """A .tlog holding UAVLOC_RSSI_BATCH2 (a new companion) and UAVLOC_RSSI_BATCH (an old one)
    gives the slots of both, the new ones with their address, fingerprint and channel."""
    from uavloc_gcs.cli.localize import load_slots
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.dialect.rssi import BATCH, BATCH2, encode_rssi_batches
    from uavloc_gcs.link.tlog import TlogWriter

    sc, _, slots = flight
    sensor = _sensor_slots(slots.take(slots.vehicle == 1))
    old = slots.take(slots.vehicle == 2)
    epoch = 1_700_000_000.0
    tlog = tmp_path / "mixed.tlog"
    w = TlogWriter(tlog)
    for v, part, kind in ((1, sensor, BATCH2), (2, old, BATCH)):
        codec = mavlink.MAVLink(None, srcSystem=v, srcComponent=191)
        for m in encode_rssi_batches(part, sc.frame, epoch_unix_s=epoch, message=kind):
            assert m.get_type() == kind
            w.write(m.pack(codec), t_us=int(m.time_usec))
    w.close()
    back = load_slots(tlog, sc)
    b1, b2 = back.take(back.vehicle == 1).sorted_by_time(), back.take(back.vehicle == 2).sorted_by_time()
    s1, s2 = sensor.sorted_by_time(), old.sorted_by_time()
    for col in ("address", "fingerprint", "channel", "n_samples"):
        assert np.array_equal(getattr(b1, col), getattr(s1, col)), col
    assert np.array_equal(b1.emitter_id, s1.address)
    assert np.array_equal(b2.address, s2.emitter_id) and not b2.fingerprint.any() and not b2.channel.any()
    assert np.allclose(b1.t_s - b1.t_s[0], s1.t_s - s1.t_s[0], atol=1e-6)
    # and the CLI localizes from it (three people: one under its addresses, two under old ids)
    r = uavloc("localize", tlog, "--scenario", SMALL, "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert len(_read_estimates(tmp_path / "o" / "estimates.csv")) >= 3


def test_missing_input_file(tmp_path, capsys):
    from uavloc_gcs.cli import main

    assert main(["localize", str(tmp_path / "nope.csv"), "--scenario", str(SMALL), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "nope.csv" in err and "not found" in err and not (tmp_path / "o").exists()


# ---------------------------------------------------------------------------------------------
# issue 40 item 4: inputs with nothing to localize were exit 0 with empty estimates; slots from
# another place were taken silently

def _localize_inproc(capsys, *args):
    from uavloc_gcs.cli import main

    code = main([str(a) for a in ["localize", *args]])
    out = capsys.readouterr()
    return code, out.out, out.err


def _tlog_of_heartbeats(path):
    from uavloc_gcs.dialect import mavlink
    from uavloc_gcs.link.tlog import TlogWriter

    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    w = TlogWriter(path)
    for k in range(3):
        w.write(codec.heartbeat_encode(2, 3, 0, 0, 0).pack(codec), t_us=1_700_000_000_000_000 + k * 1_000_000)
    w.close()


@pytest.mark.parametrize("name, make, needle", [
    ("header.csv", lambda p: p.write_text(",".join(COLUMNS) + "\n"), "has the header but no slots: nothing to localize"),
    ("empty.tlog", lambda p: p.write_bytes(b""), "is empty: nothing to localize"),
    ("beats.tlog", _tlog_of_heartbeats, "holds 3 MAVLink message(s) but no UAVLOC_RSSI_BATCH2 or UAVLOC_RSSI_BATCH"),
    ("folder.tlog", lambda p: p.mkdir(), "is a directory"),
])
def test_an_input_with_nothing_to_localize_is_refused(tmp_path, capsys, name, make, needle):
    make(tmp_path / name)
    code, out, err = _localize_inproc(capsys, tmp_path / name, "--scenario", SMALL, "--out", tmp_path / "o")
    assert code == 2, (out, err)
    line, = err.strip().splitlines()
    assert name in line and needle in line, line
    assert not (tmp_path / "o").exists()


def test_slots_all_heard_on_the_ground_are_refused(tmp_path, capsys, flight):
    sc, _, slots = flight
    low = SlotBatch.from_columns(slots.t_s, slots.vehicle, slots.xyz_m * [1.0, 1.0, 0.1], slots.emitter_id,
                                 slots.rssi_dbm, slots.n_samples)  # 10 m up: taking off
    (tmp_path / "low.csv").write_text(dumps_slots_csv(low, sc.frame))
    code, out, err = _localize_inproc(capsys, tmp_path / "low.csv", "--scenario", SMALL, "--out", tmp_path / "o")
    assert code == 2
    assert f"all {len(slots)} slots were heard below 50 m above the ground (taking off, landing or on the ground; " \
           "the scenario's scan flies at 100 m): nothing to localize" in err, err
    assert not (tmp_path / "o").exists()


def test_slots_far_from_the_scenarios_area_warn_how_far(tmp_path, capsys, flight):
    """examples/small.toml is at 47.4 N; the same flight moved 6.3 degrees north (700 km)."""
    sc, _, slots = flight
    text = dumps_slots_csv(slots, sc.frame)
    moved = loads_slots_csv(text, load_scenario(SMALL).frame)
    from uavloc_gcs.geo import LocalFrame

    north = LocalFrame(sc.launch_latlon_deg[0] + 6.3, sc.launch_latlon_deg[1])
    (tmp_path / "far.csv").write_text(dumps_slots_csv(moved, north))  # the same local track, 700 km north
    code, out, err = _localize_inproc(capsys, tmp_path / "far.csv", "--scenario", SMALL, "--out", tmp_path / "o")
    assert code == 0, err
    line, = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert f"{len(slots)} of {len(slots)} slots in far.csv lie 70" in line and " km from the area of " in line, line
    assert "small.toml (more than 5 km)" in line
    km = float(line.split(" lie ")[1].split(" ")[0])
    assert abs(km - 6.3 * 111.2) < 15, line  # a degree of latitude is 111.2 km
    # the same flight where it was flown: no warning
    (tmp_path / "near.csv").write_text(text)
    code, out, err = _localize_inproc(capsys, tmp_path / "near.csv", "--scenario", SMALL, "--out", tmp_path / "n")
    assert code == 0 and "warning" not in err


def test_the_shipped_slots_are_found_by_name_from_any_directory(tmp_path):
    r = uavloc("localize", "slots_small.csv", "--scenario", "small", "--out", "o", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert len(_read_estimates(tmp_path / "o" / "estimates.csv")) == 3
