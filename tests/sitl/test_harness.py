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


def test_a_finished_mission_is_not_taken_for_the_new_one_until_it_starts():
    """The reproduction of CI's PX4 sortie failure (2026-11-29): after a new upload a PX4 keeps
    reporting the last mission's RTL item with state COMPLETE; the helper that waits for a
    mission's end reads no item until a report of the new mission."""
    from uavloc_gcs.dialect import mavlink

    from .flying import Watch

    class Link:  # the one thing Watch asks of a link: a subscription whose callback it is given
        def subscribe(self, kind, *, source_system, callback):
            self.callback = callback
            return self

        def close(self):
            pass

    def current(seq, state):
        return mavlink.MAVLink_mission_current_message(seq, 9, state)

    link = Link()
    watch = Watch(link, 1)
    link.callback(current(8, mavlink.MISSION_STATE_COMPLETE))
    assert watch.mission_seq == 8  # no upload yet: the report is what it is
    watch.mark_upload()
    link.callback(current(8, mavlink.MISSION_STATE_COMPLETE))
    assert watch.mission_seq is None  # sortie 1's RTL item is no news about sortie 2
    link.callback(current(1, mavlink.MISSION_STATE_ACTIVE))
    assert watch.mission_seq == 1
    link.callback(current(6, mavlink.MISSION_STATE_COMPLETE))
    assert watch.mission_seq == 6  # the new mission's own end counts
