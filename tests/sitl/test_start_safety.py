"""Issue 26 on PX4 SIH: a look planned while the vehicle hovered (no take-off) whose upload stalled
until the vehicle had landed was then started on the ground -- PX4 armed by MISSION_START and
climbed off towards the look. The daemon's own exchanges run here against real PX4 through a UDP
proxy that holds back every mission-protocol message from the ground while the vehicle's scan hold
runs out and it flies home and lands by its RTL item; the proxy also records every MISSION_START
with the mission uploaded last. Measured before the fix: MISSION_START with the look [178, 16, 20]
(no take-off) after the landing, and PX4 armed and climbed."""

from __future__ import annotations

import asyncio

import numpy as np

from tests.e2e_helpers import small_scenario
from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.mission import NAV_TAKEOFF, flight_mission, to_wire
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.missionstate import with_hold_before_rtl
from uavloc_gcs.service.store import Store, StoreReader

from . import harness

ALT_M = 20.0
HOLD_S = 15.0  # the scan's closing hold [s]: then its RTL item brings the vehicle home by itself


class _Side(asyncio.DatagramProtocol):
    def __init__(self, on_data):
        self.on_data, self.transport = on_data, None

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        self.on_data(data, addr)


class MissionStallProxy:
    """Between uavloc (``udpout`` to :attr:`port`) and PX4 (which sends to ``px4_gcs_port``)."""

    def __init__(self, px4_gcs_port: int):
        self.px4_gcs_port = px4_gcs_port
        self.stall = False
        self.stalled = 0
        self.uploads: list[list[int]] = []  # the commands of each mission sent, in order
        self.starts: list[list[int]] = []  # at each MISSION_START: the commands of the last mission sent
        self._items: dict[int, int] = {}
        self._count = 0
        self._gcs = self._px4 = None
        self._parse = M.MAVLink(None)
        self._parse.robust_parsing = True

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._to_gcs, _ = await loop.create_datagram_endpoint(lambda: _Side(self._from_gcs),
                                                              local_addr=("127.0.0.1", 0))
        self._to_px4, _ = await loop.create_datagram_endpoint(lambda: _Side(self._from_px4),
                                                              local_addr=("127.0.0.1", self.px4_gcs_port))
        self.port = self._to_gcs.get_extra_info("sockname")[1]

    def close(self) -> None:
        self._to_gcs.close()
        self._to_px4.close()

    def _from_px4(self, data, addr):
        self._px4 = addr
        if self._gcs is not None:
            self._to_gcs.sendto(data, self._gcs)

    def _from_gcs(self, data, addr):
        self._gcs = addr
        for msg in self._parse.parse_buffer(data) or ():
            kind = msg.get_type()
            if kind == "BAD_DATA":
                continue
            if kind.startswith("MISSION_") and kind != "MISSION_SET_CURRENT" and self.stall:
                self.stalled += 1
                continue
            if kind == "MISSION_COUNT" and getattr(msg, "mission_type", 0) == 0:
                self._count, self._items = msg.count, {}
            elif kind == "MISSION_ITEM_INT" and getattr(msg, "mission_type", 0) == 0:
                self._items[msg.seq] = msg.command
                if len(self._items) == self._count:
                    self.uploads.append([self._items[k] for k in range(self._count)])
            elif kind == "COMMAND_LONG" and msg.command == M.MAV_CMD_MISSION_START:
                self.starts.append(list(self.uploads[-1]) if self.uploads else [])
            if self._px4 is not None:
                self._to_px4.sendto(msg.get_msgbuf(), self._px4)


class _NoPolicy:
    time_limit_s = 0.1

    def done(self, t):
        return False


async def _until(cond, timeout_s: float, what: str) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not cond():
        if loop.time() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.05)


def test_px4_look_whose_upload_stalled_until_it_landed_is_not_started_without_a_takeoff(sitl, tmp_path):
    proc = sitl("px4")
    lat, lon = proc.home[:2]
    sc = small_scenario("px4", speedup=float(proc.speedup)).replace(
        area={"origin_lat_deg": lat, "origin_lon_deg": lon}, fleet={"vehicles": 1, "altitude_m": ALT_M})
    store_path = tmp_path / "s.sqlite"
    gcs_port = int(proc.connection.rsplit(":", 1)[1])

    async def go():
        proxy = MissionStallProxy(gcs_port)
        await proxy.start()
        d = Daemon(sc, [(proc.sysid, f"udpout:127.0.0.1:{proxy.port}")],
                   DaemonOptions(store_path=store_path, resume=False, connect_timeout_s=30.0), policy=_NoPolicy())
        d.store = Store(store_path)
        try:
            await d._connect_all()
            v = d.vehicles[proc.sysid]
            a = v.agent
            # up to ALT_M, holding near home (the end of a scan), then RTL
            hover = with_hold_before_rtl(flight_mission([(lat, lon + 0.0003)], alt_m=ALT_M, speed_m_s=5.0,
                                                        autopilot="px4", home_latlon_deg=(lat, lon)), HOLD_S)
            v.phase = "uploading scan"
            await d._upload(v, "scan", to_wire(hover, "px4"), first_seq=None)
            await d._start(v)
            await _until(lambda: a.tel.rel_alt_m > ALT_M - 3.0, 120.0, "the vehicle to hover")
            v.phase, v.scan_done = "hovering (scan done)", True
            proxy.stall = True  # the look's upload gets no answer...
            job = d._launch(v, d._upload_look(v, np.array([[150.0, 100.0]]), (7,)))
            # ... while the hold runs out and the vehicle flies home and lands (its RTL item)
            await _until(lambda: a.on_ground() and not a.tel.armed, 180.0, "the vehicle to land and disarm")
            landed_at = len(proxy.starts)
            proxy.stall = False  # the link comes back: the upload goes through
            await asyncio.wait([job], timeout=120.0)
            await asyncio.sleep(5.0)
            climbed = a.tel.armed and a.tel.rel_alt_m > 3.0
            if a.tel.armed:
                await a.return_home()
                await _until(lambda: not a.tel.armed, 180.0, "the vehicle to land again")
            d.store.flush()
            with StoreReader(store_path) as rd:
                events = [f"{e.kind}: {e.text}" for e in rd.events()]
            return proxy, landed_at, climbed, job, events
        finally:
            await d._cancel_jobs()
            await d._close_links()
            d.store.close()
            proxy.close()

    proxy, landed_at, climbed, job, events = harness.run(go(), 600)
    assert proxy.stalled > 0, "the upload was held back"
    after_landing = proxy.starts[landed_at:]
    assert all(NAV_TAKEOFF in mission for mission in after_landing), (after_landing, events)
    assert any("landed" in e and "take-off" in e for e in events), events
    print(f"px4: starts after landing {after_landing}; climbed {climbed}; {events[-6:]}")
