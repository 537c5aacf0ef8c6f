"""The daemon's decisions without a network: who gets planned for, what gets uploaded."""

import asyncio
from types import SimpleNamespace

import numpy as np

from tests.e2e_helpers import small_scenario
from uavloc_gcs.service.daemon import Daemon, DaemonOptions
from uavloc_gcs.service.store import Store, StoreReader
from uavloc_gcs.service.vehicle import Telemetry


class _Agent:
    def __init__(self, xy):
        self.xy = xy
        self.tel = Telemetry(battery_pct=80.0, mission_seq=0, armed=True, mode="AUTO")
        self.flavour = SimpleNamespace(home_at_seq0=True, name="ardupilot")
        self.uploads, self.switches, self.homes = [], [], 0
        self.texts = []  # STATUSTEXTs (wall s, text)
        self.airborne_wall_s = float("-inf")

    def position_xy_m(self):
        return self.xy

    def on_ground(self):
        return False

    def landed(self):  # on the ground and disarmed, by the vehicle's own word (VehicleAgent.landed)
        return self.on_ground() and not self.tel.armed

    async def upload(self, items):
        self.uploads.append(items)

    async def switch_to(self, seq, *, before_start=None, **_kw):
        if before_start is not None:
            before_start()
        self.switches.append(seq)
        if self.on_ground():  # started from the ground: it takes off
            self.take_off()

    def take_off(self):
        self.tel.armed, self.tel.rel_alt_m = True, 10.0

    async def disarm(self):
        self.tel.armed = False

    async def return_home(self):
        self.homes += 1


class _Policy:
    """Asks for a plan; gives every vehicle it is offered one look at person 7 (or 8)."""

    time_limit_s = 0.1

    def __init__(self):
        self.offered = []

    def done(self, t):
        return False

    def needs_replan(self, t, changed):
        return bool(changed)

    def replan(self, t, vehicles):
        self.offered.append(sorted(v.id for v in vehicles))
        tasks = [SimpleNamespace(vehicle_id=v.id, target_ids=(7 + k,), eta_s=t + 60, access_times_s=(t + 10,),
                                 waypoints_xy_m=np.array([[100.0 * (k + 1), 50.0], [0.0, 0.0]]))
                 for k, v in enumerate(vehicles)]
        return SimpleNamespace(tasks=tuple(tasks), makespan_s=60.0, planner_runtime_s=0.01)


def _daemon(tmp_path):
    sc = small_scenario()
    policy = _Policy()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:26990"), (2, "udpout:127.0.0.1:26991")],
               DaemonOptions(store_path=tmp_path / "s.sqlite"), policy=policy)
    d.store = Store(tmp_path / "s.sqlite")
    for vid, v in d.vehicles.items():
        v.agent = _Agent((50.0 * vid, 100.0))
        v.scan_done, v.phase = True, "hovering (scan done)"
    return d, policy


def test_a_lost_vehicles_people_go_to_the_others_and_unchanged_missions_are_not_re_uploaded(tmp_path):
    d, policy = _daemon(tmp_path)
    try:
        asyncio.run(d._step(100.0, {7}))
        assert policy.offered == [["1", "2"]]
        a1, a2 = d.vehicles[1].agent, d.vehicles[2].agent
        assert len(a1.uploads) == 1 and len(a2.uploads) == 1
        first_seq = d.vehicles[1].look_first_seq

        asyncio.run(d._step(101.0, {7}))  # same plan, vehicles still before their looks
        assert len(a1.uploads) == 1 and len(a2.uploads) == 1

        d.vehicles[1].lost = True  # vehicle 1 goes silent: the plan is made for vehicle 2 alone
        asyncio.run(d._step(102.0, set()))
        assert policy.offered[-1] == ["2"]
        assert len(a2.uploads) == 2 and d.vehicles[2].targets == (7,)

        d.vehicles[1].lost = False  # back: planned for again
        a2.tel.mission_seq = first_seq + 1  # vehicle 2 has passed its look: an equal plan is new to it
        d.vehicles[2].ignore_seq_until_wall = 0.0
        d._report_looks(103.0)  # as the brain does before each step
        asyncio.run(d._step(103.0, set()))
        assert policy.offered[-1] == ["1", "2"] and len(a2.uploads) == 3
    finally:
        d.store.close()


def test_no_plan_until_every_vehicle_in_contact_has_finished_its_scan(tmp_path):
    d, policy = _daemon(tmp_path)
    try:
        d.vehicles[2].scan_done, d.vehicles[2].phase = False, "scanning"
        asyncio.run(d._step(50.0, {7}))
        assert policy.offered == []
        d.vehicles[2].lost = True  # ... unless the one still scanning is lost
        asyncio.run(d._step(51.0, {7}))
        assert policy.offered == [["1"]]
    finally:
        d.store.close()


class _ReportingPolicy(_Policy):
    """_Policy that also takes look reports."""

    look_reports = False

    def __init__(self):
        super().__init__()
        self.flown = []

    def look_flown(self, emitter_id, t_s):
        self.flown.append((emitter_id, t_s))


def _looking(tmp_path, name="s"):
    """One vehicle, done with its scan, given a look at person 7 by a reporting policy:
    (daemon, policy, vehicle), the store open (close it)."""
    policy = _ReportingPolicy()
    d = Daemon(small_scenario(), [(1, "udpout:127.0.0.1:26990")],
               DaemonOptions(store_path=tmp_path / f"{name}.sqlite"), policy=policy)
    d.store = Store(tmp_path / f"{name}.sqlite")
    v = d.vehicles[1]
    v.agent = _Agent((50.0, 100.0))
    v.scan_done, v.phase = True, "hovering (scan done)"
    asyncio.run(d._step(100.0, {7}))
    v.ignore_seq_until_wall = 0.0
    return d, policy, v


def test_the_daemon_reports_a_look_when_the_vehicle_passes_it(tmp_path):
    d, policy, v = _looking(tmp_path)
    assert policy.look_reports  # the daemon says it will report looks
    try:
        look = v.look_xy_m[0]
        d._report_looks(110.0)
        assert policy.flown == []  # on its way
        v.agent.xy = (float(look[0]) + 3.0, float(look[1]))  # within the waypoint tolerance
        d._report_looks(120.0)
        d._report_looks(121.0)  # reported once
        assert policy.flown == [(7, 120.0)]
        v.agent.xy = (0.0, 0.0)
        v.agent.tel.mission_seq = v.look_first_seq + 1  # moved on (MISSION_CURRENT past the look)
        d._report_looks(130.0)
        assert policy.flown == [(7, 120.0)]
    finally:
        d.store.close()


def test_a_look_is_reported_from_the_mission_sequence_alone(tmp_path):
    d, policy, v = _looking(tmp_path)
    try:
        v.agent.tel.mission_seq = v.look_first_seq + 1  # e.g. a MISSION_ITEM_REACHED we did not see
        d._report_looks(140.0)
        assert policy.flown == [(7, 140.0)]
    finally:
        d.store.close()


def test_a_look_passed_before_its_mission_is_replaced_or_the_vehicle_sent_home_is_reported(tmp_path):
    """The mountains demo said "look not flown 180 s after its time; planned again" of looks the
    vehicle had flown (its telemetry reached both look waypoints, then it landed). The brain reports
    passed looks before each policy update, which took 2-20 s of CPU over terrain; a vehicle that
    passed its look meanwhile and was then given a new look mission, or sent home, lost the pass
    with its old mission. Both now report the passes they read at that moment."""
    for how in ("home", "new look"):
        d, policy, v = _looking(tmp_path, how)
        try:
            assert v.targets == (7,) and policy.flown == []
            v.agent.tel.mission_seq = v.look_first_seq + 1  # passed while the brain was busy
            if how == "home":
                asyncio.run(d._send_home(v))
            else:
                asyncio.run(d._upload_look(v, np.array([[300.0, 300.0], [0.0, 0.0]]), (8,)))
                assert v.targets == (8,) and v.looks_reported == 0
            assert [e for e, _ in policy.flown] == [7], how
        finally:
            d.store.close()


class _DriftingPolicy(_Policy):
    """Every replan moves the look a little (an estimate settling), as the SITL runs showed; or adds
    a person when told to."""

    def __init__(self):
        super().__init__()
        self.shift, self.targets = 0.0, [7]

    def replan(self, t, vehicles):
        self.offered.append(sorted(v.id for v in vehicles))
        self.shift += 3.5
        pts = [[100.0 + 50 * k, 50.0 + self.shift] for k in range(len(self.targets))] + [[0.0, 0.0]]
        tasks = [SimpleNamespace(vehicle_id=v.id, target_ids=tuple(self.targets), eta_s=t + 60,
                                 access_times_s=tuple(t + 10 for _ in self.targets), waypoints_xy_m=np.array(pts))
                 for v in vehicles]
        return SimpleNamespace(tasks=tuple(tasks), makespan_s=60.0, planner_runtime_s=0.01)


def test_replans_that_only_shift_the_looks_a_little_are_not_uploaded_and_one_upload_per_look(tmp_path):
    """Reproduces the SITL churn of uploads (55-85 look missions per vehicle): now a plan that only
    moves a look by a few metres is not worth a restarted leg, and a vehicle gets at most one
    in-flight upload between two looks."""
    sc = small_scenario()
    policy = _DriftingPolicy()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:26990")], DaemonOptions(store_path=tmp_path / "s.sqlite"), policy=policy)
    d.store = Store(tmp_path / "s.sqlite")
    try:
        v = d.vehicles[1]
        v.agent = _Agent((50.0, 100.0))
        v.scan_done, v.phase = True, "hovering (scan done)"
        for k in range(5):  # 3.5-14 m from the uploaded look: within the required accuracy (15 m)
            asyncio.run(d._step(100.0 + k, {7}))
        assert len(v.agent.uploads) == 1 and len(policy.offered) == 5
        assert v.skipped == 2  # the two beyond the 10 m "same route" tolerance, not worth an upload
        policy.targets = [7, 9]  # someone new: worth an upload
        asyncio.run(d._step(110.0, {9}))
        assert len(v.agent.uploads) == 2
        policy.targets = [7, 9, 11]  # another one before the vehicle passed a look: deferred
        asyncio.run(d._step(111.0, {11}))
        assert len(v.agent.uploads) == 2 and v.deferred
        v.ignore_seq_until_wall = 0.0
        v.agent.tel.mission_seq = v.look_first_seq + 1  # passed its look at 7
        d._report_looks(120.0)
        assert d._replan_due
        asyncio.run(d._step(120.0, set()))
        assert len(v.agent.uploads) == 3 and v.targets == (7, 9, 11)
        outcome_rows = (v.id, v.plans, v.uploads, v.skipped)
        assert outcome_rows == (1, 3, 3, 3)
    finally:
        d.store.close()


class _LandingAgent(_Agent):
    """Descends in RTL; ``ground`` says whether it is low and slow enough to count as landed."""

    def __init__(self, xy):
        super().__init__(xy)
        self.tel.mode, self.ground = "RTL", False

    def on_ground(self):
        return self.ground

    def take_off(self):
        super().take_off()
        self.ground = False

    def silent_for_s(self):
        return 0.0

    @property
    def in_mission_mode(self):
        return self.tel.mode == "AUTO"


def test_a_vehicle_low_and_armed_that_climbs_again_in_rtl_is_returning_not_home(tmp_path):
    """Under 20 % loss a retried RTL reached a fake vehicle 1.2 m above home, still armed: the
    daemon took it for landed, the vehicle climbed back, and the search ended with it "not
    confirmed returning home" after waiting the whole landing allowance. Since issue 42 a vehicle
    low, slow and armed is not landed at all (only its own "disarmed" is): it stays returning
    while it climbs again, and is home once it says it is down and disarmed."""
    d, _policy = _daemon(tmp_path)
    try:
        v = d.vehicles[1]
        v.agent = _LandingAgent((0.0, 2.0))
        v.flew = True
        d._returning(v)
        v.agent.ground = True  # 1.2 m, armed, slow
        d._update_phase(v)
        assert not v.home and v.phase == "returning"
        v.agent.ground = False  # climbing again in RTL
        d._update_phase(v)
        assert not v.home and v.phase == "returning"
        v.agent.tel.armed, v.agent.ground = False, True  # down and disarmed
        d._update_phase(v)
        assert v.home and v.phase == "landed"
        d.store.flush()
        with StoreReader(tmp_path / "s.sqlite") as rd:
            assert [e.text for e in rd.events("landed")] == ["vehicle 1 landed (on the ground and disarmed)"]
            assert rd.events("home") == []
    finally:
        d.store.close()


def test_done_cancels_a_landed_vehicles_start_and_sends_home_one_airborne_again(tmp_path):
    """Reproduces a CI failure (tests/test_e2e_vehicle_faults.py, ArduCopter fake at 25x): a look
    started on landed vehicle 1 waited seconds for MISSION_START ACKs that never came; the
    vehicle flew the look and landed meanwhile, the person was located, and "done" cancelled the
    exchanges of the vehicles still out only. The start went on, sent vehicle 1 out again, and the
    search ended with it "not confirmed returning home". Now every exchange is cancelled at
    "done", and a vehicle airborne again after it is sent home."""
    d, policy = _daemon(tmp_path)
    policy.done = lambda t: True

    async def go():
        v1, v2 = d.vehicles[1], d.vehicles[2]
        for v in (v1, v2):
            v.agent = _LandingAgent((0.0, 2.0))
        v1.agent.ground, v1.agent.tel.armed, v1.home, v1.phase = True, False, True, "landed"
        v2.agent.tel.mode, v2.home, v2.phase = "AUTO", False, "localizing"  # out on a look
        launched = []

        async def slow_start():  # the MISSION_START still waiting for its ACK
            await asyncio.sleep(5.0)
            launched.append(1)

        d._launch(v1, slow_start())
        d.now_s = lambda: 500.0
        assert await d._step(500.0, set()) is False  # done: waiting for vehicle 2 to land
        await asyncio.sleep(0.1)
        assert v1.job is None and not launched, "the landed vehicle's start was cancelled"
        assert (v1.agent.homes, v2.agent.homes) == (0, 1) and v2.phase == "returning"

        # vehicle 1 is airborne again (a start that was already on its way): it is sent home too
        v1.agent.ground, v1.agent.tel.armed, v1.agent.tel.mode = False, True, "AUTO"
        d._update_phase(v1)
        assert not v1.home
        d.now_s = lambda: 510.0
        assert await d._step(510.0, set()) is False
        assert v1.agent.homes == 1 and v1.phase == "returning"
        return launched

    try:
        assert asyncio.run(go()) == []
        assert _texts(d, tmp_path, "done") == ["every person heard is located or given up: all vehicles return home"]
    finally:
        d.store.close()


def _texts(d, tmp_path, kind):
    d.store.flush()
    with StoreReader(tmp_path / "s.sqlite") as rd:
        return [e.text for e in rd.events(kind)]


def _all_landed(d):
    for v in d.vehicles.values():
        v.agent = _LandingAgent((0.0, 2.0))
        v.agent.ground, v.agent.tel.armed, v.home, v.phase = True, False, True, "landed"
    d._last_fleet = frozenset(v.id for v in d.vehicles.values())  # no fleet change to replan for


def test_with_everyone_home_and_people_pending_the_daemon_plans_once_more(tmp_path):
    """Seen in the fault test's store: a look flown and judged, nothing else changing, every vehicle
    landed -- and the search ended 10 s later with the person "95 % radius 283 m > 15 m", never
    planned for again. Nobody flying and people pending asks for one more plan."""
    d, policy = _daemon(tmp_path)
    _all_landed(d)
    try:
        assert asyncio.run(d._step(700.0, set())) is False
        assert policy.offered == [["1", "2"]]
        assert all(len(v.agent.uploads) == 1 and not v.home for v in d.vehicles.values())
    finally:
        d.store.close()


def test_the_search_does_not_end_idle_while_an_exchange_is_under_way(tmp_path):
    """A look's upload being retried to a landed vehicle is not "nobody is flying": the search ended
    under such an exchange before. When no look can be planned it ends, and says so."""
    d, policy = _daemon(tmp_path)
    _all_landed(d)
    policy.replan = lambda t, vehicles: SimpleNamespace(
        tasks=tuple(SimpleNamespace(vehicle_id=v.id, target_ids=(), eta_s=t, access_times_s=(),
                                    waypoints_xy_m=np.zeros((1, 2))) for v in vehicles),
        makespan_s=0.0, planner_runtime_s=0.0)
    policy.people = lambda t: [SimpleNamespace(emitter_id=7, located=False)]

    async def go():
        job = d._launch(d.vehicles[1], asyncio.sleep(30.0))
        ends = [await d._step(t, set()) for t in (700.0, 705.0, 720.0)]
        job.cancel()
        await asyncio.sleep(0.01)
        ends += [await d._step(t, set()) for t in (721.0, 725.0, 732.0)]
        return ends

    try:
        assert asyncio.run(go()) == [False] * 5 + [True]
        assert _texts(d, tmp_path, "end") == [
            "every vehicle is home and no look could be planned for person(s) 7: stopping the search"]
    finally:
        d.store.close()


def test_a_looks_events_are_logged_once_it_is_on_board_before_its_start(tmp_path):
    """Seen in the fault test's store: vehicle 1's look flew and landed while its MISSION_START
    (ACKs dropped) was still being resent; "done" cancelled that exchange, and the log never said
    the look had been uploaded or for whom. The events now come when the mission is on board."""
    d, policy = _daemon(tmp_path)

    class _SlowStart(_Agent):
        async def switch_to(self, seq, **_kw):
            await asyncio.sleep(30.0)  # ACKs that do not come

    async def go():
        for vid, v in d.vehicles.items():
            v.agent = _SlowStart((50.0 * vid, 100.0))
        task = asyncio.ensure_future(d._step(100.0, {7}))
        await asyncio.sleep(0.3)
        jobs = [v.job for v in d.vehicles.values() if v.job is not None]
        texts = (_texts(d, tmp_path, "upload"), _texts(d, tmp_path, "plan"))
        for job in jobs:
            job.cancel()
        await asyncio.gather(task, *jobs, return_exceptions=True)
        return jobs, texts

    try:
        jobs, (uploads, plans) = asyncio.run(go())
        assert len(jobs) == 2, "both starts were still under way"
        assert sorted(uploads) == [f"vehicle {k}: look mission of {n} items acknowledged" for k, n in
                                   ((1, len(d.vehicles[1].agent.uploads[0])), (2, len(d.vehicles[2].agent.uploads[0])))]
        assert sorted(plans) == ["vehicle 1 looks at 7", "vehicle 2 looks at 8"]
    finally:
        d.store.close()


def test_a_look_flown_and_landed_from_while_its_start_was_judged_leaves_the_vehicle_home(tmp_path):
    """Seen in tests/test_e2e_vehicle_faults.py's store (MISSION_START ACKs dropped, 25x): the
    vehicle flew its look and landed while the start was resent; the daemon then marked it "not
    home" after the exchange, so with everyone landed the search waited for the policy instead of
    planning again. What the vehicle does is read when the exchange ends."""
    d, policy = _daemon(tmp_path)
    _all_landed(d)

    class _FliesAndLands(_LandingAgent):
        async def switch_to(self, seq, *, before_start=None, **_kw):
            before_start()
            self.switches.append(seq)
            self.take_off()
            self.airborne_wall_s = d.wall()
            await asyncio.sleep(0.05)  # the look, flown while the ACK was awaited
            self.ground, self.tel.armed, self.tel.rel_alt_m = True, False, 0.0

    try:
        for v in d.vehicles.values():
            v.agent = _FliesAndLands((0.0, 2.0))
            v.agent.ground, v.agent.tel.armed, v.agent.tel.rel_alt_m = True, False, 0.0
        asyncio.run(d._step(700.0, set()))
        assert all(len(v.agent.switches) == 1 for v in d.vehicles.values())
        assert all(v.home and v.phase == "landed" for v in d.vehicles.values())
    finally:
        d.store.close()


def test_a_new_mission_item_is_stored_at_once_whatever_the_position_rate(tmp_path):
    """CI (a loaded machine): a daemon stopped mid-scan had stored item 5 while the vehicle was on
    its way to item 6 -- positions are stored at most ten a second and MISSION_CURRENT came between
    two of them -- so the restart re-flew one leg more than it had to. The item is stored as it
    changes."""
    from tests.uavloc_gcs.service.test_vehicle_agent import _Link, _current
    from uavloc_gcs.dialect import mavlink as mav
    from uavloc_gcs.service.vehicle import VehicleAgent

    sc = small_scenario()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:26990")], DaemonOptions(store_path=tmp_path / "s.sqlite"), policy=_Policy())
    d.store = Store(tmp_path / "s.sqlite")
    clock = [100.0]
    d.wall = lambda: clock[0]
    link = _Link()
    agent = VehicleAgent(1, link, d.frame, autopilot="ardupilot", epoch_unix_s=lambda: 0.0,
                         on_position=d._on_position, on_mission_seq=d._on_mission_seq, wall=lambda: clock[0])
    d.vehicles[1].agent = agent
    try:
        link.feed(_current(5, mav.MISSION_STATE_ACTIVE))  # no position yet: nothing to store
        link.feed(mav.MAVLink_global_position_int_message(1000, 426250000, 132830000, 0, 60000, 0, 0, 0, 0))
        clock[0] = 100.03
        link.feed(_current(6, mav.MISSION_STATE_ACTIVE))  # 30 ms after the last row
        link.feed(_current(6, mav.MISSION_STATE_ACTIVE))  # unchanged: no row
        clock[0] = 100.06
        link.feed(mav.MAVLink_global_position_int_message(1060, 426250000, 132830100, 0, 60000, 0, 0, 0, 0))
        d.store.flush()
        with StoreReader(tmp_path / "s.sqlite") as rd:
            seqs = [s for (s,) in rd._conn.execute("SELECT mission_seq FROM telemetry ORDER BY rowid")]
            assert rd.last_mission_seq() == {1: 6}
        assert seqs == [5, 6]  # the position row, then the item as it changed; the next position waits
    finally:
        d.store.close()


def test_without_a_geofence_looks_stay_inside_the_area_plus_the_stated_margin(tmp_path):
    """Issue 42 item 5: with no geofence in the scenario, looks left the field world's area by up to
    111 m (the policy keeps look points within the area grown by the hearing range). The area plus
    area.default_geofence_m is the fence now: a look planned 100 m north of the area is flown at
    most default_geofence_m - geofence_margin_m beyond it, and the daemon's log says which fence."""
    from shapely.geometry import Point, Polygon

    from uavloc_gcs import geofence

    d, _policy = _daemon(tmp_path)
    sc = d.sc
    area = Polygon(sc.area_xy_m())
    north = float(np.max(sc.area_xy_m()[:, 1]))
    try:
        v = d.vehicles[1]
        asyncio.run(d._upload_look(v, np.array([[200.0, north + 100.0]]), (7,)))
        items = v.agent.uploads[-1]
        pts = [d.frame.to_local(it.x / 1e7, it.y / 1e7) for it in items if it.command == 16 and it.x]
        beyond = max(area.distance(Point(float(e), float(n))) for e, n in pts)
        allowed = sc.area.default_geofence_m - sc.area.geofence_margin_m
        assert 0.0 < beyond <= allowed + 0.5, (beyond, pts)
        assert "No geofence given: the search area plus 50 m" in geofence.describe(sc)
    finally:
        d.store.close()
