"""``uavloc bench sorties`` (benchmarks/sorties.py): the POD the scan planner reaches per pack count."""

from __future__ import annotations

import re

import pytest

from tests.test_pod_plan import _small_field
from uavloc_gcs.cli import main


@pytest.mark.slow
def test_bench_sorties_prints_a_row_per_pack_count_and_more_packs_reach_more(tmp_path, capsys):
    sc = _small_field(tmp_path)
    assert main(["bench", "sorties", "--scenario", str(sc), "--packs", "1,2", "--target", "0.7"]) == 0
    out = capsys.readouterr().out
    assert "1 pack: POD 0.6" in out and re.search(r"2 packs: POD 0\.7 in \d+ min with 2 packs per vehicle", out), out
    rows = [line.split() for line in out.splitlines() if re.match(r"\s*[12]\s+(yes|no)\s", line)]
    assert [r[0] for r in rows] == ["1", "2"] and [r[1] for r in rows] == ["no", "yes"]
    assert float(rows[1][2]) > float(rows[0][2]) and float(rows[1][3]) > float(rows[0][3])  # POD1, POD2
    # the anchor: no plan reaches the target sooner than a receiver hearing every burst from the start
    floor = re.search(r"the phones' floor: POD 0\.7 needs (\d+):(\d\d) of listening", out)
    assert floor and int(floor[1]) * 60 + int(floor[2]) > 0, out
    assert rows[0][10] == "-" and float(rows[1][10]) >= 1.0, out


def test_bench_sorties_refuses_bad_pack_lists(capsys):
    assert main(["bench", "sorties", "--packs", "0,2"]) == 2
    assert "--packs must list 1-50 packs per vehicle" in capsys.readouterr().err
