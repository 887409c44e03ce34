"""The controller on the testbed's clock (``clock="wall"``), against clean-room clients.

The clients here are written from the testbed's rules (its controller's source, cited in
:mod:`skymule.aadm.protocol`), not from skymule's code: the comm script's poll (bare
``snr_dd``, one recv, 0.2 s, the bare tower id, one recv, once a second) and a telemetry
sender on its own once-a-second loop. The testbed's t1 is the time of the first telemetry
message after the download completed, minus the time the volumes were shared.
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from skymule.aadm import net, protocol
from skymule.aadm.controller import ControllerCore, RunningController, serve_controller
from skymule.scenario import load_scenario
from skymule.world import Mission, build_mission

SCORE = re.compile(r"^T1: (\S+) seconds, S1:(\S+), S2:(\S+), Score:(\S+)$")


@pytest.fixture(scope="module")
def mission() -> Mission:
    return build_mission(load_scenario("paper-sim-autonomous"))


@pytest.fixture(autouse=True)
def _no_server_left_behind() -> Iterator[None]:
    yield
    assert not [t for t in threading.enumerate() if t.name == "aadm-controller"]


def _telemetry_line(mission: Mission, armed: bool = True) -> bytes:
    lat, lon = mission.frame.to_latlon(0.0, 0.0)
    return f"alt:30.0,arm:{int(armed)},rtl:0,land:0,lat:{float(lat)!r},lon:{float(lon)!r}".encode()


def _tell(server: RunningController, line: bytes) -> str:
    assert server.telemetry_port is not None
    with socket.create_connection((server.host, server.telemetry_port), timeout=10) as sock:
        sock.sendall(line)
        return sock.recv(1024).decode()


def _poll(port: int, choose: object, pause_s: float = 0.2) -> tuple[str, str]:
    """The comm script's poll: bare bytes, one recv each, 0.2 s before the tower id."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(b"snr_dd")
        reply = sock.recv(1024).decode()
        time.sleep(pause_s)
        sock.sendall(str(choose(reply)).encode())  # type: ignore[operator]
        return reply, sock.recv(1024).decode()


def test_clean_room_client_at_real_cadence_gets_the_testbeds_t1(mission: Mission) -> None:
    volumes = np.array([7.0, 3.0, 3.0, 3.0])  # done in a few polls at the launch point
    core = ControllerCore(mission, volumes, clock="wall")
    left = volumes.copy()
    told: list[tuple[float, str]] = []  # (time sent, reply)
    done_at: list[float] = []
    shared_at: list[float] = []
    stop = threading.Event()

    def choose(reply: str) -> int:
        return int(np.argmax(left)) + 1

    with serve_controller(core) as server:

        def telemetry_loop() -> None:  # the UAV's telemetry, on its own 1-s loop
            while not stop.is_set():
                started = time.monotonic()
                told.append((started, _tell(server, _telemetry_line(mission))))
                stop.wait(max(0.0, 1.0 - (time.monotonic() - started)))

        sender = threading.Thread(target=telemetry_loop)
        sender.start()
        try:
            time.sleep(0.3)  # the telemetry put the UAV above 24 m
            for _ in range(15):
                started = time.monotonic()
                reply, report = _poll(server.port, choose)
                if reply.startswith("vol:"):
                    shared_at.append(started)
                got = protocol.parse_report(report)
                if got.served and got.tower is not None:
                    left[got.tower - 1] = volumes[got.tower - 1] - got.received_mbit
                if not done_at and np.all(left <= 1e-9):
                    done_at.append(time.monotonic())
                if any(text.startswith("T1:") for _, text in told):
                    break
                time.sleep(max(0.0, 1.0 - (time.monotonic() - started) - 0.0001))
        finally:
            stop.set()
            sender.join(timeout=10)
    assert shared_at and done_at, (told, core.received_mbit())
    scored = [(when, text) for when, text in told if text.startswith("T1:")]
    assert len(scored) == 1, told
    sent, line = scored[0]
    # the first telemetry sent after the download completed carries the score, no later one
    after = [when for when, _ in told if when >= done_at[0]]
    assert sent == after[0]
    match = SCORE.match(line)
    assert match, line
    t1 = float(match.group(1))
    expected = sent - shared_at[0]  # the testbed's rule, measured by the client
    assert abs(t1 - expected) < 0.5, (t1, expected)
    assert line == f"T1: {t1:.2f} seconds, S1:{500 - t1:.2f}, S2:100.00, Score:{600 - t1:.2f}"
    assert core.score()["aadm_t1_s"] == pytest.approx(t1, abs=0.01)
    # the testbed's "other" messages: "None" (it prints "Download starts at" on its console)
    assert {text for _, text in told if not text.startswith("T1:")} <= {
        protocol.NOT_STARTED,
        protocol.NOTHING_NEW,
    }


def test_polls_are_answered_at_most_once_a_testbed_second(mission: Mission) -> None:
    core = ControllerCore(mission, clock="wall", speed=10.0)  # 1 testbed s = 0.1 wall s
    with serve_controller(core) as server:
        _tell(server, _telemetry_line(mission))
        answered = []
        for _ in range(6):  # as fast as the client can
            _poll(server.port, lambda reply: 1, pause_s=0.0)
            answered.append(time.monotonic())
    # round k + 1 starts 1 testbed second after round k started (the first round at the
    # server's start, so the first gap may be shorter), less timer slack
    gaps = np.diff(answered)[1:]
    assert gaps.min() >= 0.09, gaps
    assert core.served_polls == 6


def test_crediting_goes_on_past_the_window_until_the_telemetry_ends_it(mission: Mission) -> None:
    core = ControllerCore(mission, clock="wall", speed=10.0, window_s=2.0)
    with serve_controller(core) as server:
        assert _tell(server, _telemetry_line(mission)) == protocol.NOT_STARTED
        for _ in range(6):  # 6 testbed seconds, past the 2-s window, no telemetry meanwhile
            _poll(server.port, lambda reply: 4, pause_s=0.0)
        assert core.served_polls == 6  # the testbed serves while the UAV has not disarmed
        line = _tell(server, _telemetry_line(mission))
        match = SCORE.match(line)
        assert match, line
        # unrounded t1 once the window closed, as the testbed prints it; S2 counts every poll
        assert re.fullmatch(r"\d+\.\d+", match.group(1)) and float(match.group(1)) > 2.0
        s2 = 100 * core.received_mbit().sum() / 3000.0
        assert match.group(3) == f"{s2:.2f}" and core.received_mbit()[3] > 0
        time.sleep(0.15)  # the controller's next round begins after the score line
        with socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
            sock.sendall(b"snr_dd")
            assert net.receive_all(sock).decode() == protocol.OFF_REPLY
    assert core.served_polls == 6


def test_a_disarm_ends_the_session_with_the_score(mission: Mission) -> None:
    core = ControllerCore(mission, clock="wall", speed=10.0)
    with serve_controller(core) as server:
        _tell(server, _telemetry_line(mission))
        for _ in range(3):
            _poll(server.port, lambda reply: 1, pause_s=0.0)
        line = _tell(server, _telemetry_line(mission, armed=False))
    match = SCORE.match(line)
    assert match and match.group(2) == "0.00", line
    assert core.disarmed and core.score()["aadm_score"] == pytest.approx(
        float(match.group(4)), abs=0.005
    )


def test_strangers_polling_flat_out_do_not_take_the_uavs_turns(mission: Mission) -> None:
    core = ControllerCore(mission, clock="wall", speed=10.0)  # 1 testbed s = 0.1 wall s
    stop = threading.Event()
    refused: list[str] = []
    with serve_controller(core) as server:
        _tell(server, _telemetry_line(mission))  # 127.0.0.1 owns the session

        def flood(source: str) -> None:
            while not stop.is_set():
                address = (server.host, server.port)
                with socket.create_connection(address, 10, (source, 0)) as sock:
                    sock.sendall(b"snr_dd")
                    refused.append(net.receive_all(sock).decode())

        strangers = [threading.Thread(target=flood, args=(f"127.0.0.{k}",)) for k in range(2, 6)]
        for stranger in strangers:
            stranger.start()
        try:
            answered = []
            for _ in range(6):
                _poll(server.port, lambda reply: 1, pause_s=0.0)
                answered.append(time.monotonic())
        finally:
            stop.set()
            for stranger in strangers:
                stranger.join(timeout=10)
    # a round each (0.1 s wall): refused before they wait for a turn, the strangers take none
    gaps = np.diff(answered)[1:]
    assert gaps.max() < 0.18, gaps
    assert refused and all("this session's UAV is at 127.0.0.1" in r for r in refused)
    assert core.served_polls == 6
