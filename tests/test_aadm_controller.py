"""The AADM controller emulator: protocol, accounting, robustness (loopback, port 0)."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from skymule.aadm import files
from skymule.aadm.controller import ControllerCore, poll_once, serve_controller
from skymule.aadm.protocol import Reply
from skymule.aadm.score import poll_download_bit
from skymule.flight.paths import Track
from skymule.scenario import load_scenario
from skymule.world import Mission, build_mission, mission_from_track

UP = np.array([0.0, 0.0, 30.0])  # above the launch point, above 24 m
GROUND = np.array([0.0, 0.0, 5.0])


@pytest.fixture(scope="module")
def mission() -> Mission:
    return build_mission(load_scenario("paper-sim-autonomous"))  # 500/800/700/1000 Mbit


@pytest.fixture
def running(mission: Mission, tmp_path: Path) -> Iterator[tuple[ControllerCore, int]]:
    core = ControllerCore(mission, log_path=tmp_path / "dl.csv")
    with serve_controller(core) as server:
        yield core, server.port
    assert not [t for t in threading.enumerate() if t.name == "aadm-controller"]


def tower(number: int) -> object:
    return lambda reply: number


def test_protocol_and_accounting(running: tuple[ControllerCore, int], mission: Mission) -> None:
    core, port = running
    reply, report = poll_once("127.0.0.1", port, tower(1), GROUND)
    assert reply.kind == "wait" and "not served (volumes not shared yet)" in report
    reply, report = poll_once("127.0.0.1", port, tower(1), UP)
    assert reply.kind == "vol" and list(reply.values) == [500, 800, 700, 1000]
    assert reply.snr_db is not None
    expected = poll_download_bit(mission.source.snr_db(UP[None])[0, 0], 500e6) / 1e6
    assert report.startswith(f"report:tower 1 +{expected:.3f} Mbit")
    reply, _ = poll_once("127.0.0.1", port, tower(2), UP)
    assert reply.kind == "download"
    assert reply.values[0] == pytest.approx(expected, rel=1e-5)
    assert core.served_polls == 2
    log = files.read_download_log(core._log_path)  # type: ignore[arg-type]
    assert list(log.time_s) == [0.0, 1.0]
    assert log.cumulative_mbit[0, 0] == pytest.approx(expected, abs=1e-6)


def _raw(port: int, *lines: str) -> list[str]:
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        answers = []
        for line in lines:
            sock.sendall(line.encode())
            answers.append(sock.makefile().readline().strip())
        return answers


def test_bad_input_is_answered_and_never_stops_the_server(
    running: tuple[ControllerCore, int],
) -> None:
    core, port = running
    assert _raw(port, "hello\n")[0].startswith("error:request 'hello' is not allowed")
    assert _raw(port, "\x00\xff garbage\n")[0].startswith("error:")
    assert _raw(port, "snr_dd;pos:1,2\n")[0].startswith("error:request field pos")
    answers = _raw(port, "snr_dd;pos:0,0,30\n", "7\n")
    assert answers[0].startswith("vol:")
    assert answers[1] == "error:tower choice: tower id '7' is not allowed; allowed: 1..4"
    assert core.served_polls == 0 and core.errors == 4
    # the server still serves
    reply, report = poll_once("127.0.0.1", port, tower(3), UP)
    assert reply.kind == "download" and report.startswith("report:tower 3 +")


def test_client_disconnecting_mid_poll_costs_nothing(running: tuple[ControllerCore, int]) -> None:
    core, port = running
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(b"snr_dd;pos:0,0,30\n")
        assert sock.makefile().readline().startswith("vol:")
    # closed without naming a tower: not counted
    _, report = poll_once("127.0.0.1", port, tower(1), UP)
    assert "t1 1 s" in report and core.served_polls == 1


def test_concurrent_polls_are_each_counted_once(running: tuple[ControllerCore, int]) -> None:
    core, port = running
    poll_once("127.0.0.1", port, tower(1), UP)  # share
    errors: list[BaseException] = []

    def poll(number: int) -> None:
        try:
            poll_once("127.0.0.1", port, tower(1 + number % 4), UP)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=poll, args=(i,)) for i in range(12)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert not errors
    assert core.served_polls == 13
    assert core.received_mbit().sum() * 1e6 == pytest.approx(sum(core.per_poll_bit))


def test_300_fast_polls_account_300_nominal_seconds(mission: Mission, tmp_path: Path) -> None:
    # polled as fast as the loopback allows (far above 10 polls/s): the accounting is per
    # poll, so 300 polls are exactly 300 s of t1 and 300 x rate(SNR) x 1 s, no wall-time drift
    core = ControllerCore(mission, log_path=tmp_path / "dl.csv")
    near_lw4 = np.array([-180.0, 600.0, 30.0])
    with serve_controller(core) as server:
        for _ in range(300):
            poll_once("127.0.0.1", server.port, tower(4), near_lw4)
    snr = mission.source.snr_db(near_lw4[None])[0, 3]
    per_poll = float(poll_download_bit(snr, 1e12))
    assert per_poll > 0
    expected = min(1000e6, 300 * per_poll)
    assert core.received_mbit()[3] * 1e6 == pytest.approx(expected, rel=1e-9)
    log = files.read_download_log(tmp_path / "dl.csv")
    assert len(log.time_s) == core.served_polls
    np.testing.assert_allclose(np.diff(log.time_s), 1.0, atol=1e-6)


def test_window_and_completion_stop_serving(mission: Mission) -> None:
    core = ControllerCore(mission, np.array([0.0, 0.0, 0.0, 3.0]), window_s=5.0)
    with serve_controller(core) as server:
        replies = [poll_once("127.0.0.1", server.port, tower(1), UP) for _ in range(7)]
    # tower 1 has no volume: nothing is downloaded, the window closes after 5 polls
    assert [r.kind for r, _ in replies] == ["vol"] + ["download"] * 6
    assert "window of 5 s closed" in replies[-1][1]
    assert core.score()["aadm_t1_s"] == 5.0 and core.score()["aadm_score"] == 0.0

    done = ControllerCore(mission, np.array([1.0, 0.0, 0.0, 0.0]))
    with serve_controller(done) as server:
        replies = [poll_once("127.0.0.1", server.port, tower(1), UP) for _ in range(3)]
    assert replies[1][0].kind == "download_complete"
    assert "not served (all data downloaded)" in replies[1][1]
    assert done.score() == {
        "aadm_t1_s": 1.0,
        "aadm_s1": 499.0,
        "aadm_s2": 100.0,
        "aadm_complete": True,
        "aadm_score": 599.0,
    }


def test_disarm_stops_serving(mission: Mission) -> None:
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        poll_once("127.0.0.1", server.port, tower(1), UP)
        _, report = poll_once("127.0.0.1", server.port, tower(1), UP, armed=False)
    assert "not served (disarmed)" in report and core.served_polls == 1


def test_trace_source_replays_one_sample_a_poll() -> None:
    snr = np.array([[30.0, 0.0], [30.0, 0.0], [5.0, 25.0], [-99.0, 10.0]])
    z_m = np.array([0.0, 20.0, 30.0, 30.0])
    track = Track(np.column_stack([np.zeros(4), np.zeros(4), z_m]), snr, hold_at_end=False)
    core = ControllerCore(mission_from_track(track, [100, 100], n_slots=4))

    def choose(reply: Reply) -> int:
        assert reply.snr_db is not None
        return int(np.argmax(reply.snr_db)) + 1

    with serve_controller(core) as server:
        kinds = [poll_once("127.0.0.1", server.port, choose)[0].kind for _ in range(4)]
    assert kinds == ["wait", "wait", "vol", "download"]  # plain snr_dd: position from the trace
    got = core.received_mbit()
    assert got[1] == pytest.approx(5.55 * 1.4 + 1.91 * 1.4)  # 25 dB then 10 dB (CQI 8.1)
