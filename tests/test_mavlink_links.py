"""Host links of the MAVLink port (``mcusim run --mavlink``, :mod:`mcusim.hostudp`) and real-time
pacing (``--realtime``, :mod:`mcusim.realtime`), with pymavlink's own connections as the host.

The simulations here run in simulated time and the host side is polled, so nothing asserts a
wall-clock rate; the pacing logic is checked against a scripted clock."""

import io
import os
import select
import subprocess
import sys

import pytest

import mcusim
from mcusim.cli import main
from mcusim.errors import ConfigError
from mcusim.hostudp import UdpEndpoint, describe, parse_link
from mcusim.realtime import run_realtime

mavutil = pytest.importorskip("pymavlink.mavutil")


def _run_until(sim, conn, kind, slices=300, step="10ms", condition=None):
    """Run the simulation in slices until the host connection has a message of ``kind``."""
    for _ in range(slices):
        sim.run(seconds=step)
        m = conn.recv_match(type=kind, blocking=False)
        while m is not None:
            if condition is None or condition(m):
                return m
            m = conn.recv_match(type=kind, blocking=False)
    raise AssertionError(f"no {kind} reached the host")


def test_udpout_reaches_a_pymavlink_udpin_listener_and_its_commands_come_back():
    host = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=255)
    port = host.port.getsockname()[1]
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART3", UdpEndpoint("udpout", "127.0.0.1", port))
    try:
        hb = _run_until(sim, host, "HEARTBEAT")
        assert (hb.type, hb.get_srcSystem(), hb.get_srcComponent()) == (10, 1, 1)
        host.mav.command_long_send(1, 0, 400, 0, 0, 0, 0, 0, 0, 0, 0)     # disarm: always accepted
        ack = _run_until(sim, host, "COMMAND_ACK")
        assert (ack.command, ack.result) == (400, 0)
        assert ep.injected and sim.firmware.link.rx_frames >= 1
    finally:
        ep.close()
        host.close()
        sim.close()


def test_udpin_answers_the_peer_that_spoke_first_and_drops_output_until_then():
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART3", UdpEndpoint("udpin", "127.0.0.1", 0))
    port = ep.address[1]
    host = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255)
    try:
        sim.run(seconds="0.05s")
        assert ep.dropped > 0 and ep.peer is None          # the heartbeat at boot had nowhere to go
        host.mav.heartbeat_send(6, 8, 0, 0, 0)              # a GCS heartbeat: the peer is known
        host.mav.command_long_send(1, 1, 176, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = _run_until(sim, host, "COMMAND_ACK")
        assert (ack.command, ack.result) == (176, 3)       # DO_SET_MODE: unsupported, still answered
    finally:
        ep.close()
        host.close()
        sim.close()


@pytest.mark.parametrize("spec", ["udp:127.0.0.1:14550", "udpout:127.0.0.1", "serial", "tcp:127.0.0.1:5760", ""])
def test_a_link_that_is_not_pty_udpout_or_udpin_is_refused_naming_the_forms(spec):
    with pytest.raises(ConfigError, match="expected pty, udpout:HOST:PORT or udpin:HOST:PORT"):
        parse_link(spec)


@pytest.mark.parametrize("spec,bound", [("udpout:127.0.0.1:0", "1 to 65535"), ("udpout:127.0.0.1:70000", "1 to 65535"),
                                        ("udpin:0.0.0.0:65536", "0 to 65535")])
def test_a_port_out_of_range_is_named_as_such(spec, bound):
    """Was the generic 'expected pty, udpout:HOST:PORT ...' for a well-formed link."""
    with pytest.raises(ConfigError, match=f"port {spec.rsplit(':', 1)[1]} is out of range \\({bound}"):
        parse_link(spec)


def test_mavlink_on_a_board_without_a_mavlink_firmware_is_a_usage_error(capsys):
    assert main(["run", "pro-mini", "--mavlink", "pty", "--duration", "1ms"]) == 2
    err = capsys.readouterr().err
    assert "pro-mini runs no firmware with a MAVLink link" in err and "Traceback" not in err
    assert main(["run", "ciaa-edu", "--no-firmware", "--mavlink", "pty", "--duration", "1ms"]) == 2


def test_a_udpin_port_already_taken_is_a_usage_error(capsys):
    import socket
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    try:
        port = s.getsockname()[1]
        assert main(["run", "ciaa-edu", "--mavlink", f"udpin:127.0.0.1:{port}", "--duration", "1ms"]) == 2
        assert "Address already in use" in capsys.readouterr().err
    finally:
        s.close()


class _Clock:
    """A scripted wall clock: ``per_slice`` wall seconds pass while the simulation runs a slice."""

    def __init__(self, sim, wall_per_sim_s):
        self.sim, self.k, self.t, self.slept = sim, wall_per_sim_s, 0.0, []

    def __call__(self):
        return self.sim.time_s * self.k + sum(self.slept)

    def sleep(self, s):
        self.slept.append(s)


def test_realtime_sleeps_when_the_simulation_is_ahead_and_stays_in_step():
    sim = mcusim.load("ciaa-edu")
    clock = _Clock(sim, 0.25)                   # the simulation computes 4x faster than real time
    pace = run_realtime(sim, "1s", clock=clock, sleep=clock.sleep, stream=io.StringIO())
    assert sim.time_s == pytest.approx(1.0)
    assert sum(clock.slept) == pytest.approx(0.75, abs=1e-9)     # the 0.75 s it was ahead
    assert pace.max_lag_s == pytest.approx(0.0, abs=1e-9) and "kept pace" in pace.line()


def test_realtime_reports_the_lag_when_the_simulation_is_slower_than_the_wall_clock():
    sim = mcusim.load("ciaa-edu")
    clock = _Clock(sim, 4.0)                    # 0.25x real time, as the rover on a slow host
    out = io.StringIO()
    pace = run_realtime(sim, "2s", clock=clock, sleep=clock.sleep, stream=out, report_every=1.0)
    assert not clock.slept
    assert pace.lag_s == pytest.approx(6.0) and pace.max_lag_s == pytest.approx(6.0)
    assert "behind by 6.000 s" in pace.line() and "0.250x real time" in pace.line()
    assert "s behind at simulated t =" in out.getvalue()


def test_cli_pty_link_paced_in_real_time_gives_a_pymavlink_serial_client_the_heartbeat():
    proc = subprocess.Popen([sys.executable, "-m", "mcusim", "run", "ciaa-edu", "--mavlink", "pty", "--realtime",
                             "--duration", "30s", "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 60)
        assert ready, "no pty path printed"
        line = proc.stdout.readline()
        assert line.startswith("MAVLink: /dev/")
        path = line.split()[1]
        assert os.path.exists(path)
        conn = mavutil.mavlink_connection(path, baud=57600, source_system=255)
        hb = conn.wait_heartbeat(timeout=20)
        assert hb is not None and hb.type == 10 and conn.target_system == 1
        conn.mav.command_long_send(conn.target_system, conn.target_component, 400, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=20)
        # the bench has no modules: TEMPORARILY_REJECTED while it still looks for them (~0.22 s of
        # simulated time, paced in real time here), FAILED once it has found none
        assert ack is not None and ack.command == 400 and ack.result in (1, 4)
        conn.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_with_a_mavlink_link_the_profiles_demo_command_is_not_applied(tmp_path):
    """elementall's [run.set] drives at 0.5 m/s; with --mavlink the ground station commands."""
    out = tmp_path / "s.json"
    assert main(["run", "elementall", "--mavlink", "udpin:127.0.0.1:0", "--duration", "0.3s", "-q",
                 "--summary", str(out)]) == 0
    import json
    s = json.loads(out.read_text())
    assert s["pose"]["x"] == 0.0 and s["firmware"]["watchdog_tripped"] is False


def test_a_host_that_outpaces_the_line_loses_bytes_beyond_the_rx_buffer_not_seconds_of_latency():
    """A serial bridge's receive buffer is finite: a burst larger than ``rx_buffer`` puts at most that
    many bytes on the USART's RX line, counts the rest in ``rx_dropped``, and the last reply comes
    within the buffer's line time (1024 bytes x 10 bits at 57600 baud) instead of behind the burst."""
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART3", UdpEndpoint("udpin", "127.0.0.1", 0))
    host = mavutil.mavlink_connection(f"udpout:127.0.0.1:{ep.address[1]}", source_system=255)
    try:
        sim.run(seconds="0.01s")
        sent = 0
        for n in range(200):                    # 8 kB at once: 1.4 s of line time at 57600 baud
            msg = host.mav.command_long_encode(1, 1, 31000 + n, 0, 0, 0, 0, 0, 0, 0, 0)
            buf = msg.pack(host.mav)
            host.write(buf)
            sent += len(buf)
        start = sim.kernel.now
        sim.run(seconds=1024 * 10 / 57600 + 0.05)
        taken = sum(len(d) for _, d in ep.injected)
        assert taken <= ep.rx_buffer == 1024 and ep.rx_dropped == sent - taken
        assert ep.usart.rx_pending == 0        # everything taken has been received by now
        acks = []
        while (m := host.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)) is not None:
            acks.append(m.command)              # (the host waits for datagrams already sent)
        assert acks == [31000 + n for n in range(taken // len(buf))]   # the whole frames that got in
        assert sim.kernel.now - start <= sim.timebase.ticks("0.25s")
    finally:
        ep.close()
        host.close()
        sim.close()


def test_realtime_does_not_run_faster_than_real_time_to_make_up_an_earlier_lag():
    """After a slow stretch the schedule is re-anchored: the fast stretch that follows is still paced
    1:1 (sleeping), not run flat out until the wall clock is caught up; the total lag is reported."""
    sim = mcusim.load("ciaa-edu")

    class Phases(_Clock):                       # 4x slower than real time for 1 s, then 4x faster
        def __call__(self):
            t = self.sim.time_s
            return min(t, 1.0) * 4.0 + max(0.0, t - 1.0) * 0.25 + sum(self.slept)
    clock = Phases(sim, None)
    pace = run_realtime(sim, "2s", clock=clock, sleep=clock.sleep, stream=io.StringIO())
    assert sum(clock.slept) == pytest.approx(0.75, abs=0.02)    # the second second took a wall second
    assert pace.lag_s == pytest.approx(3.0, abs=0.02) and "behind by 3.0" in pace.line()


def _ipv6_loopback():
    import socket
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as s:
            s.bind(("::1", 0))
        return True
    except OSError:
        return False


@pytest.mark.skipif(not _ipv6_loopback(), reason="no IPv6 loopback on this host")
def test_an_ipv6_address_in_brackets_is_a_udp_link_like_pymavlinks():
    import socket
    assert parse_link("udpout:[::1]:14550") == ("udpout", "[::1]", 14550)
    sim = mcusim.load("ciaa-edu")
    ep = sim.connect_serial("USART3", UdpEndpoint("udpin", "[::1]", 0))
    host = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
    host.setblocking(False)
    try:
        from pymavlink.dialects.v20 import common as ml
        mav = ml.MAVLink(None, 255, 190)
        host.sendto(mav.command_long_encode(1, 1, 31000, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav), ep.address[:2])
        got = b""
        for _ in range(100):
            sim.run(seconds="10ms")
            try:
                got += host.recv(65535)
            except BlockingIOError:
                pass
            acks = [m for m in ml.MAVLink(None).parse_buffer(got) or [] if m.get_type() == "COMMAND_ACK"]
            if acks:
                break
        assert acks and acks[0].command == 31000
        assert "UDP on [::1]:" in describe(ep)
    finally:
        ep.close()
        host.close()
        sim.close()


def test_a_run_with_a_link_reports_the_bytes_it_dropped_each_way(tmp_path, capsys):
    out = tmp_path / "s.json"
    main(["run", "ciaa-edu", "--mavlink", "udpin:127.0.0.1:0", "--duration", "50ms", "-q", "--summary", str(out)])
    assert "MAVLink link: 0 bytes from the host dropped" in capsys.readouterr().out
    import json
    link = json.loads(out.read_text())["link"]
    assert link["rx_dropped"] == 0 and link["tx_dropped"] > 0     # udpin: nobody to send to yet
