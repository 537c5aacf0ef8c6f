"""The harness itself: builds found or a clear skip, instance numbers never shared, processes
stopped by pid, and a uavloc link hears each autopilot."""

from __future__ import annotations

import os

import pytest

from uavloc_gcs.link import open_link

from . import harness


def test_missing_builds_give_one_sentence(monkeypatch, tmp_path):
    monkeypatch.setenv("UAVLOC_SITL_DIR", str(tmp_path))
    monkeypatch.delenv("UAVLOC_ARDUCOPTER", raising=False)
    monkeypatch.delenv("UAVLOC_PX4_DIR", raising=False)
    for kind in ("ardupilot", "px4"):
        reason = harness.skip_reason(kind)
        assert reason and "UAVLOC_SITL_DIR" in reason and reason.count(".") <= 2
    with pytest.raises(harness.SitlError, match="UAVLOC_SITL_DIR"):
        harness.start_arducopter()


def test_instance_locks_are_exclusive():
    a = harness.InstanceLock("selftest", range(0, 3))
    b = harness.InstanceLock("selftest", range(0, 3))
    try:
        assert a.number != b.number
        c = harness.InstanceLock("selftest", range(0, 3))
        with pytest.raises(harness.SitlError, match="in use"):
            harness.InstanceLock("selftest", range(0, 3))
        c.release()
        d = harness.InstanceLock("selftest", range(0, 3))  # a released number is free again
        assert d.number == c.number
        d.release()
    finally:
        a.release()
        b.release()


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_start_hear_and_stop(kind, sitl):
    proc = sitl(kind)
    assert proc.ready_after_s is not None and proc.alive()

    async def hear():
        async with await open_link(proc.connection) as link:
            hb = await link.wait_heartbeat(proc.sysid, timeout_s=30)
            return hb.autopilot
    expected = 3 if kind == "ardupilot" else 12  # MAV_AUTOPILOT_ARDUPILOTMEGA / _PX4
    assert harness.run(hear(), 60) == expected
    pgid = proc.proc.pid
    proc.stop()
    assert not proc.alive()
    with pytest.raises(ProcessLookupError):
        os.killpg(pgid, 0)  # the whole process group is gone
