"""`uavloc bench low_orbit` runs end to end and prints what it measured (the figures themselves are
the benchmark's; here one short run)."""

import argparse

from benchmarks import low_orbit


def test_one_short_low_orbit_prints_its_rows_and_summary(capsys):
    p = argparse.ArgumentParser()
    low_orbit.add_arguments(p)
    assert low_orbit.main(p.parse_args(["--alt", "30", "--minutes", "3", "--runs", "1"])) == 0
    out = capsys.readouterr().out
    assert "at 30 m (radius 30 m" in out and "located (95 % radius <= 15 m):" in out
    assert out.count("\n") >= 4
