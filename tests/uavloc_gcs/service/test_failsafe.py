"""The ground-station-loss failsafe check: read from fake vehicles over real MAVLink, judged per
autopilot; and the daemon's exchange judgement (lifecycle.persist)."""

import asyncio
from pathlib import Path

import pytest

from sim_link.vehicles.fleet import FakeFleet
from uavloc_gcs.errors import CommandError
from uavloc_gcs.link import open_link
from uavloc_gcs.scenario import load_scenario
from uavloc_gcs.service.failsafe import gcs_loss_warning, read_gcs_loss_warning
from uavloc_gcs.service.lifecycle import ExchangeFailed, allowed, persist

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


@pytest.mark.parametrize("autopilot,name,bad,words", [
    ("ardupilot", "FS_GCS_ENABLE", 0.0, ["FS_GCS_ENABLE = 0", "hovers", "set FS_GCS_ENABLE = 1"]),
    ("px4", "NAV_DLL_ACT", 1.0, ["NAV_DLL_ACT = 1", "holds position after COM_DL_LOSS_T = 10 s", "hovers"]),
])
def test_a_failsafe_that_would_leave_a_vehicle_hovering_is_named_over_mavlink(autopilot, name, bad, words):
    sc = load_scenario(EXAMPLES / "small.toml").replace(fleet={"autopilot": autopilot, "vehicles": 2})

    async def go():
        async with FakeFleet(sc, speedup=1, seed=3, base_port=0) as fleet:
            fleet.vehicle(2).params[name] = bad  # vehicle 1 keeps the fake's field setting
            out = []
            for vid, (_n, conn) in enumerate(fleet.endpoints, start=1):
                async with await open_link(conn, source_system=245) as link:
                    await link.wait_heartbeat(vid, timeout_s=10)
                    out.append(await read_gcs_loss_warning(link, vid, autopilot))
            return out

    good, warned = asyncio.run(asyncio.wait_for(go(), 60))
    assert good is None
    assert warned is not None and warned.startswith("vehicle 2 has")
    for w in words:
        assert w in warned, warned


def test_unknown_or_dangerous_settings_are_warned_and_safe_ones_are_not():
    assert gcs_loss_warning(1, "ardupilot", {"FS_GCS_ENABLE": 1.0}) is None
    assert gcs_loss_warning(1, "ardupilot", {"FS_GCS_ENABLE": 5.0}) is None  # lands
    assert "did not report FS_GCS_ENABLE" in gcs_loss_warning(3, "ardupilot", {"FS_GCS_ENABLE": None})
    assert gcs_loss_warning(1, "px4", {"NAV_DLL_ACT": 2.0, "COM_DL_LOSS_T": 10.0}) is None
    assert "falls" in gcs_loss_warning(1, "px4", {"NAV_DLL_ACT": 5.0, "COM_DL_LOSS_T": 10.0})
    assert "disabled" in gcs_loss_warning(1, "px4", {"NAV_DLL_ACT": 0.0, "COM_DL_LOSS_T": None})


def test_the_state_machine_allows_only_its_moves():
    assert allowed("scanning", "hovering (scan done)") and allowed("localizing", "unusable")
    assert not allowed("landed", "scanning") and not allowed("connecting", "localizing")


class _Vehicle:
    """Carries out what it is told; the ACK of the first ``lose`` commands is lost."""

    def __init__(self, lose=0, refuse=False):
        self.lose, self.refuse, self.done, self.calls, self.heard = lose, refuse, False, 0, 0.0

    async def command(self):
        self.calls += 1
        if self.refuse:
            raise CommandError("MAV_CMD_X: TEMPORARILY_REJECTED")
        self.done = True
        self.heard = asyncio.get_running_loop().time()
        if self.calls <= self.lose:
            raise CommandError("MAV_CMD_X: no COMMAND_ACK after 6 tries")


def _persist(v, **kw):
    loop = asyncio.get_running_loop()
    return persist(v.command, lambda: v.done, what="x", vehicle=1, backoff_s=(0.01,), settle_s=0.2,
                   heard_since=lambda t: v.heard >= t - 1.0, wall=loop.time, **kw)


def test_a_lost_ack_is_judged_from_what_the_vehicle_does_and_a_refusal_fails_after_every_try():
    async def go():
        ok = _Vehicle()
        lost = _Vehicle(lose=5)
        refusing = _Vehicle(refuse=True)
        retries = []
        r1 = await _persist(ok)
        r2 = await _persist(lost)
        with pytest.raises(ExchangeFailed, match="failed 3 times"):
            await _persist(refusing, on_retry=retries.append)
        return r1, r2, ok.calls, lost.calls, refusing.calls, retries

    r1, r2, ok_calls, lost_calls, refused_calls, retries = asyncio.run(go())
    assert (r1, ok_calls) == ("acked", 1)
    assert (r2, lost_calls) == ("judged", 1)  # not sent again: the vehicle was seen doing it
    assert refused_calls == 3 and len(retries) == 2


class _ShortLook:
    """Takes off on the command, flies a look shorter than the command's wait for its ACK, lands,
    and never acknowledges: by the time the command gives up, the vehicle is done and on the ground."""

    def __init__(self):
        self.calls, self.flying, self.heard = 0, False, 0.0

    async def command(self):
        self.calls += 1
        loop = asyncio.get_running_loop()
        self.flying, self.heard = True, loop.time()
        await asyncio.sleep(0.2)
        self.flying, self.heard = False, loop.time()
        await asyncio.sleep(0.2)
        raise CommandError("MAV_CMD_MISSION_START: no COMMAND_ACK after 6 tries")


def test_a_vehicle_seen_doing_it_while_the_ack_was_awaited_is_not_told_again():
    async def go():
        v = _ShortLook()
        loop = asyncio.get_running_loop()
        how = await persist(v.command, lambda: v.flying, what="start", vehicle=1, backoff_s=(0.01,),
                            settle_s=0.2, heard_since=lambda t: v.heard >= t, wall=loop.time)
        return how, v.calls

    # judged only after the command failed, it looked landed, and was started a second time
    assert asyncio.run(go()) == ("judged", 1)
