"""The telemetry a fake vehicle streams, and the messages it sends on request.

Streams are scheduled in simulated time at the nominal rates of a real telemetry link, so the
byte rate per simulated second is what a radio would carry (``docs/guide/fake-vehicles.md``):
HEARTBEAT 1 Hz (optionally also from the companion, component 191), GLOBAL_POSITION_INT 5 Hz,
SYS_STATUS 1 Hz, SYSTEM_TIME 1 Hz, MISSION_CURRENT 1 Hz and on change, EXTENDED_SYS_STATE 1 Hz;
GPS_RAW_INT and BATTERY_STATUS (battery.py) when asked. MAV_CMD_SET_MESSAGE_INTERVAL changes a
stream's interval, MAV_CMD_REQUEST_MESSAGE sends a message once.
"""

from __future__ import annotations

import math

from uavloc_gcs.dialect import mavlink as mav
from uavloc_gcs.dialect.rssi import COMPANION_COMPONENT_ID

from .mission_server import Reply

DEFAULT_INTERVALS_S = {
    mav.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.2,
    mav.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    mav.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
    mav.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    mav.MAVLINK_MSG_ID_GPS_RAW_INT: math.inf,  # on request (SET_MESSAGE_INTERVAL), as the daemon asks
    mav.MAVLINK_MSG_ID_BATTERY_STATUS: math.inf,  # on request (the daemon asks when it judges a pack)
}
CAPABILITIES = (
    mav.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mav.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE | mav.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
)


class TelemetryMixin:
    """Mixed into FakeVehicle; uses its state (t_s, kin, mode, armed, mission, executor, ...)."""

    def _init_telemetry(self) -> None:
        self._out: list[Reply] = []
        self._later: list[tuple[float, Reply]] = []  # (simulated time due, reply)
        self.intervals_s = dict(DEFAULT_INTERVALS_S)
        if self.cfg.realistic_streams:  # only what the autopilot streams unasked
            self.intervals_s = {k: (v if k in self.flavour.default_streams else math.inf)
                                for k, v in self.intervals_s.items()}
        self._next_due = {mid: self.t_s if iv < math.inf else math.inf for mid, iv in self.intervals_s.items()}
        self._mission_current_due = True
        self._last_yaw_cdeg = 0
        if self.flavour.name == "ardupilot":  # ArduPilot's EKF says when it has a position
            self.say_later(max(0.0, self.boot_t_s + self.cfg.position_after_boot_s - self.t_s), mav.MAV_SEVERITY_INFO,
                           "EKF3 IMU0 is using GPS")

    def set_interval(self, msg_id: int, interval_us: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL: -1 disables, 0 restores the default, else microseconds."""
        if msg_id not in DEFAULT_INTERVALS_S:
            return False
        if interval_us == 0:
            self.intervals_s[msg_id] = DEFAULT_INTERVALS_S[msg_id]
        elif interval_us < 0:
            self.intervals_s[msg_id] = math.inf
        else:
            self.intervals_s[msg_id] = interval_us / 1e6
        self._next_due[msg_id] = self.t_s
        return True

    def _telemetry_due(self) -> None:
        for mid, interval in self.intervals_s.items():
            if self.t_s + 1e-9 >= self._next_due[mid]:
                self._next_due[mid] = self._next_due[mid] + interval if self._next_due[mid] + interval > self.t_s \
                    else self.t_s + interval
                self._out.extend(self.message_replies(mid))
                if mid == mav.MAVLINK_MSG_ID_MISSION_CURRENT:
                    self._mission_current_due = False
        if self._mission_current_due and self.intervals_s[mav.MAVLINK_MSG_ID_MISSION_CURRENT] < math.inf:
            self._mission_current_due = False
            self._out.append(self.mission_current_reply())

    def message_replies(self, msg_id: int) -> list[Reply]:
        """The message with id ``msg_id`` now (stream or MAV_CMD_REQUEST_MESSAGE); [] if unknown."""
        if msg_id == mav.MAVLINK_MSG_ID_HEARTBEAT:
            out = [self.heartbeat_reply()]
            if self.cfg.companion_heartbeat and self.cfg.rssi and self.world is not None:
                out.append(Reply(mav.MAVLink_heartbeat_message(
                    mav.MAV_TYPE_ONBOARD_CONTROLLER, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE, 3),
                    None, COMPANION_COMPONENT_ID))
            return out
        build = {
            mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._global_position_int,
            mav.MAVLINK_MSG_ID_SYS_STATUS: self._sys_status,
            mav.MAVLINK_MSG_ID_BATTERY_STATUS: self._battery_status,
            mav.MAVLINK_MSG_ID_GPS_RAW_INT: self._gps_raw_int,
            mav.MAVLINK_MSG_ID_SYSTEM_TIME: self._system_time,
            mav.MAVLINK_MSG_ID_MISSION_CURRENT: lambda: self.mission_current_reply().msg,
            mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self._extended_sys_state,
            mav.MAVLINK_MSG_ID_HOME_POSITION: self._home_position,
            mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self._autopilot_version,
        }.get(msg_id)
        return [Reply(build())] if build else []

    def text(self, severity: int, text: str) -> Reply:
        """One STATUSTEXT; a text longer than 50 bytes is the first of its chunks (see :meth:`texts`)."""
        return self.texts(severity, text)[0]

    def texts(self, severity: int, text: str) -> list[Reply]:
        """STATUSTEXT as the autopilots send it: a text longer than 50 bytes goes in chunks sharing
        a non-zero id, numbered by chunk_seq (PX4 SITL splits its arming refusal in two)."""
        raw = text.encode()
        if len(raw) <= 50:
            return [Reply(mav.MAVLink_statustext_message(severity, raw))]
        self._text_id = getattr(self, "_text_id", 0) % 0xFFFF + 1
        return [Reply(mav.MAVLink_statustext_message(severity, raw[i:i + 50], self._text_id, n))
                for n, i in enumerate(range(0, len(raw), 50))]

    @property
    def time_boot_ms(self) -> int:
        return int((self.t_s - self.boot_t_s) * 1000) & 0xFFFFFFFF

    def heartbeat_reply(self) -> Reply:
        base = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.mode in ("GUIDED", "AUTO", "RTL", "LAND", "LOITER", "TAKEOFF"):
            base |= mav.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.mode == "AUTO":
            base |= mav.MAV_MODE_FLAG_AUTO_ENABLED
        if self.armed:
            base |= mav.MAV_MODE_FLAG_SAFETY_ARMED
        status = mav.MAV_STATE_ACTIVE if self.armed else mav.MAV_STATE_STANDBY
        return Reply(mav.MAVLink_heartbeat_message(
            mav.MAV_TYPE_QUADROTOR, self.flavour.mav_autopilot, base, self.flavour.custom_mode(self.mode), status, 3))

    def mission_current_reply(self) -> Reply:
        items = self.mission.mission()
        n_real = len(items) - (1 if self.flavour.home_is_item0 and items else 0)
        ex = self.executor
        if n_real <= 0:
            state, total = mav.MISSION_STATE_NO_MISSION, 65535
        elif ex.complete or self.stale_complete:
            state, total = mav.MISSION_STATE_COMPLETE, n_real
        elif not ex.started:
            state, total = mav.MISSION_STATE_NOT_STARTED, n_real
        else:
            state = mav.MISSION_STATE_ACTIVE if self.mode == "AUTO" else mav.MISSION_STATE_PAUSED
            total = n_real
        mission_mode = 1 if self.mode == "AUTO" else (2 if ex.started and not ex.complete else 0)
        seq = ex.current if ex.carried is not None else min(ex.current, max(len(items) - 1, 0))
        return Reply(mav.MAVLink_mission_current_message(seq, total, state, mission_mode))

    def _global_position_int(self):
        p, v = self.kin.pos, self.kin.vel
        lat, lon = self.cfg.frame.to_wgs84(p[0], p[1])
        if math.hypot(v[0], v[1]) > 0.5:
            self._last_yaw_cdeg = int(round(math.degrees(math.atan2(v[0], v[1])) * 100)) % 36000
        return mav.MAVLink_global_position_int_message(
            self.time_boot_ms, int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7)),
            int(round((self.cfg.home_alt_amsl_m + p[2]) * 1000)), int(round(p[2] * 1000)),
            _i16(v[1] * 100), _i16(v[0] * 100), _i16(-v[2] * 100), self._last_yaw_cdeg)

    def _power_w(self) -> float:
        return 0.0 if self.landed else float(self.cfg.power.power_w(self.kin.ground_speed_m_s))

    def _sys_status(self):
        b = self.battery
        sensors = mav.MAV_SYS_STATUS_SENSOR_3D_GYRO | mav.MAV_SYS_STATUS_SENSOR_GPS | mav.MAV_SYS_STATUS_PREARM_CHECK
        # the pre-arm check bit healthy once it would arm (both autopilots report it so)
        health = sensors if self.ready_to_arm else sensors & ~mav.MAV_SYS_STATUS_PREARM_CHECK
        return mav.MAVLink_sys_status_message(
            sensors, sensors, health, 100, int(b.voltage_v * 1000), b.current_ca(self._power_w()),
            int(round(b.remaining * 100)), 0, 0, 0, 0, 0, 0)

    def _battery_status(self):
        return self.battery.battery_status(self._power_w(), self.params)

    def _gps_raw_int(self):
        lat, lon = self.cfg.frame.to_wgs84(self.kin.pos[0], self.kin.pos[1])
        fix = mav.GPS_FIX_TYPE_3D_FIX if self.position_ready else mav.GPS_FIX_TYPE_NO_FIX
        return mav.MAVLink_gps_raw_int_message(
            self.time_boot_ms * 1000, fix, int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7)),
            int(round((self.cfg.home_alt_amsl_m + self.kin.pos[2]) * 1000)), 80, 120,
            int(round(self.kin.ground_speed_m_s * 100)), 65535, 12 if self.position_ready else 3)

    def _system_time(self):
        unix_us = int(round((self.cfg.epoch_unix_s + self.t_s) * 1e6))
        return mav.MAVLink_system_time_message(unix_us, self.time_boot_ms)

    def _extended_sys_state(self):
        if self.landed:
            landed = mav.MAV_LANDED_STATE_ON_GROUND
        elif self.takeoff_alt_m is not None:
            landed = mav.MAV_LANDED_STATE_TAKEOFF
        elif self.mode == "LAND" or self.rtl_phase == "land":
            landed = mav.MAV_LANDED_STATE_LANDING
        else:
            landed = mav.MAV_LANDED_STATE_IN_AIR
        return mav.MAVLink_extended_sys_state_message(mav.MAV_VTOL_STATE_MC, landed)

    def _home_position(self):
        h = self._home_item()
        return mav.MAVLink_home_position_message(
            h.x, h.y, int(round(self.cfg.home_alt_amsl_m * 1000)), float(self.home_xyz_m[1]),
            float(self.home_xyz_m[0]), 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0,
            int(round((self.cfg.epoch_unix_s + self.t_s) * 1e6)))

    def _autopilot_version(self):
        return mav.MAVLink_autopilot_version_message(
            CAPABILITIES, 0x04060000, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, self.sysid)


def _i16(v: float) -> int:
    return int(max(-32768, min(32767, round(float(v)))))
