"""One fake vehicle: modes, commands, mission execution, flight, energy and telemetry.

:class:`FakeVehicle` is transport-free: :meth:`FakeVehicle.handle` takes a decoded MAVLink message
(with its sender and the wall-clock time) and :meth:`FakeVehicle.advance` moves the simulation to a
new mission time; both return :class:`~sim_link.vehicles.mission_server.Reply` objects for the caller
(:mod:`sim_link.vehicles.fleet`) to encode and send. Physics runs in fixed steps of simulated time, so a
vehicle is deterministic given its seed and the (simulated) times commands arrive.

Modes are named the ArduPilot way (GUIDED, AUTO, RTL, LAND, LOITER, STABILIZE; TAKEOFF is PX4's
own) and encoded per flavour in HEARTBEAT.custom_mode (:mod:`sim_link.vehicles.flavour`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import COMPANION_COMPONENT_ID, RssiBatcher
from uavloc_gcs.energy import RotorcraftPower
from uavloc_gcs.geo import LocalFrame
from uavloc_gcs.mission import WireItem

from .battery import Battery
from .commands import handle_command, handle_position_target, handle_set_mode
from .executor import NAV_COMMANDS, TAKEOFF, MissionExecutor
from .flavour import Flavour
from .flight import Kinematics
from .mission_server import MissionServer, Peer, Reply
from .params import default_params, handle_param
from .auto import AutoMixin
from .telemetry import TelemetryMixin

log = logging.getLogger(__name__)

PHYSICS_DT_S = 0.05
LAND_FINAL_ALT_M = 10.0
LAND_FINAL_SPEED_M_S = 0.5
POSITION_MODES = frozenset({"GUIDED", "AUTO", "LOITER", "RTL"})  # need a position estimate (ArduCopter)


@dataclass(frozen=True)
class VehicleConfig:
    """Everything fixed about one fake vehicle. Speeds m/s, accelerations m/s^2, energy J."""

    sysid: int
    flavour: Flavour
    frame: LocalFrame  # launch point = local origin
    cruise_speed_m_s: float = 10.0  # until a DO_CHANGE_SPEED
    max_accel_m_s2: float = 5.0
    climb_rate_m_s: float = 5.0
    descent_rate_m_s: float = 3.0
    acceptance_radius_m: float = 2.0  # ArduPilot WPNAV_RADIUS
    corner_cut_m: float = 10.0  # how far a rounded pass-through corner may pass from its waypoint
    rtl_alt_m: float = 15.0  # ArduPilot RTL_ALT: return at max(current, this)
    home_alt_amsl_m: float = 0.0
    energy_budget_j: float = 250_000.0
    power: RotorcraftPower = field(default_factory=RotorcraftPower)
    slot_s: float = 0.025
    epoch_unix_s: float = 0.0
    rssi: bool = True  # generate UAVLOC_RSSI_BATCH from the world (off when a companion does it)
    # send what the real Wi-Fi sensor (uavloc_gcs.sense) makes of the radiotap frames behind the
    # world's slots, as the companion emulator's via_sense does (sensor_feed.through_sensor)
    via_sense: bool = False
    # A real companion also sends a 1 Hz HEARTBEAT (MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID)
    # from component 191. Off by default: with it, MAVSDK 4.1 on a lossy link intermittently takes
    # the system for a non-ArduPilot one and NACKs ArduPilot's MISSION_REQUEST (seen in our tests).
    companion_heartbeat: bool = False
    # Real-autopilot behaviours that need the daemon's side of issue 14 (off until it lands):
    # stream only the flavour's default_streams until SET_MESSAGE_INTERVAL asks (ArduPilot: none
    # but HEARTBEAT; PX4: no SYSTEM_TIME; measured on SITL, tests/sitl/test_behaviours.py).
    realistic_streams: bool = False
    # PX4's stale "mission complete" after an upload, as issue 14 reports it from a daemon run. NOT
    # reproduced on SITL so far: after a mission ends in the air PX4 holds (AUTO.LOITER) and a new
    # upload reports NOT_STARTED, seq 0. Kept as an option for the daemon's tests of that report.
    stale_mission_complete: bool = False
    # With FakeFleet(route=True): forward a companion's messages as the autopilot would (PX4 drops
    # ids outside its dialect). Off until the daemon takes RSSI beside the autopilot (issue 14.5).
    realistic_forwarding: bool = False
    # Refuse to arm this long after boot with the flavour's STATUSTEXT; None: the flavour's measured
    # period. Off by default: MAVSDK and the pymavlink test clients arm at once without retrying.
    arm_refused_after_boot_s: float | None = 0.0
    # ArduCopter before its EKF uses GPS: modes that need a position (GUIDED, AUTO, LOITER, RTL) are
    # refused "Mode change to Auto failed: requires position" this long after boot [simulated s],
    # while it still arms in a manual mode (issue 26: armed in STABILIZE, refused AUTO x3, disarmed).
    position_after_boot_s: float = 0.0
    # PX4 SIH's battery simulator: every disarm gives a full pack (measured on ../shared/sitl/px4).
    # Off by default: a real pack does not refill; the team swaps it (FakeFleet.swap_pack).
    refill_on_disarm: bool = False


class FakeVehicle(AutoMixin, TelemetryMixin):
    def __init__(self, cfg: VehicleConfig, world=None, *, t_s: float = 0.0):
        self.cfg = cfg
        self.flavour = cfg.flavour
        self.world = world
        self.kin = Kinematics(cfg.max_accel_m_s2, cfg.climb_rate_m_s, cfg.descent_rate_m_s)
        self.mission = MissionServer(cfg.flavour, cfg.sysid, self._home_item, self._on_mission_changed)
        self.executor = MissionExecutor(cfg.frame, cfg.home_alt_amsl_m, 1 if cfg.flavour.home_is_item0 else 0)
        self.executor.reset()
        self.batcher = RssiBatcher(cfg.frame, cfg.epoch_unix_s, cfg.slot_s)
        self.t_s = t_s
        self.battery = Battery(cfg.flavour.name, cfg.energy_budget_j, refill_on_disarm=cfg.refill_on_disarm)
        self.rssi_slots = 0
        self._boot(t_s)
        self.on_reboot_request: Callable[[], None] | None = None
        self.params = default_params(self)
        self._init_telemetry()

    def _boot(self, t_s: float) -> None:
        self.boot_t_s = t_s
        self.mission_changed_t_s = -math.inf  # the last upload's time (PX4 checks it a while: commands.py)
        self.armed = False
        self.landed = True
        self.touchdown_t_s: float | None = None  # touched down, its land detector not yet sure (_land)
        self.disarm_at_t_s: float | None = None  # landed: disarms by itself then (flavour.disarm_after_landed_s)
        self.mode = "STABILIZE" if self.flavour.name == "ardupilot" else "LOITER"
        self.speed_m_s = self.cfg.cruise_speed_m_s
        self.home_xyz_m = np.array([self.kin.pos[0], self.kin.pos[1], 0.0])
        self.hold_xyz_m = self.kin.pos.copy()
        self.takeoff_alt_m: float | None = None
        self.rtl_phase = "climb"
        self.rtl_alt = self.cfg.rtl_alt_m
        self._complete_reported = False
        self._missing_takeoff_reported = False
        self.auto_held = False
        self.stale_complete = False
        self.next_slot_t_s = math.ceil(t_s / self.cfg.slot_s - 1e-9) * self.cfg.slot_s

    # ---------------------------------------------------------------- state others read
    @property
    def sysid(self) -> int:
        return self.cfg.sysid

    @property
    def position_xyz_m(self) -> np.ndarray:
        return self.kin.pos.copy()

    @property
    def latlon_deg(self) -> tuple[float, float]:
        lat, lon = self.cfg.frame.to_wgs84(self.kin.pos[0], self.kin.pos[1])
        return float(lat), float(lon)

    @property
    def mission_items(self) -> list[WireItem]:
        return self.mission.mission()

    @property
    def current_seq(self) -> int:
        return self.executor.current

    @property
    def energy_used_j(self) -> float:
        """Energy taken from the pack it carries [J] (issue 38: a swap gives a fresh one)."""
        return self.battery.used_j

    @energy_used_j.setter
    def energy_used_j(self, value: float) -> None:
        self.battery.used_j = float(value)

    @property
    def battery_remaining_fraction(self) -> float:
        """What the autopilot reports as remaining (ArduPilot: its monitor; PX4: the pack)."""
        return self.battery.remaining

    def swap_pack(self) -> None:
        """The team puts in a fresh pack (on the ground). Without a reboot ArduPilot's monitor
        keeps its count (FakeFleet.swap_pack reboots, as a real pack swap does)."""
        self.battery.swap()

    # ---------------------------------------------------------------- inputs
    def handle(self, msg, peer: Peer, wall_s: float) -> list[Reply]:
        """React to one message from ``peer``; returns the replies."""
        name = msg.get_type()
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.sysid):
            return []
        tcomp = getattr(msg, "target_component", None)
        if name.startswith("MISSION_") and name not in ("MISSION_SET_CURRENT", "MISSION_CURRENT"):
            if tcomp not in (None, 0, 1):
                return []
            return self.mission.handle(msg, peer, wall_s)
        if tcomp not in (None, 0, 1):
            return []
        if name in ("COMMAND_LONG", "COMMAND_INT"):
            return handle_command(self, msg, peer)
        if name == "SET_MODE":
            return handle_set_mode(self, msg, peer)
        if name == "SET_POSITION_TARGET_GLOBAL_INT":
            return handle_position_target(self, msg, peer)
        if name.startswith("PARAM_"):
            return handle_param(self, msg, peer)
        if name == "MISSION_SET_CURRENT":
            if not self.set_current(int(msg.seq)):
                return [self.text(mav.MAV_SEVERITY_WARNING, f"Mission: set current {msg.seq} failed")]
            return [self.mission_current_reply()]
        return []

    def tick_protocols(self, wall_s: float) -> list[Reply]:
        return self.mission.tick(wall_s)

    # ---------------------------------------------------------------- actions (commands call these)
    def arm_refusal(self) -> tuple[int, str] | None:
        """(MAV_RESULT, STATUSTEXT) while the vehicle is not ready to arm after boot or on its pack
        (battery.py), else None."""
        wait = self.cfg.arm_refused_after_boot_s
        wait = self.flavour.arm_refused_after_boot_s if wait is None else wait
        if self.t_s - self.boot_t_s < wait:
            return self.flavour.arm_refusal
        pack = self.battery.arm_refusal(self.params)
        return None if pack is None else (self.flavour.arm_refusal[0], pack)

    @property
    def position_ready(self) -> bool:
        """Its estimator has a position (ArduCopter: "EKF3 IMU0 is using GPS"; GPS_RAW_INT 3D fix)."""
        return self.t_s - self.boot_t_s >= self.cfg.position_after_boot_s

    @property
    def ready_to_arm(self) -> bool:
        """What SYS_STATUS's pre-arm check bit reports: it would arm now (in a mode that needs a
        position it also needs one)."""
        return self.arm_refusal() is None and self.position_ready

    def arm(self, force: bool = False) -> bool:
        if self.armed:
            return True
        if self.mode in ("RTL", "LAND") and not force:
            return False
        refusal = self.arm_refusal()
        if refusal is not None and not force:
            self.say_later(self.flavour.refusal_text_delay_s, mav.MAV_SEVERITY_CRITICAL, refusal[1])
            return False
        self.armed = True
        self.disarm_at_t_s = None
        self.home_xyz_m = np.array([self.kin.pos[0], self.kin.pos[1], 0.0])
        self.hold_xyz_m = self.kin.pos.copy()
        self._out.append(self.text(mav.MAV_SEVERITY_INFO, "Arming motors"))
        return True

    def disarm(self, force: bool = False) -> bool:
        if not self.armed:
            return True
        if not self.landed and not force:
            return False
        self.armed = False
        self.disarm_at_t_s = None
        if not self.landed:  # forced disarm in the air: it falls
            self.kin.pos[2] = 0.0
            self.kin.stop()
            self.landed = True
        self.takeoff_alt_m = None
        self._out.append(self.text(mav.MAV_SEVERITY_INFO, "Disarming motors"))
        self.battery.on_disarm()
        return True

    def set_mode(self, mode: str) -> bool:
        if mode in POSITION_MODES and self.t_s - self.boot_t_s < self.cfg.position_after_boot_s:
            self._out.append(self.text(mav.MAV_SEVERITY_WARNING,
                                       f"Mode change to {mode.title()} failed: requires position"))
            return False
        if mode == "AUTO":
            items = self.mission.mission()
            if len(items) <= self.executor.first_seq:
                self._out.append(self.text(mav.MAV_SEVERITY_WARNING, "Mission: no mission"))
                return False
            if self.flavour.auto_needs_takeoff_on_ground and self.armed and self.landed \
                    and not self._starts_with_takeoff(items):
                # ArduCopter ModeAuto::init: armed and landed, AUTO is refused unless the mission
                # goes on with a take-off (mission.starts_with_takeoff_cmd); MISSION_START -> FAILED
                self._out.append(self.text(mav.MAV_SEVERITY_CRITICAL, "Auto: Missing Takeoff Cmd"))
                self._out.append(self.text(mav.MAV_SEVERITY_WARNING, "Mode change to Auto failed: init failed"))
                return False
            if self.auto_held:  # MISSION_START / AUTO after set-current on a finished mission
                self.auto_held = False
            elif self.executor.complete or self.executor.current >= len(items):
                self.executor.reset()
            self.executor.leg_start_xyz_m = None
            self.executor.started = True
        elif mode in ("RTL", "LAND") and self.landed:
            return False
        elif mode in ("GUIDED", "LOITER", "STABILIZE"):
            self.hold_xyz_m = self.kin.pos.copy()
        # A return cut short by a mode change starts afresh next time. RTL commanded in RTL
        # changes nothing: both autopilots keep descending (measured on SITL,
        # tests/sitl/test_behaviours.py::test_return_home_sent_again_while_landing).
        if mode != self.mode and mode in ("RTL", "AUTO"):
            self.rtl_phase = "climb"
        log.debug("uav%d: mode %s -> %s", self.sysid, self.mode, mode)
        self.mode = mode
        self._out.append(self.heartbeat_reply())
        return True

    def _starts_with_takeoff(self, items: list[WireItem]) -> bool:
        """Whether AUTO would begin with a take-off: the first navigation command from the item it
        would run (its current one, or the first after a finished mission), DO items skipped, as
        ArduPilot's ``AP_Mission::starts_with_takeoff_cmd`` looks from its current nav index."""
        ex = self.executor
        seq = ex.first_seq if (ex.complete or ex.current >= len(items)) else ex.current
        for it in items[seq:]:
            if it.command in NAV_COMMANDS:
                return it.command == TAKEOFF
        return False

    def takeoff(self, alt_m: float) -> bool:
        if not self.armed or not self.landed or not (alt_m > 0.0):
            return False
        self.takeoff_alt_m = float(alt_m)
        self.hold_xyz_m = np.array([self.kin.pos[0], self.kin.pos[1], float(alt_m)])
        self.landed = False
        self._out.append(self.text(mav.MAV_SEVERITY_INFO, f"Takeoff to {alt_m:.1f} m"))
        return True

    def goto(self, lat, lon, alt_m: float, *, degE7: bool) -> bool:
        """Fly to a position and hold there (GUIDED; PX4 Hold). NaN keeps a coordinate."""
        scale = 1e-7 if degE7 else 1.0
        here_lat, here_lon = self.latlon_deg
        lat_deg = here_lat if not math.isfinite(lat) else lat * scale
        lon_deg = here_lon if not math.isfinite(lon) else lon * scale
        if not (-90 <= lat_deg <= 90 and -180 <= lon_deg <= 180):
            return False
        e, n = self.cfg.frame.to_local(lat_deg, lon_deg)
        z = float(self.kin.pos[2]) if not math.isfinite(alt_m) else float(alt_m)
        self.hold_xyz_m = np.array([float(e), float(n), z])
        self.mode = "GUIDED" if self.flavour.name == "ardupilot" else "LOITER"
        return True

    def set_current(self, seq: int, reset: bool = False) -> bool:
        items = self.mission.mission()
        if seq == -1:
            seq = self.executor.current
        if self.flavour.home_is_item0 and seq == 0:
            seq = 1
        if not 0 <= seq < len(items):
            return False
        if reset:
            self.executor.jumps_done.clear()  # MAV_CMD_DO_SET_MISSION_CURRENT param2: reset DO_JUMP counters
        finished = self.executor.complete
        self.executor.reset(seq)
        if finished and self.flavour.set_current_on_finished_holds and self.mode == "AUTO":
            self.auto_held = True  # ArduPilot: AUTO holds here until MISSION_START
            self.hold_xyz_m = self.kin.pos.copy()
        return True

    def _on_mission_changed(self, mission_type: int) -> None:
        if mission_type != 0:
            return
        n = len(self.mission.stores[0])
        self.mission_changed_t_s = self.t_s
        if self.flavour.name == "px4":
            self.executor.jumps_done.clear()  # PX4 stores every uploaded DO_JUMP with its count at 0
        self.stale_complete = (self.cfg.stale_mission_complete and self.flavour.keeps_mission_complete
                               and self.executor.complete)
        if self.flavour.name == "px4" and not self.mission.busy():
            self.executor.reset()  # PX4 starts a new plan from its first item
            # ... when it is flying a mission; otherwise the new plan waits for a start
            self.executor.started = self.mode == "AUTO"
        elif self.flavour.upload_restarts_leg and self.mode == "AUTO" and not self.landed:
            self.executor.leg_start_xyz_m = None  # ArduPilot re-flies the leg it is on from here
            if self.executor.current >= n:  # ... or flies on the item it was flying
                ex = self.executor
                running = ex.started and not ex.complete and ex.flying is not None and ex.flying.seq == ex.current
                ex.carried = ex.flying if running else None
                ex.complete = ex.started and ex.carried is None
        elif self.executor.current >= n:
            self.executor.complete = self.executor.started
        self._mission_current_due = True

    def _home_item(self) -> WireItem:
        lat, lon = self.cfg.frame.to_wgs84(self.home_xyz_m[0], self.home_xyz_m[1])
        return WireItem(0, mav.MAV_FRAME_GLOBAL, 16, 0, 1, 0.0, 0.0, 0.0, 0.0,
                        int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7)), self.cfg.home_alt_amsl_m)

    def reboot(self, keep_mission: bool | None = None) -> None:
        """Power-cycle: on the ground where it is, disarmed, default mode, mission kept or lost."""
        keep = self.flavour.keep_mission_on_reboot if keep_mission is None else keep_mission
        log.info("uav%d: reboot (mission %s)", self.sysid, "kept" if keep else "lost")
        self.kin.pos[2] = 0.0
        self.kin.stop()
        if not keep:
            self.mission.stores = {0: [], 1: [], 2: []}
        self.mission.upload = None
        self.executor.reset()
        self.executor.started = False
        self.battery.on_boot()
        self._boot(self.t_s)
        self._init_telemetry()

    # ---------------------------------------------------------------- simulation
    def advance(self, t_s: float) -> list[Reply]:
        """Simulate up to mission time ``t_s`` in fixed physics steps; returns the telemetry due."""
        slot_t: list = []
        slot_xyz: list = []
        while self.t_s + PHYSICS_DT_S <= t_s + 1e-9:
            p0, t0 = self.kin.pos.copy(), self.t_s
            self._physics(PHYSICS_DT_S)
            self.t_s = t0 + PHYSICS_DT_S
            self.battery.watch(self.t_s, self.params, self.armed)
            self._slots(t0, p0, self.t_s, self.kin.pos, slot_t, slot_xyz)
            self._telemetry_due()
        self._hear(slot_t, slot_xyz)
        due = [r for t, r in self._later if t <= self.t_s]
        self._later = [(t, r) for t, r in self._later if t > self.t_s]
        out, self._out = self._out + due, []
        return out

    def say_later(self, delay_s: float, severity: int, text: str) -> None:
        """A STATUSTEXT (chunked when long) sent ``delay_s`` simulated seconds from now."""
        for reply in self.texts(severity, text):
            self._later.append((self.t_s + delay_s, reply))

    def _physics(self, dt: float) -> None:
        if self.landed:
            self.kin.stop()
            if self.armed and self.disarm_at_t_s is not None and self.t_s >= self.disarm_at_t_s - 1e-9:
                self.disarm()  # landed and left armed for the flavour's delay: it disarms by itself
                return
            if self.armed and self.mode == "AUTO" and self.executor.started:
                self._auto(dt)
            return
        if self.takeoff_alt_m is not None:
            self._fly(dt, self.hold_xyz_m, stop=True)
            self._burn(dt)
            if self.kin.pos[2] >= self.takeoff_alt_m - 0.5:
                self.takeoff_alt_m = None
                if self.flavour.name == "px4" and self.mode == "TAKEOFF":
                    self.mode = "LOITER"
            return
        if self.mode == "AUTO":
            self._auto(dt)
        elif self.mode == "RTL":  # both autopilots land at home inside RTL (the mode stays RTL)
            if self.rtl_phase == "land":
                if self._land(dt):
                    self.rtl_phase = "climb"  # the next RTL (mode or mission item) starts afresh
            elif self._rtl(dt):
                self.rtl_phase = "land"
        elif self.mode == "LAND":
            self._land(dt)
        else:
            self._fly(dt, self.hold_xyz_m, stop=True)
        self._burn(dt)

    def _fly(self, dt: float, xyz, *, stop: bool) -> None:
        self.kin.step(dt, xyz, self.speed_m_s, stop_at_target=stop)

    def _burn(self, dt: float) -> None:
        if not self.landed:
            self.battery.burn(float(self.cfg.power.power_w(self.kin.ground_speed_m_s)), dt)

    def _land(self, dt: float) -> bool:
        """Descend and touch down; True once the land detector says so (landed state ON_GROUND),
        ``flavour.land_detect_s`` after touchdown. The vehicle then disarms by itself
        ``flavour.disarm_after_landed_s`` later (:meth:`_physics`), as both autopilots do."""
        if self.kin.pos[2] > 0.0:
            self.touchdown_t_s = None
            # ArduPilot: LAND_SPEED_HIGH down to 10 m, then LAND_SPEED (0.5 m/s) to touchdown
            rate = self.cfg.descent_rate_m_s if self.kin.pos[2] > LAND_FINAL_ALT_M else LAND_FINAL_SPEED_M_S
            self.kin.descend(dt, rate)
            if self.kin.pos[2] > 0.0:
                return False
            self.touchdown_t_s = self.t_s + dt
        self.kin.stop()
        if self.touchdown_t_s is None:
            self.touchdown_t_s = self.t_s
        if self.t_s + dt - self.touchdown_t_s < self.flavour.land_detect_s - 1e-9:
            return False  # down, armed, landed state still LANDING
        self.landed = True
        self.touchdown_t_s = None
        self._out.append(self.text(mav.MAV_SEVERITY_INFO, "Landed"))
        self.disarm_at_t_s = self.t_s + dt + self.flavour.disarm_after_landed_s
        if self.flavour.disarm_after_landed_s <= 0.0:
            self.disarm()
        return True

    def _rtl(self, dt: float) -> bool:
        """Climb to max(current, RTL_ALT), fly home, then report True (caller lands)."""
        if self.rtl_phase == "climb":
            self.rtl_alt = max(float(self.kin.pos[2]), self.cfg.rtl_alt_m)
            self.rtl_phase = "return"
        home = np.array([self.home_xyz_m[0], self.home_xyz_m[1], self.rtl_alt])
        self._fly(dt, home, stop=True)
        return float(np.linalg.norm(self.kin.pos - home)) < 1.0 and self.kin.ground_speed_m_s < 0.5

    def _slots(self, t0: float, p0: np.ndarray, t1: float, p1: np.ndarray, ts: list, xyz: list) -> None:
        """Queue the RSSI slots starting in [t0, t1), positions interpolated along the physics step."""
        if self.world is None or not self.cfg.rssi:
            return
        slot = self.cfg.slot_s
        k = self.next_slot_t_s
        times = []
        while k < t1 - 1e-9:
            times.append(k)
            k = round((k + slot) / slot) * slot
        self.next_slot_t_s = k
        if not times or self.landed:
            return
        w = ((np.array(times) - t0) / (t1 - t0))[:, None]
        ts.extend(times)
        xyz.append(p0[None, :] * (1 - w) + p1[None, :] * w)

    def _hear(self, ts: list, xyz: list) -> None:
        """Ask the world what the queued slots hear (one call per advance) and batch the result."""
        if self.world is None or not self.cfg.rssi:
            return
        if ts:
            heard = self.world.hear_track(self.sysid, np.array(ts), np.vstack(xyz))
            if self.cfg.via_sense:
                from .sensor_feed import through_sensor

                heard = through_sensor(heard, self.cfg.slot_s, self.cfg.epoch_unix_s)
            self.rssi_slots += len(heard)
            for m in self.batcher.add(heard):
                self._out.append(Reply(m, None, COMPANION_COMPONENT_ID))
        for m in self.batcher.flush(now_s=self.t_s):
            self._out.append(Reply(m, None, COMPANION_COMPONENT_ID))
