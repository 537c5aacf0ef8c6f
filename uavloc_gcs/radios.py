"""The radios a phone is heard by: Wi-Fi probe requests and Bluetooth LE advertising (issue 39).

A slot's radio is recorded with it (``SlotBatch.radio``: 0 Wi-Fi, 1 Bluetooth LE, as the sensor,
the telemetry and the files carry it); a BLE frame's channel is one of the three primary
advertising channels 37, 38 and 39 (Bluetooth Core 5.x, Vol 6 Part B 1.4.1) when the capture says
it (an HCI report does not: 0). One phone's Wi-Fi bursts and BLE beacons share no
content, so an identity is of one radio (the identity module never links different fingerprints).

A BLE identity differs from a Wi-Fi one in what each unit of evidence is: one beacon every
``emission.ble_interval_s`` (one frame: the scanner sits on one advertising channel and hears one
of the three copies of an advertising event), at the phone's BLE power, above the BLE scanner's own
sensitivity. :func:`ble_view` is the scenario as a BLE identity sees it: the same area, fleet and
environment, the link budget and the rate of its beacons. The estimator (one frame per unit), the
orbit design (a stream of single frames, as an on-board access point's elicited frames are) and the
POD read the BLE view for BLE identities.
"""

from __future__ import annotations

import numpy as np

BLE_ADV_CHANNELS = (37, 38, 39)
WIFI = "wifi"
BLE = "ble"
RADIO_BLE = 1  # SlotBatch.radio / the dialect's radio field (uavloc_gcs.sense.frames.RADIO_BLE)


def is_ble(slots) -> np.ndarray:
    """Per slot, whether the BLE radio heard it: a SlotBatch's ``radio`` column (RADIO_BLE, what the
    sensor records: an HCI report carries no channel); an array is taken as channels and tested
    against the advertising channels (only where the radio is not recorded: 6 GHz Wi-Fi has a
    channel 37)."""
    radio = getattr(slots, "radio", None)
    if radio is not None:
        return np.asarray(radio, dtype=int) == RADIO_BLE
    return np.isin(np.asarray(slots, dtype=int), BLE_ADV_CHANNELS)


def radio_of(slots) -> str:
    """The radio of one identity's slots: "ble" when the BLE radio heard every one."""
    b = is_ble(slots)
    return BLE if len(b) and bool(np.all(b)) else WIFI


def beacons_on(sc) -> bool:
    """Whether the scenario's phones send BLE beacons (a share of them, emission.findmy_share)."""
    return sc.emission.model == "probe-bursts" and sc.emission.findmy_share > 0


_VIEWS: dict = {}  # id(scenario) -> (scenario, its BLE view); the scenario kept so its id is not reused


def _ble_view(sc):
    from .heights import look_floor_m

    em, ch = sc.emission, sc.channel
    return sc.replace(
        channel={"reference_power_dbm": ch.reference_power_dbm + em.ble_power_offset_db,
                 "receiver_sensitivity_dbm": ch.ble_receiver_sensitivity_dbm},
        emission={"elicitation_rate_hz": 1.0 / em.ble_interval_s, "findmy_share": 0.0,
                  "mimicry_share": 1.0, "elicitation_join": "in-reach"},
        search={"look_height_m": look_floor_m(sc)})


def ble_view(sc):
    """The scenario as a BLE beacon identity sees it: the BLE link budget (reference power plus
    ``emission.ble_power_offset_db``, the BLE scanner's sensitivity), its beacons as a stream of
    single frames at 1 / ``ble_interval_s`` (the form the orbit design and the POD model give an
    on-board access point's elicited frames), and its looks at the look floor (heights.look_floor_m:
    a beacon at 0 dBm is heard from 30 m up, seldom from 60 m). Cached per scenario."""
    hit = _VIEWS.get(id(sc))
    if hit is None or hit[0] is not sc:
        if len(_VIEWS) > 16:
            _VIEWS.clear()
        hit = _VIEWS[id(sc)] = (sc, _ble_view(sc))
    return hit[1]
