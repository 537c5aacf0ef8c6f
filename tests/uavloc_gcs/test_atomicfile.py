import pytest


def test_atomic_write_leaves_nothing_behind_on_error(tmp_path):
    from uavloc_gcs.atomicfile import atomic_open, atomic_write_text

    target = tmp_path / "a.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_open(target, "w") as fh:
            fh.write("half")
            raise RuntimeError("crash mid-write")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]
    assert (target.stat().st_mode & 0o777) == 0o644
