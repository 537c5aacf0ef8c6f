"""What a vehicle does when it loses its ground station, read from its parameters at start.

Every mission the daemon uploads ends in RTL, so a vehicle flying a mission comes home without the
daemon. The risk is a vehicle that is *not* flying a mission when the link goes (GUIDED or LOITER
while being armed or started, held by the operator) and whose link-loss failsafe does nothing, or
holds: it hovers until its battery failsafe. The parameters (names and values checked against the
autopilots' sources):

* ArduCopter ``FS_GCS_ENABLE``: 0 disabled; 1 RTL; 2 RTL or continue the mission in AUTO (removed in
  4.0, see FS_OPTIONS); 3 SmartRTL or RTL; 4 SmartRTL or land; 5 land; 6 DO_LAND_START or RTL;
  7 brake or land. Timeout ``FS_GCS_TIMEOUT`` [s].
* PX4 ``NAV_DLL_ACT``: 0 disabled; 1 hold; 2 return; 3 land; 5 terminate; 6 disarm. Timeout
  ``COM_DL_LOSS_T`` [s].
"""

from __future__ import annotations

from ..link.params import read_param

AP_SAFE = {1: "RTL", 2: "RTL (or continue the mission in AUTO)", 3: "SmartRTL or RTL", 4: "SmartRTL or land",
           5: "land", 6: "DO_LAND_START or RTL", 7: "brake, then land"}
PX4_SAFE = {2: "return (RTL)", 3: "land"}


def gcs_loss_warning(vehicle: int, autopilot: str, values: dict[str, float | None]) -> str | None:
    """One sentence when losing the ground station could leave the vehicle hovering (or worse);
    None when its failsafe brings it home or down. ``values``: parameter name -> value or None."""
    if autopilot == "ardupilot":
        v = values.get("FS_GCS_ENABLE")
        if v is None:
            return (f"vehicle {vehicle} did not report FS_GCS_ENABLE: its ground-station-loss failsafe is "
                    "unknown; check it is 1 (RTL) before flying out of radio range")
        if int(v) in AP_SAFE:
            return None
        return (f"vehicle {vehicle} has FS_GCS_ENABLE = {v:g} (disabled): if it loses the ground station "
                "while not flying a mission (GUIDED, LOITER) it hovers until its battery failsafe; "
                "set FS_GCS_ENABLE = 1 (RTL)")
    v = values.get("NAV_DLL_ACT")
    timeout = values.get("COM_DL_LOSS_T")
    after = f" after COM_DL_LOSS_T = {timeout:g} s" if timeout is not None else ""
    if v is None:
        return (f"vehicle {vehicle} did not report NAV_DLL_ACT: its data-link-loss failsafe is unknown; "
                "check it is 2 (return) before flying out of radio range")
    if int(v) in PX4_SAFE:
        return None
    what = {0: "is disabled: out of a mission (Hold, Position) the vehicle hovers until its battery failsafe",
            1: f"holds position{after}: the vehicle hovers until its battery failsafe",
            5: f"terminates the flight{after}: the vehicle falls",
            6: f"disarms{after}: the vehicle falls"}.get(int(v), "is not return or land")
    return f"vehicle {vehicle} has NAV_DLL_ACT = {v:g}, which on data-link loss {what}; set NAV_DLL_ACT = 2 (return)"


PARAMS = {"ardupilot": ("FS_GCS_ENABLE",), "px4": ("NAV_DLL_ACT", "COM_DL_LOSS_T")}


async def read_gcs_loss_warning(link, vehicle: int, autopilot: str) -> str | None:
    """Read the vehicle's link-loss failsafe parameters and judge them (:func:`gcs_loss_warning`)."""
    values = {name: await read_param(link, vehicle, 1, name, retries=2) for name in PARAMS[autopilot]}
    return gcs_loss_warning(vehicle, autopilot, values)
