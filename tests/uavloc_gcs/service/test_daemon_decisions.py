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

    def position_xy_m(self):
        return self.xy

    def on_ground(self):
        return False

    async def upload(self, items):
        self.uploads.append(items)

    async def switch_to(self, seq, *, on_ground):
        self.switches.append(seq)

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


def test_the_daemon_reports_a_look_when_the_vehicle_passes_it(tmp_path):
    sc = small_scenario()
    policy = _ReportingPolicy()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:26990")], DaemonOptions(store_path=tmp_path / "s.sqlite"), policy=policy)
    assert policy.look_reports  # the daemon says it will report looks
    d.store = Store(tmp_path / "s.sqlite")
    try:
        v = d.vehicles[1]
        v.agent = _Agent((50.0, 100.0))
        v.scan_done, v.phase = True, "hovering (scan done)"
        asyncio.run(d._step(100.0, {7}))
        v.ignore_seq_until_wall = 0.0
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
    sc = small_scenario()
    policy = _ReportingPolicy()
    d = Daemon(sc, [(1, "udpout:127.0.0.1:26990")], DaemonOptions(store_path=tmp_path / "s.sqlite"), policy=policy)
    d.store = Store(tmp_path / "s.sqlite")
    try:
        v = d.vehicles[1]
        v.agent = _Agent((50.0, 100.0))
        v.scan_done, v.phase = True, "hovering (scan done)"
        asyncio.run(d._step(100.0, {7}))
        v.ignore_seq_until_wall = 0.0
        v.agent.tel.mission_seq = v.look_first_seq + 1  # e.g. a MISSION_ITEM_REACHED we did not see
        d._report_looks(140.0)
        assert policy.flown == [(7, 140.0)]
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

    def silent_for_s(self):
        return 0.0

    @property
    def in_mission_mode(self):
        return self.tel.mode == "AUTO"


def test_a_vehicle_judged_landed_that_climbs_again_in_rtl_is_returning_not_home(tmp_path):
    """Under 20 % loss a retried RTL reached a fake vehicle 1.2 m above home, still armed: the
    daemon took it for landed, the vehicle climbed back, and the search ended with it "not
    confirmed returning home" after waiting the whole landing allowance. Airborne again in a
    homing mode, it is returning."""
    d, _policy = _daemon(tmp_path)
    try:
        v = d.vehicles[1]
        v.agent = _LandingAgent((0.0, 2.0))
        v.flew = True
        d._returning(v)
        v.agent.ground = True  # 1.2 m, armed, slow
        d._update_phase(v)
        assert v.home and v.phase == "landed"
        v.agent.ground = False  # climbing again in RTL
        d._update_phase(v)
        assert not v.home and v.phase == "returning"
        d.store.flush()
        with StoreReader(tmp_path / "s.sqlite") as rd:
            assert [e.text for e in rd.events("home")] == ["vehicle 1 is airborne again in RTL: returning home"]
        v.agent.tel.armed, v.agent.ground = False, True  # down and disarmed
        d._update_phase(v)
        assert v.home and v.phase == "landed"
    finally:
        d.store.close()
