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


# ---------------------------------------------------------------------------------------------
# issue 40 item 4: writing across filesystems (a USB stick's mount point, a link to another disk)

import errno
import os
from pathlib import Path


@pytest.fixture
def other_fs(tmp_path):
    """A directory on another filesystem than ``tmp_path`` (a tmpfs under /dev/shm), removed at
    the end; the test is skipped, saying why, where the machine has none."""
    import shutil
    import tempfile

    shm = Path("/dev/shm")
    if not shm.is_dir() or not os.access(shm, os.W_OK) or shm.stat().st_dev == tmp_path.stat().st_dev:
        pytest.skip("no second filesystem here (/dev/shm missing, read-only or on the same device as the "
                    "temporary directory); the EXDEV fallback is also tested with rename made to fail")
    d = Path(tempfile.mkdtemp(prefix="uavloc-test-", dir=shm))
    yield d
    shutil.rmtree(d, ignore_errors=True)


def test_replace_copies_a_file_across_filesystems(tmp_path, other_fs):
    from uavloc_gcs.atomicfile import replace

    src = tmp_path / "new.txt"
    src.write_text("new")
    (other_fs / "a.txt").write_text("old")
    with pytest.raises(OSError) as caught:
        os.replace(src, other_fs / "a.txt")  # the plain rename really cannot cross
    assert caught.value.errno == errno.EXDEV
    replace(src, other_fs / "a.txt")
    assert (other_fs / "a.txt").read_text() == "new"
    assert not src.exists()
    assert [p.name for p in other_fs.iterdir()] == ["a.txt"]  # no staging left beside it


def test_replace_moves_a_directory_across_filesystems_over_an_old_one(tmp_path, other_fs):
    from uavloc_gcs.atomicfile import replace

    (tmp_path / "d" / "sub").mkdir(parents=True)
    (tmp_path / "d" / "sub" / "x.csv").write_text("1\n")
    (other_fs / "d").mkdir()
    (other_fs / "d" / "stale.csv").write_text("old\n")
    replace(tmp_path / "d", other_fs / "d")
    assert sorted(str(p.relative_to(other_fs)) for p in other_fs.rglob("*")) == ["d", "d/sub", "d/sub/x.csv"]
    assert not (tmp_path / "d").exists()


def test_atomic_output_dir_into_a_link_to_another_filesystem(tmp_path, other_fs):
    """``--out usb`` where usb is a link to (or the mount point of) another filesystem: the rename
    from a staging directory beside it failed with EXDEV (issue 40)."""
    from uavloc_gcs.cli._output import atomic_output_dir

    (tmp_path / "usb").symlink_to(other_fs)
    (other_fs / "keep.txt").write_text("mine")
    with atomic_output_dir(tmp_path / "usb") as out:
        (out / "a.csv").write_text("a")
        (out / "b.png").write_bytes(b"b")
    assert sorted(p.name for p in other_fs.iterdir()) == ["a.csv", "b.png", "keep.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["usb"]  # nothing staged beside it


def _rename_cannot_cross(monkeypatch, staging_root: Path):
    """Make every rename out of ``staging_root`` fail as a cross-device rename does."""
    real_rename, real_replace = os.rename, os.replace

    def guard(real):
        def fake(src, dst, *a, **k):
            if Path(src).is_relative_to(staging_root) and not Path(dst).is_relative_to(staging_root):
                raise OSError(errno.EXDEV, os.strerror(errno.EXDEV), str(src), None, str(dst))
            return real(src, dst, *a, **k)
        return fake

    monkeypatch.setattr(os, "rename", guard(real_rename))
    monkeypatch.setattr(os, "replace", guard(real_replace))


def test_exdev_from_the_staging_directory_falls_back_to_copy_and_replace(tmp_path, monkeypatch):
    from uavloc_gcs.cli import _output

    staging = tmp_path / "staging"
    staging.mkdir()
    real_mkdtemp = _output.tempfile.mkdtemp
    monkeypatch.setattr(_output.tempfile, "mkdtemp",  # the command's staging directory elsewhere
                        lambda prefix="", dir=None: real_mkdtemp(
                            prefix=prefix, dir=staging if "partial-" in prefix else dir))
    _rename_cannot_cross(monkeypatch, staging)
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.csv").write_text("old")
    with _output.atomic_output_dir(out) as tmp:
        assert tmp.is_relative_to(staging)
        (tmp / "a.csv").write_text("new")
        (tmp / "sub").mkdir()
        (tmp / "sub" / "c.txt").write_text("c")
    assert (out / "a.csv").read_text() == "new" and (out / "sub" / "c.txt").read_text() == "c"
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", "sub"]
    assert list(staging.iterdir()) == []


def test_a_copy_that_fails_half_way_changes_nothing_in_the_output(tmp_path, monkeypatch):
    """Disk full on the stick while copying the second file: the first is not put in place
    either, and the sentence names the directory."""
    import shutil

    from uavloc_gcs.cli import _output
    from uavloc_gcs.errors import OutputError

    staging = tmp_path / "staging"
    staging.mkdir()
    real_mkdtemp = _output.tempfile.mkdtemp
    monkeypatch.setattr(_output.tempfile, "mkdtemp",  # the command's staging directory elsewhere
                        lambda prefix="", dir=None: real_mkdtemp(
                            prefix=prefix, dir=staging if "partial-" in prefix else dir))
    _rename_cannot_cross(monkeypatch, staging)
    real_copy2 = shutil.copy2

    def copy2(src, dst, *a, **k):
        if Path(src).name == "b.csv":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))
        return real_copy2(src, dst, *a, **k)

    monkeypatch.setattr(shutil, "copy2", copy2)
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.csv").write_text("old")
    with pytest.raises(OutputError, match=r"cannot write into .*out: No space left on device; nothing was changed"):
        with _output.atomic_output_dir(out) as tmp:
            (tmp / "a.csv").write_text("new")
            (tmp / "b.csv").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["a.csv"]
    assert (out / "a.csv").read_text() == "old"


def test_a_full_disk_while_writing_is_one_sentence_and_leaves_the_old_file(tmp_path):
    from uavloc_gcs.atomicfile import atomic_open
    from uavloc_gcs.errors import OutputError

    target = tmp_path / "a.txt"
    target.write_text("old")
    with pytest.raises(OutputError, match=r"cannot write .*a\.txt: No space left on device"):
        with atomic_open(target, "w"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_directory_that_holds_no_files_is_one_sentence(tmp_path):
    from uavloc_gcs.atomicfile import atomic_write_text
    from uavloc_gcs.errors import OutputError

    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match=r"cannot write .*f/x\.txt: Not a directory"):
        atomic_write_text(tmp_path / "f" / "x.txt", "x")
