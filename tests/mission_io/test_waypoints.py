"""QGC WPL 110 .waypoints: layout, full precision, lossless round trips, malformed input."""

import math

import pytest
from hypothesis import given, settings

from mission_io import waypoints as W
from uavloc_gcs import mission as M
from uavloc_gcs.errors import FileFormatError

from .strategies import plans, plans_equal


def _mission():
    return M.flight_mission([(47.123456789012, 8.987654321098), (47.2, 8.2)], alt_m=80.0, speed_m_s=12.5,
                            autopilot="ardupilot", home_latlon_deg=(47.0, 8.0), home_alt_amsl_m=432.5)


def test_layout_home_on_line_0_and_12_tab_columns():
    lines = W.dumps(_mission()).splitlines()
    assert lines[0] == "QGC WPL 110"
    assert lines[1] == "0\t1\t0\t16\t0\t0\t0\t0\t47\t8\t432.5\t1"
    assert all(len(line.split("\t")) == 12 for line in lines[1:])
    assert [line.split("\t")[0] for line in lines[1:]] == [str(k) for k in range(len(lines) - 1)]
    assert lines[2].split("\t")[1:4] == ["0", "3", "22"]
    assert lines[3].split("\t")[1:8] == ["0", "2", "178", "1", "12.5", "-1", "0"]
    wp = lines[4].split("\t")
    assert wp[3:12] == ["16", "0", "0", "0", "nan", "47.123456789012", "8.987654321098", "80", "1"]


def test_full_precision_not_percent_f():
    text = W.dumps(_mission())
    back = W.loads(text)
    assert back.items[2].lat_deg == 47.123456789012  # %f would keep 47.123457 (~5 cm off)
    assert "e-" not in text and "e+" not in text


@settings(max_examples=150, deadline=None)
@given(plans(home_alt_finite=True, extras=False))
def test_round_trip_is_exact(plan):
    back = W.loads(W.dumps(plan), autopilot=plan.autopilot)
    assert plans_equal(back, plan)
    assert W.dumps(back) == W.dumps(plan)


def test_unknown_home_reads_back_as_unknown():
    plan = M.MissionPlan((M.return_to_launch(),))
    text = W.dumps(plan)
    assert text.splitlines()[1] == "0\t1\t0\t16\t0\t0\t0\t0\t0\t0\t0\t1"
    back = W.loads(text)
    assert math.isnan(back.home_lat_deg) and math.isnan(back.home_lon_deg)


def test_whitespace_separated_and_comments_are_accepted(tmp_path):
    text = W.dumps(_mission()).replace("\t", "  ")
    text = text.replace("\n1 ", "\n# takeoff first\n1 ", 1)
    f = tmp_path / "m.waypoints"
    f.write_text(text)
    assert W.read(f).same_as(_mission())


def test_write_is_atomic_and_deterministic(tmp_path):
    a = W.write(tmp_path / "a.waypoints", _mission())
    b = W.write(tmp_path / "b.waypoints", _mission())
    assert a.read_bytes() == b.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.waypoints", "b.waypoints"]


GOOD = W.dumps(_mission())


def _replace_line(n, new):
    lines = GOOD.splitlines()
    lines[n] = new
    return "\n".join(lines) + "\n"


def _replace_col(n, col, value):
    lines = GOOD.splitlines()
    cols = lines[n].split("\t")
    cols[col] = value
    lines[n] = "\t".join(cols)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "text, line, field, fragment",
    [
        ("", 1, "header", "an empty file"),
        ("QGC WPL 100\n", 1, "header", "QGC WPL 110"),
        (_replace_line(3, "2\t0\t2\t178\t1\t12.5"), 4, None, "12 tab-separated columns, got 6"),
        (_replace_col(3, 0, "two"), 4, "index", "whole number"),
        (_replace_col(3, 1, "2"), 4, "current", "out of range"),
        (_replace_col(3, 2, "3.5"), 4, "frame", "whole number"),
        (_replace_col(3, 3, "-16"), 4, "command", "out of range"),
        (_replace_col(3, 5, "fast"), 4, "param2", "must be a number"),
        (_replace_col(3, 6, "inf"), 4, "param3", "finite"),
        (_replace_col(4, 8, "91"), 5, "latitude/x", "outside -90..90"),
        (_replace_col(4, 9, "-181"), 5, "longitude/y", "outside -180..180"),
        (_replace_col(4, 10, "nan"), 5, "altitude/z", "not a finite"),
        (_replace_col(4, 11, "yes"), 5, "autocontinue", "whole number"),
    ],
)
def test_malformed_waypoints_name_file_line_and_field(text, line, field, fragment):
    with pytest.raises(FileFormatError) as ei:
        W.loads(text, path="uav1.waypoints")
    err = ei.value
    assert str(err).startswith("uav1.waypoints, line")
    assert (err.line, err.field) == (line, field)
    assert fragment in str(err)


def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="not found"):
        W.read(tmp_path / "nope.waypoints")


def test_binary_file(tmp_path):
    f = tmp_path / "bin.waypoints"
    f.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(FileFormatError, match="not UTF-8"):
        W.read(f)
