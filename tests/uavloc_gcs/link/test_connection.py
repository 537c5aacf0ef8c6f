"""Link basics: connection strings, each transport end to end, signing, stats and the .tlog."""

import asyncio
import os
import socket
import time

import pytest

from uavloc_gcs.dialect import mavlink as M
from uavloc_gcs.errors import ConfigError, FileFormatError, LinkError
from uavloc_gcs.link import iter_tlog, open_link, parse_connection, parse_signing_key

from .conftest import run

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))


@pytest.mark.parametrize("text", ["udp:1.2.3.4:5", "udpin:127.0.0.1", "udpout::14550", "tcp:host:notaport",
                                  "serial:", "bogus", "udpin:127.0.0.1:70000"])
def test_bad_connection_strings_are_config_errors(text):
    with pytest.raises(ConfigError, match="connection"):
        parse_connection(text)


def test_connection_strings_parse():
    assert parse_connection("udpin::14550").host == "127.0.0.1"  # loopback unless asked otherwise
    e = parse_connection("serial:/dev/ttyUSB0:115200")
    assert (e.device, e.baud) == ("/dev/ttyUSB0", 115200)
    assert parse_connection("serial:/dev/ttyAMA0").baud == 57600
    assert str(parse_connection("tcp:127.0.0.1:5760")) == "tcp:127.0.0.1:5760"


def test_signing_key_parsing():
    assert parse_signing_key(KEY.hex()) == KEY
    with pytest.raises(ConfigError, match="64 hex digits"):
        parse_signing_key("abcd")
    with pytest.raises(ConfigError, match="hexadecimal"):
        parse_signing_key("zz" * 32)


def test_tcp_to_unreachable_port_is_a_link_error():
    with socket.socket() as s:  # a port that nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(LinkError, match=f"tcp:127.0.0.1:{port}"):
        run(open_link(f"tcp:127.0.0.1:{port}"))


def _vehicle_codec(key=None, sysid=1):
    mav = M.MAVLink(None, sysid, 1)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)  # 10 us since 2015
    return mav


def _packet(mav, msg) -> bytes:
    buf = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return buf


def _heartbeat(mav):
    return _packet(mav, mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 0, 0, M.MAV_STATE_ACTIVE))


def _rssi(mav):
    return _packet(mav, mav.uavloc_rssi_batch_encode(1, 2, 3, 4, 0, 0, 0, 50000, 1, [0] * 12, [7] * 12,
                                                     [-7000] * 12, [3] * 12))


def test_tcp_server_and_client_links_talk_both_ways():
    async def go():
        async with await open_link("tcpin:127.0.0.1:0", source_system=1, source_component=1,
                                   heartbeat_interval_s=None) as server:
            port = server.local_address[1]
            async with await open_link(f"tcp:127.0.0.1:{port}", heartbeat_interval_s=None) as client:
                with server.subscribe("HEARTBEAT") as hb_at_server, client.subscribe("PING") as ping_at_client:
                    await client.send(client.mav.heartbeat_encode(6, 8, 0, 0, 4))
                    hb = await hb_at_server.get(2)
                    await server.send(server.mav.ping_encode(5, 6, 255, 190))
                    ping = await ping_at_client.get(2)
                return hb.get_srcSystem(), ping.get_srcSystem(), ping.seq

    assert run(go()) == (255, 1, 6)


def test_serial_link_over_a_pty():
    master, slave = os.openpty()
    try:
        async def go():
            async with await open_link(f"serial:{os.ttyname(slave)}:57600", heartbeat_interval_s=None) as link:
                with link.subscribe("HEARTBEAT") as hbs:
                    os.write(master, _heartbeat(_vehicle_codec()))
                    hb = await hbs.get(2)
                await link.send(link.mav.ping_encode(1, 2, 0, 0))
                await asyncio.sleep(0.1)
                echoed = M.MAVLink(None).parse_buffer(os.read(master, 1000))
                return hb.get_srcSystem(), [m.get_type() for m in echoed]

        import termios
        import tty
        tty.setraw(master)  # no line discipline in the way of binary data
        termios.tcflush(master, termios.TCIOFLUSH)
        assert run(go()) == (1, ["PING"])
    finally:
        os.close(master)
        os.close(slave)


def _udp_sender():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    return s


def test_signing_drops_and_counts_unsigned_and_forged_packets(tmp_path):
    tlog = tmp_path / "signed.tlog"

    async def go():
        async with await open_link("udpin:127.0.0.1:0", signing_key=KEY, tlog_path=tlog,
                                   heartbeat_interval_s=None) as link:
            addr = link.local_address
            seen = []
            with link.subscribe(callback=seen.append):
                vehicle, intruder, forger = _vehicle_codec(KEY), _vehicle_codec(None), _vehicle_codec(OTHER_KEY)
                # the forger claims a later time than the vehicle: with pymavlink's own check
                # (timestamp recorded before the signature is compared) that locked the vehicle out
                forger.signing.timestamp += 10**9
                with _udp_sender() as good, _udp_sender() as bad:
                    for _ in range(3):
                        good.sendto(_heartbeat(vehicle), addr)
                        good.sendto(_rssi(vehicle), addr)
                        bad.sendto(_rssi(intruder), addr)  # unsigned RSSI injection
                        bad.sendto(_packet(intruder, intruder.mission_ack_encode(255, 190, 0)), addr)
                        bad.sendto(_rssi(forger), addr)  # signed with the wrong key
                        replay = _heartbeat(vehicle)
                        good.sendto(replay, addr)
                        good.sendto(replay, addr)  # replayed packet: same timestamp again
                    await asyncio.sleep(0.3)
                # our own packets go out signed with the fleet key
                with _udp_sender() as listener:
                    listener.sendto(_heartbeat(vehicle), addr)
                    await asyncio.sleep(0.1)
                    await link.send(link.mav.ping_encode(0, 0, 1, 1))
                    data, _ = listener.recvfrom(1000)
            return seen, link.stats, data

    seen, stats, data = run(go())
    assert [m.get_type() for m in seen].count("UAVLOC_RSSI_BATCH") == 3
    assert "MISSION_ACK" not in {m.get_type() for m in seen}
    assert all(m._signed for m in seen)
    assert stats.unsigned_dropped == 6
    assert stats.bad_signature_dropped == 3 + 3  # forged key, and the 3 replays (stale timestamp)
    assert stats.rx_packets == len(seen) == 3 + 3 + 3 + 1
    checker = _vehicle_codec(KEY)
    checker.signing.sign_outgoing = False
    checker.signing.timestamp = 0
    (ping,) = checker.parse_buffer(data)
    assert ping.get_type() == "PING" and ping._signed
    # the .tlog holds every packet received, dropped ones included; filtering with the key
    # gives back exactly what the live link accepted
    everything = list(iter_tlog(tlog))
    assert len(everything) == 3 * 7 + 1
    accepted = [m.get_type() for _, m in iter_tlog(tlog, signing_key=KEY)]
    assert accepted == [m.get_type() for m in seen]


def test_tlog_is_readable_by_pymavlink_and_ours(tmp_path):
    from pymavlink import mavutil  # an independent reader of the same format

    tlog = tmp_path / "flight.tlog"

    async def go():
        async with await open_link("udpin:127.0.0.1:0", tlog_path=tlog, heartbeat_interval_s=None) as link:
            mav = _vehicle_codec()
            with _udp_sender() as s, link.subscribe("UAVLOC_RSSI_BATCH") as sub:
                for _ in range(5):
                    s.sendto(_heartbeat(mav) + _rssi(mav), link.local_address)
                    await sub.get(2)
                s.sendto(b"\x00garbage\x01", link.local_address)
                await asyncio.sleep(0.05)
            return link.stats

    stats = run(go())
    ours = list(iter_tlog(tlog))
    assert [m.get_type() for _, m in ours] == ["HEARTBEAT", "UAVLOC_RSSI_BATCH"] * 5
    stamps = [t for t, _ in ours]
    assert stamps == sorted(stamps) and 1.6e15 < stamps[0] < 4e15  # UNIX microseconds
    assert stats.junk_bytes == 9
    os.environ.setdefault("MAVLINK20", "1")
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    types = []
    while (m := log.recv_match()) is not None:
        types.append(m.get_type())
    assert types.count("HEARTBEAT") == 5 and len(types) == 10
    # a record cut short by a crash ends the replay quietly; junk raises a clear error
    data = tlog.read_bytes()
    (tmp_path / "cut.tlog").write_bytes(data[:-5])
    assert len(list(iter_tlog(tmp_path / "cut.tlog"))) == 9
    (tmp_path / "junk.tlog").write_bytes(b"\x00" * 8 + b"not mavlink at all")
    with pytest.raises(FileFormatError, match="junk.tlog"):
        list(iter_tlog(tmp_path / "junk.tlog"))


def test_udpin_routes_replies_to_the_peer_each_vehicle_was_heard_on():
    async def go():
        async with await open_link("udpin:127.0.0.1:0", heartbeat_interval_s=None) as link:
            with _udp_sender() as a, _udp_sender() as b, link.subscribe("HEARTBEAT") as hbs:
                a.sendto(_heartbeat(_vehicle_codec(sysid=1)), link.local_address)
                b.sendto(_heartbeat(_vehicle_codec(sysid=2)), link.local_address)
                await hbs.get(2)
                await hbs.get(2)
                await link.send(link.mav.command_long_encode(2, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
                await link.send(link.mav.heartbeat_encode(6, 8, 0, 0, 4))  # broadcast
                await asyncio.sleep(0.1)
                a.setblocking(False)
                b.setblocking(False)
                got_a = M.MAVLink(None).parse_buffer(a.recv(1000)) or []
                got_b = [M.MAVLink(None).parse_buffer(b.recv(1000))[0] for _ in range(2)]
                with pytest.raises(BlockingIOError):
                    a.recv(1000)
            return [m.get_type() for m in got_a], sorted(m.get_type() for m in got_b), link.systems

    assert run(go()) == (["HEARTBEAT"], ["COMMAND_LONG", "HEARTBEAT"], [1, 2])


def test_tcp_client_reconnects_when_the_vehicle_restarts(monkeypatch):
    from uavloc_gcs.link import transport
    monkeypatch.setattr(transport, "TCP_RECONNECT_INTERVAL_S", 0.1)

    async def go():
        server = await open_link("tcpin:127.0.0.1:0", source_system=1, source_component=1, heartbeat_interval_s=None)
        port = server.local_address[1]
        async with await open_link(f"tcp:127.0.0.1:{port}", heartbeat_interval_s=0.05) as client:
            with server.subscribe("HEARTBEAT") as hbs:
                await hbs.get(2)
            await server.close()  # SITL stops ...
            await asyncio.sleep(0.3)
            server = await open_link(f"tcpin:127.0.0.1:{port}", source_system=1, source_component=1,
                                     heartbeat_interval_s=None)  # ... and starts again on the same port
            async with server:
                with server.subscribe("HEARTBEAT") as hbs:
                    hb = await hbs.get(3)
            return hb.get_srcSystem(), client.stats.tx_packets

    sysid, sent = run(go())
    assert sysid == 255 and sent > 5


@pytest.mark.parametrize("sender_key,expected", [(None, "heard only unsigned packets"),
                                                 (OTHER_KEY, "heard only packets signed with another key")])
def test_signing_mismatch_is_named_when_no_heartbeat_arrives(sender_key, expected):
    """A vehicle that does not sign (or signs with another key) looks silent on a signed link:
    the error says why instead of only 'no heartbeat'."""

    async def go():
        async with await open_link("udpin:127.0.0.1:0", signing_key=KEY, heartbeat_interval_s=None) as link:
            vehicle = _vehicle_codec(sender_key)
            with _udp_sender() as out:
                for _ in range(4):
                    out.sendto(_heartbeat(vehicle), link.local_address)
                await asyncio.sleep(0.2)
                await link.wait_heartbeat(timeout_s=0.3)
    with pytest.raises(LinkError, match=expected):
        run(go())


def test_no_signing_diagnosis_without_a_key():
    async def go():
        async with await open_link("udpin:127.0.0.1:0", heartbeat_interval_s=None) as link:
            await link.wait_heartbeat(timeout_s=0.2)
    with pytest.raises(LinkError) as err:
        run(go())
    assert "signed" not in str(err.value)
