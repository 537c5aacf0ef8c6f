"""Live Bluetooth LE advertising from a Linux adapter, through bleak over BlueZ's D-Bus API.

Why bleak (hbldh/bleak, MIT, releases through 2026) and not an HCI socket: BlueZ owns the adapter
on a Linux companion computer, and a raw HCI socket would fight it for the controller (and needs
CAP_NET_RAW); bleak's scanner is the documented way in. Scanning is active with BlueZ's discovery
filter ``DuplicateData: true`` (BlueZ doc/org.bluez.Adapter.rst, SetDiscoveryFilter: "Disables
duplicate detection of advertisement data"), so that every advertisement is reported, not only the
first from each device: RSSI is what is measured, so repeats are the point.

What BlueZ hands on is not the link-layer PDU: the device's address and address type, the RSSI,
and the advertisement's fields it parsed (manufacturer data by company id, service data, ...), not
the channel or the PDU type. Each report becomes a record of uavloc's private link type 147
(LINKTYPE_USER0, :data:`~.ble.LINKTYPE_UAVLOC_BLE_SCAN`): ``address[6] BE, random u8, rssi s8``,
then the manufacturer data rebuilt as AD structures (type 0xFF, company id little-endian, data),
which :mod:`.ble_ad` reads as it reads a capture's. A known limit, stated by BlueZ: a report that
repeats the previous one's properties exactly (same RSSI, same data) may not be signalled again.

Without bleak, or without an adapter (no D-Bus system bus, no BlueZ, no ``hci0``), starting
raises :class:`~uavloc_gcs.errors.ConfigError` in one sentence; the CLI exits 2.
"""

from __future__ import annotations

import logging
import time

from ..errors import ConfigError
from .ble import LINKTYPE_UAVLOC_BLE_SCAN
from .capture import Record

log = logging.getLogger(__name__)

MAX_QUEUE = 100_000  # records held between polls; more means the loop stalled: the oldest are dropped


def _import_bleak():
    try:
        import bleak
    except ImportError:
        raise ConfigError("--ble-adapter needs the Bluetooth LE library bleak, which is not installed: "
                          "pip install 'uavloc[sense]' (or pip install bleak)", key="--ble-adapter") from None
    return bleak


def scan_record(address: str, random: bool, rssi_dbm: int, manufacturer_data: dict[int, bytes]) -> bytes:
    """The record of one scan report (see the module doc); ``address`` as 'AA:BB:CC:DD:EE:FF'."""
    ad = b"".join(bytes([3 + len(v), 0xFF, k & 0xFF, k >> 8]) + v for k, v in manufacturer_data.items()
                  if 0 <= k <= 0xFFFF and len(v) <= 252)
    return (bytes.fromhex(address.replace(":", "")) + bytes([1 if random else 0, rssi_dbm & 0xFF]) + ad)


class BleScanner:
    """A source for :mod:`.run`: ``await start()``, ``poll()`` every tick, ``await stop()``."""

    def __init__(self, adapter: str):
        self.adapter = adapter
        self._bleak = _import_bleak()
        self._queue: list[Record] = []
        self.dropped = 0
        self._scanner = None

    def _on_advertisement(self, device, adv) -> None:
        props = (getattr(device, "details", None) or {}).get("props", {}) if isinstance(
            getattr(device, "details", None), dict) else {}
        random = props.get("AddressType", "public") == "random"
        if adv.rssi is None:
            return
        data = scan_record(device.address, random, int(adv.rssi), dict(adv.manufacturer_data))
        if len(self._queue) >= MAX_QUEUE:
            self._queue.pop(0)
            self.dropped += 1
        self._queue.append((LINKTYPE_UAVLOC_BLE_SCAN, time.time(), data, False))

    async def start(self) -> None:
        bluez = {"adapter": self.adapter, "filters": {"DuplicateData": True}}
        try:
            self._scanner = self._bleak.BleakScanner(self._on_advertisement, scanning_mode="active", bluez=bluez)
            await self._scanner.start()
        except Exception as err:  # noqa: BLE001 - bleak raises D-Bus, OS and its own errors alike
            self._scanner = None
            raise ConfigError(f"cannot scan for Bluetooth LE on {self.adapter}: {_why(err)}",
                              key="--ble-adapter") from None
        log.info("scanning for Bluetooth LE advertising on %s", self.adapter)

    def poll(self) -> list[Record]:
        out, self._queue = self._queue, []
        return out

    async def stop(self) -> None:
        if self._scanner is not None:
            try:
                await self._scanner.stop()
            except Exception as err:  # noqa: BLE001 - the adapter may be gone; stopping is best effort
                log.warning("stopping the Bluetooth LE scan on %s: %s", self.adapter, _why(err))
            self._scanner = None


def _why(err: Exception) -> str:
    """One clause for why a scan could not start."""
    if isinstance(err, (FileNotFoundError, ConnectionRefusedError)):
        return "no D-Bus system bus (is BlueZ running? no Bluetooth adapter on this machine?)"
    text = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    return text.rstrip(".")
