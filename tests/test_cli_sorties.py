"""Scenarios with several packs (issue 38) where vehicles are flown: until the daemon flies sorties,
`uavloc demo` and `uavloc daemon` refuse them in one sentence naming the key, writing nothing."""

from __future__ import annotations

from pathlib import Path

from uavloc_gcs.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _two_packs(tmp_path: Path, extra: str = "") -> Path:
    text = (ROOT / "examples" / "paper.toml").read_text()
    text = text.replace("energy_reserve_fraction = 0.15", "energy_reserve_fraction = 0.15\nbatteries = 2")
    assert "batteries = 2" in text
    p = tmp_path / "two-packs.toml"
    p.write_text(text + extra)
    return p


def test_demo_and_daemon_refuse_several_packs_until_they_fly_sorties(tmp_path, capsys):
    sc = _two_packs(tmp_path, '\n[link]\nconnections = ["udpout:127.0.0.1:9", "udpout:127.0.0.1:9", '
                              '"udpout:127.0.0.1:9", "udpout:127.0.0.1:9"]\n')
    out = tmp_path / "out"
    for argv in (["demo", "--scenario", str(sc), "--no-web", "--out", str(out)],
                 ["daemon", "--config", str(sc), "--out", str(out)]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "key 'fleet.batteries': is 2" in err and "set fleet.batteries = 1" in err
        assert not out.exists() or not any(out.iterdir())
