"""A fake vehicle in AUTO: the mission's items flown one by one (take-off, waypoints with their
corners, ArduCopter's loiter turns, RTL and LAND items), each reported reached as the autopilots do.

:class:`AutoMixin` is mixed into :class:`~sim_link.vehicles.vehicle.FakeVehicle` and uses its state
(``kin``, ``executor``, ``mission``, ``flavour``, ``landed``, ``rtl_phase``, ...) and its flight
primitives (``_fly``, ``_land``, ``_rtl``).
"""

from __future__ import annotations

import math

import numpy as np

from uavloc_gcs.dialect import mavlink as mav

from .executor import CIRCLE_ACCEL_M_S2, Target, corner
from .mission_server import Reply


class AutoMixin:
    """Mixed into FakeVehicle: the AUTO mode's step (:meth:`_auto`) and what it needs."""

    def _auto(self, dt: float) -> None:
        ex = self.executor
        if self.auto_held:
            if not self.landed:
                self._fly(dt, self.hold_xyz_m, stop=True)
            return
        self.stale_complete = False
        items = self.mission.mission()
        ex.advance_instant_items(items, self._set_speed)
        tgt: Target = ex.target(items, self.kin.pos)
        if tgt.kind == "done":
            if not self._complete_reported:
                self._complete_reported = True
                self.hold_xyz_m = self.kin.pos.copy()
                self._out.append(self.text(mav.MAV_SEVERITY_INFO, self.flavour.mission_done_text))
                self._mission_current_due = True
            if not self.landed:
                self._fly(dt, self.hold_xyz_m, stop=True)
            return
        self._complete_reported = False
        if self.landed and tgt.kind != "takeoff":
            if tgt.kind in ("rtl", "land"):
                self._item_done()  # already on the ground
            elif self.flavour.name == "px4":
                self.takeoff_alt_m = float(max(tgt.xyz_m[2], self.flavour.takeoff_alt_default_m))
                self.hold_xyz_m = np.array([self.kin.pos[0], self.kin.pos[1], self.takeoff_alt_m])
                self.landed = False  # PX4 climbs before flying to the first waypoint
            elif not self._missing_takeoff_reported:
                self._missing_takeoff_reported = True
                self._out.append(self.text(mav.MAV_SEVERITY_WARNING, "Auto: Missing Takeoff Cmd"))
            return
        if tgt.kind == "takeoff":
            if self.landed:
                self.landed = False
            self._fly(dt, tgt.xyz_m, stop=True)
            if self.kin.pos[2] >= tgt.xyz_m[2] - 0.5:
                self._item_done()
        elif tgt.kind == "rtl" and self.flavour.rtl_item_leaves_mission:
            # PX4 (measured on SITL): the RTL item is reported reached, the mission complete at
            # its seq, and the vehicle returns in AUTO.RTL
            self.executor.complete = True
            self._complete_reported = True
            self._mission_current_due = True
            self._out.append(Reply(mav.MAVLink_mission_item_reached_message(self.executor.current)))
            self._out.append(self.text(mav.MAV_SEVERITY_INFO, self.flavour.mission_done_text))
            self._out.append(self.text(mav.MAV_SEVERITY_INFO, "Returning to launch"))
            self.set_mode("RTL")
        elif tgt.kind == "rtl":
            if self.rtl_phase not in ("return", "land"):
                self.rtl_phase = "climb"
            if self.rtl_phase != "land":
                if self._rtl(dt):
                    self.rtl_phase = "land"  # above home: descend from the next step on
            elif self._land(dt):
                self.rtl_phase = "climb"
                self._item_done()
        elif tgt.kind == "land":
            d = np.linalg.norm(tgt.xyz_m[:2] - self.kin.pos[:2])
            if d > 1.0 and self.rtl_phase != "land":
                self._fly(dt, tgt.xyz_m, stop=True)
            else:
                self.rtl_phase = "land"
                if self._land(dt):
                    self.rtl_phase = "climb"
                    self._item_done()
        elif tgt.kind == "circle":
            self._circle(dt, tgt)
        elif tgt.stop or tgt.next_xyz_m is None:
            self._fly(dt, tgt.xyz_m, stop=True)
            if ex.reached(tgt, self.kin.pos, self.kin.ground_speed_m_s, self.t_s + dt,
                          self.cfg.acceptance_radius_m):
                self._item_done()
        else:
            self._pass_through(dt, tgt)

    def _circle(self, dt: float, tgt: Target) -> None:
        """ArduCopter's NAV_LOITER_TURNS: to the edge of the circle nearest the vehicle, then
        ``turns`` turns at min(cruise, sqrt(a r)), then the next item (not a hover at the centre)."""
        ex = self.executor
        c, r = tgt.xyz_m, tgt.radius_m
        rel = self.kin.pos[:2] - c[:2]
        d = float(np.hypot(*rel))
        u = rel / d if d > 1e-6 else np.array([1.0, 0.0])
        if ex.circled_rad is None:
            edge = np.array([c[0] + r * u[0], c[1] + r * u[1], c[2]])
            self._fly(dt, edge, stop=True)
            if np.linalg.norm(self.kin.pos - edge) < 1.0 and self.kin.ground_speed_m_s < 0.5:
                ex.circled_rad = 0.0
            return
        v = min(self.speed_m_s, math.sqrt(CIRCLE_ACCEL_M_S2 * r))
        w = (v / r) * (1.0 if tgt.ccw else -1.0)
        theta = math.atan2(u[1], u[0]) + w * dt
        xy = c[:2] + r * np.array([math.cos(theta), math.sin(theta)])
        vel = w * r * np.array([-math.sin(theta), math.cos(theta)])
        self.kin.pos = np.array([xy[0], xy[1], self.kin.pos[2]])
        self.kin.vel = np.array([vel[0], vel[1], 0.0])
        ex.circled_rad += abs(w) * dt
        if ex.circled_rad >= 2.0 * math.pi * tgt.turns - 1e-9:
            self._item_done()

    def _pass_through(self, dt: float, tgt: Target) -> None:
        """Fly towards a pass-through waypoint, slowing for the corner; it is reached where the turn
        onto the next leg begins (or when passed)."""
        a = self.kin.max_accel_m_s2
        leg_in = tgt.xyz_m[:2] - tgt.prev_xyz_m[:2]
        v_corner, lead = corner(leg_in, tgt.next_xyz_m[:2] - tgt.xyz_m[:2], self.speed_m_s, a,
                                self.cfg.corner_cut_m)
        dist = float(np.hypot(*(tgt.xyz_m[:2] - self.kin.pos[:2])))
        # brake (with 80 % of the budget) so as to arrive at the turn at the corner speed
        speed = min(self.speed_m_s, math.sqrt(v_corner**2 + 2.0 * 0.8 * a * max(0.0, dist - lead)))
        if v_corner <= 0.0:  # a reversal: stop at the waypoint, then go on
            self._fly(dt, tgt.xyz_m, stop=True)
            if dist < 0.5 and self.kin.ground_speed_m_s < 0.5:
                self._item_done()
            return
        self.kin.step(dt, tgt.xyz_m, speed, stop_at_target=False)
        accept = max(lead, self.cfg.acceptance_radius_m)
        if self.executor.reached(tgt, self.kin.pos, self.kin.ground_speed_m_s, self.t_s + dt, accept):
            self._item_done()

    def _item_done(self) -> None:
        seq = self.executor.next()
        self._out.append(Reply(mav.MAVLink_mission_item_reached_message(seq)))
        if self.flavour.name == "ardupilot":
            self._out.append(self.text(mav.MAV_SEVERITY_INFO, f"Reached command #{seq}"))
        self._mission_current_due = True
        if self.executor.current >= len(self.mission.stores[0]):
            self.executor.complete = True
            self._complete_reported = True
            self.hold_xyz_m = self.kin.pos.copy()
            self._out.append(self.text(mav.MAV_SEVERITY_INFO, self.flavour.mission_done_text))
            if self.flavour.hold_after_mission and not self.landed:
                self.mode = "LOITER"  # PX4 switches to Hold at the end of a mission in the air
                self._out.append(self.heartbeat_reply())

    def _set_speed(self, speed_m_s: float) -> None:
        self.speed_m_s = speed_m_s
