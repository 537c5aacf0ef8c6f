"""Mission clear: MISSION_CLEAR_ALL -> MISSION_ACK (devguide ``services/mission.md``, "Clear
Missions"). Re-sent after the default timeout; on an error ACK the GCS keeps its copy and the
caller gets a MissionTransferError with the MAV_MISSION_RESULT."""

from __future__ import annotations

import time

from ..errors import MissionTransferError
from ..mission import MISSION_TYPE_MISSION
from .connection import Link
from .mission_wire import ACCEPTED, DEFAULT_TIMEOUT_S, GIVE_UP_S, INVALID_SEQUENCE, for_us, result_name


async def clear_mission(link: Link, target_system: int, target_component: int, *,
                        mission_type: int = MISSION_TYPE_MISSION) -> None:
    """Remove the vehicle's mission (``mission_type`` 255 clears mission, fence and rally)."""
    request = link.mav.mission_clear_all_encode(target_system, target_component, mission_type)
    with link.subscribe("MISSION_ACK", source_system=target_system) as acks:
        await link.send(request)
        give_up_at = time.monotonic() + GIVE_UP_S
        while True:
            try:
                ack = await acks.get(DEFAULT_TIMEOUT_S)
            except TimeoutError:
                if time.monotonic() >= give_up_at:
                    raise MissionTransferError(f"no MISSION_ACK for {GIVE_UP_S:g} s", vehicle=str(target_system),
                                               operation="mission clear") from None
                await link.send(request)
                continue
            if not for_us(ack, link.mav.srcSystem) or ack.type == INVALID_SEQUENCE:
                continue
            if ack.type == ACCEPTED:
                return
            raise MissionTransferError("vehicle refused to clear its mission", vehicle=str(target_system),
                                       operation="mission clear", result=ack.type, result_name=result_name(ack.type))
