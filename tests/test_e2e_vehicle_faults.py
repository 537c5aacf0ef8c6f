"""One vehicle's fault never ends the search: four fake vehicles over UDP, each fault on one of them
(lost COMMAND_ACKs, NACKed commands, every upload refused), the others finish the search."""

import pytest

from tests.e2e_helpers import small_scenario
from tests.uavloc_gcs.service.faulty_proxy import ProxyThread, Rules
from uavloc_gcs.cli._fleet import start_fleet_process
from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.service.daemon import DaemonOptions
from uavloc_gcs.service.run import run_search
from uavloc_gcs.service.store import StoreReader

pytestmark = pytest.mark.slow  # a whole search or demo: `pytest -m 'not slow and not sitl'` leaves it out


@pytest.mark.parametrize("autopilot", ["ardupilot"])
def test_lost_acks_nacks_and_a_refusing_vehicle_each_on_one_of_four(tmp_path, autopilot):
    # 25 m, not the small scenario's 15 m: with 15 m the one clean vehicle flew 9 looks at one
    # person (5,600 s of mission time, 194 s of wall time); the faults are the subject here
    sc = small_scenario(autopilot, speedup=25.0).replace(fleet={"vehicles": 4}, people={"required_accuracy_m": 25.0})
    rules = {
        1: Rules(drop_acks_for=frozenset({M.MAV_CMD_MISSION_START}), drop_ack_p=0.3, seed=1),  # lost ACKs
        2: Rules(nack_every=2),  # every other command NACKed
        3: Rules(reject_uploads=True),  # refuses every mission
        4: Rules(),  # clean
    }
    fleet = start_fleet_process(sc, speedup=sc.simulation.speedup, seed=sc.simulation.seed, base_port=0)
    try:
        ports = [int(conn.rsplit(":", 1)[1]) for _name, conn in fleet.endpoints]
        with ProxyThread([(port, vid, rules[vid]) for vid, port in enumerate(ports, start=1)]) as px:
            conns = [(vid, p.connection) for vid, p in enumerate(px.proxies, start=1)]
            opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False)
            result = run_search(sc, conns, opts, tmp_path)
    finally:
        fleet.stop()
    out = result.outcome
    # the faults really happened
    assert rules[1].counts.get(f"dropped ack {M.MAV_CMD_MISSION_START}", 0) >= 1, rules[1].counts
    assert rules[2].counts.get("nacked", 0) >= 1, rules[2].counts
    assert rules[3].counts.get("rejected uploads", 0) >= 3, rules[3].counts
    with StoreReader(tmp_path / "search.sqlite") as rd:
        events = rd.events()
    unusable = sorted({e.vehicle for e in events if e.kind == "unusable"})
    # vehicle 3 refuses everything; vehicle 2 NACKs every other command, so an exchange of several
    # commands can fail three times in lock-step and mark it unusable too (that is the rule) --
    # but never vehicles 1 and 4
    assert 3 in unusable and set(unusable) <= {2, 3}, [e.text for e in events if e.kind == "unusable"]
    started = {e.vehicle for e in events if e.kind == "start"}
    assert started == {1, 2, 4}, started
    judged = [e.text for e in events if e.kind == "retry" and e.vehicle == 1 and "does it" in e.text]
    assert judged, "vehicle 1's lost MISSION_START ACK was judged from its mode"
    assert any(e.kind == "retry" and e.vehicle == 2 for e in events), "vehicle 2's NACKs were retried"
    # the search ran to its end with the three usable vehicles, who came home
    assert any(e.kind == "end" for e in events)
    back = set(out.vehicles_home + out.vehicles_returning)
    assert back >= {1, 4} and (2 in back or 2 in unusable), out.statement
    assert out.vehicles_lost == ()
    assert out.people, out.statement


def test_a_vehicle_that_never_answers_does_not_stop_the_others(tmp_path):
    sc = small_scenario("px4", speedup=25.0)
    fleet = start_fleet_process(sc.replace(fleet={"vehicles": 1}), speedup=sc.simulation.speedup,
                                seed=sc.simulation.seed, base_port=0)
    try:
        (_n, conn), = fleet.endpoints
        dead = "udpout:127.0.0.1:9"  # nothing answers there
        opts = DaemonOptions(store_path=tmp_path / "search.sqlite", tlog_dir=tmp_path, resume=False,
                             connect_timeout_s=3.0)
        result = run_search(sc, [(1, conn), (2, dead)], opts, tmp_path)
    finally:
        fleet.stop()
    with StoreReader(tmp_path / "search.sqlite") as rd:
        events = rd.events()
    assert any(e.kind == "lost" and e.vehicle == 2 and "searching without it" in e.text for e in events)
    assert {e.vehicle for e in events if e.kind == "start"} == {1}
    out = result.outcome
    assert out.vehicles_lost == (2,) and "Lost contact with vehicle(s) 2" in out.statement
    assert 1 in out.vehicles_home + out.vehicles_returning, out.statement
    assert out.people, "vehicle 1 heard someone on its part of the scan"
