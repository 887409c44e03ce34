"""The AADM controller emulator: the challenge's bytes, accounting, robustness (loopback, port 0).

The clients here are written from the protocol (:mod:`skymule.aadm.protocol` cites the
challenge's own controller and UAV-side script): bare ``snr_dd``, bare tower id, one recv for
the reply, as the challenge's comm script does.
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from conftest import preset_mission
from skymule.aadm import files, net, protocol
from skymule.aadm.controller import (
    ControllerCore,
    RunningController,
    poll_once,
    send_telemetry,
    serve_controller,
)
from skymule.aadm.protocol import Reply
from skymule.aadm.score import poll_download_bit
from skymule.flight.paths import Track
from skymule.world import Mission, mission_from_track

UP = np.array([0.0, 0.0, 30.0])  # above the launch point, above 24 m
GROUND = np.array([0.0, 0.0, 5.0])
REPORT = re.compile(
    r"^\[Controller-->UAV\] Report: ts>\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{6}, bs>(\d), "
    r"snr>(-?\d+\.\d{6}) db, rate>(\d+\.\d\d) mbps, RECV>(\d+\.\d\d) mbits$"
)


@pytest.fixture(scope="module")
def mission() -> Mission:
    return preset_mission("paper-sim-autonomous")  # 500/800/700/1000 Mbit


@pytest.fixture
def running(mission: Mission, tmp_path: Path) -> Iterator[RunningController]:
    core = ControllerCore(mission, log_path=tmp_path / "dl.csv")
    with serve_controller(core) as server:
        yield server
    assert not [t for t in threading.enumerate() if t.name == "aadm-controller"]


def at(mission: Mission, where: np.ndarray, armed: bool = True) -> str:
    """The testbed's telemetry line for a UAV at ``where`` (local metres)."""
    lat, lon = mission.frame.to_latlon(where[0], where[1])
    return f"alt:{where[2]},arm:{int(armed)},rtl:0,land:0,lat:{float(lat)!r},lon:{float(lon)!r}"


def tell(server: RunningController, text: str) -> str:
    """One telemetry message, bare (no newline) as the testbed sends it."""
    assert server.telemetry_port is not None
    with socket.create_connection((server.host, server.telemetry_port), timeout=10) as sock:
        sock.sendall(text.encode())
        return net.receive_all(sock).decode()


def raw_poll(port: int, tower: bytes = b"1", source: str = "127.0.0.1") -> tuple[str, str]:
    """A poll exactly as the challenge's comm script makes it: bare bytes, one recv each."""
    with socket.create_connection(("127.0.0.1", port), 10, (source, 0)) as sock:
        sock.sendall(b"snr_dd")
        reply = sock.recv(1024).decode()
        sock.sendall(tower)
        return reply, net.receive_all(sock).decode()


def tower(number: int) -> object:
    return lambda reply: number


def test_the_testbeds_bytes(running: RunningController, mission: Mission) -> None:
    core, port = running.core, running.port
    assert tell(running, at(mission, GROUND)) == protocol.NOT_STARTED
    reply, report = raw_poll(port)
    assert reply == (
        "[Controller-->UAV] Cannot share now. Please wait for the UAV to reach the desired "
        "altitude.;"
    )
    assert report == "[Controller-->UAV] Please wait for the UAV to reach the desired altitude."
    tell(running, at(mission, UP))
    reply, report = raw_poll(port, b"1")
    snr = mission.source.snr_db(UP[None])[0]
    shown = ",".join(f"{i + 1}:{v:.6f}" for i, v in enumerate(snr))
    assert reply == f"vol:{{'1': 500.0, '2': 800.0, '3': 700.0, '4': 1000.0}};snr:{shown}"
    got = poll_download_bit(snr[0], 500e6) / 1e6
    match = REPORT.match(report)
    assert match, report
    assert match.groups() == ("1", f"{snr[0]:.6f}", f"{got:.2f}", f"{got:.2f}")
    # the testbed prints "Download starts at ..." on its console and sends "None"
    assert tell(running, at(mission, UP)) == "None"
    assert tell(running, at(mission, UP)) == "None"
    reply, report = raw_poll(port, b"2\n")  # the testbed compares the bare bytes
    assert reply == f"download:1:{got:.2f},2:0.00,3:0.00,4:0.00;snr:{shown}"
    assert report == "Invalid BS Number"
    assert core.served_polls == 2  # the poll still counts toward t1, with nothing credited
    log = files.read_download_log(core._log_path)  # type: ignore[arg-type]
    assert list(log.time_s) == [0.0, 1.0]
    np.testing.assert_allclose(log.cumulative_mbit[:, 0], [got, got], atol=1e-6)


def test_lenient_dialect_keeps_the_old_tolerance(mission: Mission) -> None:
    core = ControllerCore(mission, dialect="lenient")
    with serve_controller(core) as server:
        assert tell(server, at(mission, UP)) == protocol.NOT_STARTED
        raw_poll(server.port, b"1")
        assert tell(server, at(mission, UP)).startswith("Download starts at 20")
        reply, report = raw_poll(server.port, b"2\n")  # a newline after the id is tolerated
        assert reply.startswith("download:") and REPORT.match(report)
        with socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
            sock.sendall(b"hello")
            assert "request 'hello' is not allowed" in net.receive_all(sock).decode()
    assert core.served_polls == 2 and core.received_mbit()[1] > 0


def test_testbed_dialect_answers_as_the_real_controller_and_warns(
    running: RunningController, mission: Mission, caplog: pytest.LogCaptureFixture
) -> None:
    core, port = running.core, running.port
    tell(running, at(mission, UP))
    with caplog.at_level("WARNING", logger="skymule.aadm.controller"):
        reply, report = raw_poll(port, b"1\n")
    # the sharing poll: volumes go out, the id with a newline downloads nothing
    assert reply.startswith("vol:") and report == "Invalid BS Number"
    assert core.received_mbit().sum() == 0 and core.served_polls == 1
    assert "would fail on the testbed: tower id '1\\n'" in caplog.text
    assert "send '1'" in caplog.text
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(b"hello")  # the testbed never reads the request: a normal poll
        reply = sock.recv(1024).decode()
        assert reply.startswith("download:None;snr:1:")  # no credit yet, as the testbed says
        sock.sendall(b"3")
        assert REPORT.match(net.receive_all(sock).decode())
    assert core.served_polls == 2 and core.received_mbit()[2] > 0


def test_newline_terminated_request_is_tolerated(running: RunningController) -> None:
    with socket.create_connection(("127.0.0.1", running.port), timeout=10) as sock:
        sock.sendall(b"snr_dd\n")
        assert sock.recv(1024).decode().startswith("[Controller-->UAV] Cannot share now")


def test_bad_input_is_answered_and_never_stops_the_server(mission: Mission) -> None:
    with serve_controller(ControllerCore(mission, dialect="lenient")) as running:
        _bad_input_is_answered(running, mission)


def _bad_input_is_answered(running: RunningController, mission: Mission) -> None:
    core, port = running.core, running.port
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(b"hello")
        assert "request 'hello' is not allowed" in net.receive_all(sock).decode()
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(b"snr_dd;pos:0,0,30")  # the old dialect: no position by request
        assert "not allowed" in net.receive_all(sock).decode()
    assert tell(running, "alt:x,arm:1").startswith("Error: telemetry field alt:'x'")
    tell(running, at(mission, UP))
    reply, report = raw_poll(port, b"7")
    assert reply.startswith("vol:") and report == "Invalid BS Number"
    assert core.served_polls == 0 and core.errors == 4
    reply, report = raw_poll(port, b"3")  # the server still serves
    assert reply.startswith("download:") and REPORT.match(report)


def test_client_disconnecting_mid_poll_costs_nothing(
    running: RunningController, mission: Mission
) -> None:
    tell(running, at(mission, UP))
    with socket.create_connection(("127.0.0.1", running.port), timeout=10) as sock:
        sock.sendall(b"snr_dd")
        assert sock.recv(1024).startswith(b"vol:")
    # closed without naming a tower: not counted
    raw_poll(running.port)
    assert running.core.served_polls == 1


def test_concurrent_polls_are_each_counted_once(
    running: RunningController, mission: Mission
) -> None:
    core, port = running.core, running.port
    tell(running, at(mission, UP))
    raw_poll(port)  # share
    errors: list[BaseException] = []

    def poll(number: int) -> None:
        try:
            raw_poll(port, str(1 + number % 4).encode())
        except BaseException as exc:
            errors.append(exc)

    # within the cap on connections from one address (the share poll's may still be closing)
    concurrent = net.MAX_PER_ADDRESS - 2
    threads = [threading.Thread(target=poll, args=(i,)) for i in range(concurrent)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert not errors
    assert core.served_polls == 1 + concurrent
    assert core.received_mbit().sum() * 1e6 == pytest.approx(sum(core.per_poll_bit))


def test_300_fast_polls_account_300_nominal_seconds(mission: Mission, tmp_path: Path) -> None:
    # polled as fast as the loopback allows (far above 10 polls/s): the accounting is per
    # poll, so 300 polls are exactly 300 s of t1 and 300 x rate(SNR) x 1 s, no wall-time drift
    core = ControllerCore(mission, log_path=tmp_path / "dl.csv")
    near_lw4 = np.array([-180.0, 600.0, 30.0])
    with serve_controller(core) as server:
        tell(server, at(mission, near_lw4))
        for _ in range(300):
            poll_once("127.0.0.1", server.port, tower(4), 4)
    snr = mission.source.snr_db(near_lw4[None])[0, 3]
    per_poll = float(poll_download_bit(snr, 1e12))
    assert per_poll > 0
    expected = min(1000e6, 300 * per_poll)
    assert core.received_mbit()[3] * 1e6 == pytest.approx(expected, rel=1e-6)
    log = files.read_download_log(tmp_path / "dl.csv")
    assert len(log.time_s) == core.served_polls
    np.testing.assert_allclose(np.diff(log.time_s), 1.0, atol=1e-6)


def test_window_and_completion_stop_serving(mission: Mission) -> None:
    core = ControllerCore(mission, np.array([0.0, 0.0, 0.0, 3.0]), window_s=5.0)
    with serve_controller(core) as server:
        tell(server, at(mission, UP))
        replies = [raw_poll(server.port, b"1") for _ in range(7)]
        score_line = tell(server, at(mission, UP))
    # tower 1 has no volume: nothing is downloaded, the window closes after 5 polls
    assert all(r.startswith("download:") for r, _ in replies[1:])
    assert all("No data left for download from BS1" in r for _, r in replies)
    assert core.stopped == "window of 5 s closed" and core.served_polls == 5
    assert score_line == "T1: 5.0 seconds, S1:0.00, S2:0.00, Score:0.00"

    done = ControllerCore(mission, np.array([1.0, 0.0, 0.0, 0.0]))
    with serve_controller(done) as server:
        tell(server, at(mission, UP))
        replies = [raw_poll(server.port, b"1") for _ in range(3)]
        score_line = tell(server, at(mission, UP))
        assert tell(server, at(mission, UP)) == "None"  # the score is told once
    assert replies[1][0].startswith("download_complete:1;snr:")  # told once, then download:
    assert replies[2][0].startswith("download:1:1.00,")
    assert replies[1][1].endswith("No data left for download from BS1")
    assert score_line == "T1: 1.00 seconds, S1:499.00, S2:100.00, Score:599.00"


def test_a_disarmed_uav_is_not_served(mission: Mission) -> None:
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        tell(server, at(mission, UP))
        raw_poll(server.port)
        landed = tell(server, at(mission, np.zeros(3), armed=False))
        reply, report = raw_poll(server.port)
    assert landed.startswith("T1: ") and core.disarmed
    assert reply.startswith("[Controller-->UAV] Cannot share now") and "wait" in report
    assert core.served_polls == 1


def test_model_source_without_telemetry_is_on_the_ground(running: RunningController) -> None:
    # no position sent: the controller cannot know the UAV is up (the testbed neither)
    for _ in range(3):
        reply, _ = raw_poll(running.port)
        assert "Cannot share now" in reply


def test_trace_source_replays_one_sample_a_poll() -> None:
    snr = np.array([[30.0, 0.0], [30.0, 0.0], [5.0, 25.0], [-99.0, 10.0]])
    z_m = np.array([0.0, 20.0, 30.0, 30.0])
    track = Track(np.column_stack([np.zeros(4), np.zeros(4), z_m]), snr, hold_at_end=False)
    core = ControllerCore(mission_from_track(track, [100, 100], n_slots=4))

    def choose(reply: Reply) -> int:
        return 1 if reply.snr_db is None else int(np.argmax(reply.snr_db)) + 1

    with serve_controller(core, telemetry_port=None) as server:
        kinds = [poll_once("127.0.0.1", server.port, choose, 2)[0].kind for _ in range(4)]
    assert kinds == ["wait", "wait", "vol", "download"]  # bare snr_dd: position from the trace
    got = core.received_mbit()
    assert got[1] == pytest.approx(5.55 * 1.4 + 1.91 * 1.4)  # 25 dB then 10 dB (CQI 8.1)


def test_a_slow_message_is_dropped_whole(mission: Mission, monkeypatch: pytest.MonkeyPatch) -> None:
    # lenient: a message is whole at its end (the testbed takes whatever one recv returns);
    # the deadline is on the whole message, not per byte: one byte every 0.2 s cannot hold
    # the connection past it
    monkeypatch.setattr(net, "MESSAGE_DEADLINE_S", 0.6)
    with serve_controller(ControllerCore(mission, dialect="lenient")) as running:
        _slow_message_dropped(running)


def _slow_message_dropped(running: RunningController) -> None:
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", running.port), timeout=10) as sock:
        for byte in b"snr_d":
            try:
                sock.sendall(bytes([byte]))
            except OSError:
                break
            time.sleep(0.2)
        assert net.receive_all(sock) == b""  # closed without a reply
    assert time.monotonic() - started < 3.0
    assert "Cannot share now" in raw_poll(running.port)[0]


def test_connections_past_the_cap_are_closed(
    mission: Mission, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(net, "MAX_CONNECTIONS", 3)
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        idle = [socket.create_connection(("127.0.0.1", server.port), timeout=10) for _ in range(3)]
        try:
            time.sleep(0.2)  # the three hold their handler threads
            with socket.create_connection(("127.0.0.1", server.port), timeout=10) as extra:
                extra.sendall(b"snr_dd")
                assert net.receive_all(extra, 5.0) == b""  # refused: closed at once
        finally:
            for sock in idle:
                sock.close()
        time.sleep(0.2)
        assert "Cannot share now" in raw_poll(server.port)[0]


def test_the_session_belongs_to_its_uav(running: RunningController, mission: Mission) -> None:
    tell(running, at(mission, UP))
    raw_poll(running.port)  # 127.0.0.1 got the volumes: the session is its
    with socket.create_connection(("127.0.0.1", running.port), 10, ("127.0.0.2", 0)) as sock:
        sock.sendall(b"snr_dd")
        assert "this session's UAV is at 127.0.0.1" in net.receive_all(sock).decode()
    assert running.core.served_polls == 1
    lat, lon = mission.frame.to_latlon(0.0, 0.0)
    with socket.create_connection(
        ("127.0.0.1", running.telemetry_port or 0), 10, ("127.0.0.2", 0)
    ) as sock:  # a spoofed position from another address is refused
        sock.sendall(f"alt:30,arm:1,lat:{float(lat)},lon:{float(lon)}".encode())
        assert net.receive_all(sock).decode().startswith("Error: telemetry from 127.0.0.2")


def test_send_telemetry_adds_a_newline_the_controller_tolerates(
    running: RunningController, mission: Mission
) -> None:
    assert running.telemetry_port is not None
    reply = send_telemetry("127.0.0.1", running.telemetry_port, at(mission, UP))
    assert reply == protocol.NOT_STARTED
    assert "vol:" in raw_poll(running.port)[0]


def test_the_uav_is_served_right_beside_fifty_slow_clients(
    mission: Mission, monkeypatch: pytest.MonkeyPatch
) -> None:
    # 50 clients that trickle one byte at a time hold connections; the UAV's polls are served
    # and credited as without them, and the slow ones are dropped at the message deadline
    # (lenient: the testbed would take the one byte "s" as a whole request, and serve it)
    monkeypatch.setattr(net, "MESSAGE_DEADLINE_S", 1.5)
    core = ControllerCore(mission, dialect="lenient")
    quiet = ControllerCore(mission, dialect="lenient")
    slow: list[socket.socket] = []
    with serve_controller(core) as server, serve_controller(quiet) as alone:
        try:
            for _ in range(50):  # from another address (8 held, the others closed at once)
                sock = socket.create_connection(("127.0.0.1", server.port), 10, ("127.0.0.2", 0))
                sock.sendall(b"s")
                slow.append(sock)
            for target in (server, alone):
                tell(target, at(mission, UP))
                for number in (1, 2, 3, 4, 4):
                    raw_poll(target.port, str(number).encode())
            time.sleep(2.0)
            assert all(_closed(sock) for sock in slow)  # dropped
        finally:
            for sock in slow:
                sock.close()
    assert core.served_polls == quiet.served_polls == 5
    np.testing.assert_array_equal(core.received_mbit(), quiet.received_mbit())


def _closed(sock: socket.socket) -> bool:
    try:
        return net.receive_all(sock, 5.0) == b""
    except ConnectionResetError:
        return True
