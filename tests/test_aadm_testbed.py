"""The challenge's own software against skymule: its UAV-side bytes, its telemetry, its towers.

Every client here is written from the protocol (the challenge's comm script and controller,
cited in :mod:`skymule.aadm.protocol`), not with skymule's helpers: bare ``snr_dd``, bare ids,
one ``recv`` per reply, replies split on ``;`` with the braces and quotes dropped.
"""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from conftest import preset_mission, run_cli, start_cli
from skymule.aadm.controller import ControllerCore, serve_controller
from skymule.aadm.score import aadm_score_one
from skymule.aadm.towers import (
    TowerRadio,
    ask_tower,
    experiment_env,
    read_experiment_env,
    serve_towers,
)
from skymule.errors import SkymuleError
from skymule.scenario import load_scenario
from skymule.tasks.simulate import simulate
from skymule.world import build_mission

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "examples" / "samples" / "flight_merged.csv"
FLIGHT = (ROOT / "examples" / "paper-rw-flight1.toml").read_text()


@pytest.fixture(autouse=True)
def _no_server_left_behind() -> Iterator[None]:
    yield
    names = {t.name for t in threading.enumerate()}
    assert not names & {"aadm-controller", "aadm-towers"}


def _values(part: str) -> dict[int, float]:
    cleaned = part.replace("{", "").replace("}", "").replace("'", "")
    return {int(k): float(v) for k, v in (item.split(":") for item in cleaned.split(","))}


class ChallengeUav:
    """The challenge's UAV-side comm script, as a greedy team would drive it."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.volumes: dict[int, float] = {}
        self.downloaded: dict[int, float] = {}
        self.replies: list[str] = []

    def poll(self) -> str:
        with socket.create_connection(("127.0.0.1", self.port), timeout=10) as sock:
            sock.sendall(b"snr_dd")
            reply = sock.recv(1024).decode()
            self.replies.append(reply)
            snr: dict[int, float] = {}
            for part in reply.split(";"):
                if part.startswith("snr:"):
                    snr = _values(part[4:])
                elif part.startswith("vol:"):
                    self.volumes = _values(part[4:])
                elif part.startswith("download:"):
                    self.downloaded = _values(part[9:])
            left = {k: v - self.downloaded.get(k, 0.0) for k, v in self.volumes.items()}
            with_data = [k for k in snr if left.get(k, 0.0) > 0.005]
            choice = max(with_data, key=lambda k: snr[k]) if with_data else 1
            sock.sendall(str(choice).encode())
            return sock.recv(1024).decode()


def test_testbed_uav_over_a_recorded_flight_scores_like_skymule_run(tmp_path: Path) -> None:
    # the shipped sample flight (360 polls at 30 m; synthetic, in the merged-log format of a
    # real AADM flight), replayed by the controller one sample a poll
    path = tmp_path / "flight.toml"
    path.write_text(FLIGHT.replace('"flight1_merged.csv"', f'"{SAMPLE.as_posix()}"'))
    scenario = load_scenario(str(path)).with_policy("greedy")
    mission = build_mission(scenario)
    core = ControllerCore(mission)
    with serve_controller(core, telemetry_port=None) as server:
        uav = ChallengeUav(server.port)
        reports = [uav.poll() for _ in range(mission.n_slots)]
    assert uav.replies[0].startswith("vol:{'1': 500.0, '2': 800.0, '3': 700.0, '4': 1000.0};")
    assert all(r.startswith("[Controller-->UAV] Report: ts>") for r in reports)
    engine = simulate(scenario, mission=mission)
    total = float(mission.buffers_bit.sum())
    run = aadm_score_one(engine.log.downloaded_bit, total, mission.slot_s)
    flight = core.score()
    got, want = core.received_mbit().sum(), engine.log.downloaded_bit.sum() / 1e6
    assert got == pytest.approx(want, rel=0.02)
    assert flight["aadm_score"] == pytest.approx(run["aadm_score"], rel=0.02)


def test_testbed_uav_with_telemetry_gets_data_from_a_model(tmp_path: Path) -> None:
    mission = preset_mission("paper-sim-autonomous")
    lat, lon = mission.frame.to_latlon(100.0, -100.0)
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        assert server.telemetry_port is not None
        uav = ChallengeUav(server.port)
        for _ in range(20):
            with socket.create_connection(("127.0.0.1", server.telemetry_port), 10) as sock:
                sock.sendall(f"alt:30.0,arm:1,rtl:0,land:0,lat:{lat},lon:{lon}".encode())
                sock.recv(1024)
            uav.poll()
    assert uav.replies[0].startswith("vol:")
    assert core.received_mbit().sum() > 20 * 0.5  # every poll served, at a good SNR


@pytest.fixture
def towers_and_controller() -> Iterator[tuple[TowerRadio, tuple[int, ...], int, ControllerCore]]:
    mission = preset_mission("paper-sim-autonomous")
    core = ControllerCore(mission)
    radio = TowerRadio(mission)
    with serve_controller(core) as controller:
        assert controller.telemetry_port is not None
        forward = ("127.0.0.1", controller.telemetry_port)
        with serve_towers(radio, forward=forward) as towers:
            assert towers.telemetry_port is not None
            yield radio, towers.ports, towers.telemetry_port, core


def test_towers_answer_as_the_fixed_nodes(
    towers_and_controller: tuple[TowerRadio, tuple[int, ...], int, ControllerCore],
) -> None:
    radio, ports, telemetry_port, core = towers_and_controller
    mission = radio.mission
    where = np.array([-150.0, 300.0, 30.0])
    lat, lon = mission.frame.to_latlon(where[0], where[1])
    with socket.create_connection(("127.0.0.1", telemetry_port), timeout=10) as sock:
        sock.sendall(f"alt:30.0,arm:1,rtl:0,land:0,lat:{lat},lon:{lon}".encode())
        answer = sock.recv(1024).decode()
    assert answer == "Start time not initialized."  # the controller's reply, passed back
    assert core.telemetry_host == "127.0.0.1"  # forwarded: the controller knows the UAV too
    snr = mission.source.snr_db(where[None])[0]
    for k, port in enumerate(ports):
        with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
            sock.sendall(str(k + 1).encode())  # as the controller asks: the bare id
            reply = sock.recv(1024).decode()
        fields = reply.split(",")
        assert fields[0] == "00" and len(fields) == 3
        # the SNR as a float32 prints, the previous answer's Shannon rate in bit/s
        assert fields[1] == str(np.float32(snr[k]))
        assert fields[2] == "0.0"  # no previous answer yet
    with socket.create_connection(("127.0.0.1", ports[0]), timeout=10) as sock:
        sock.sendall(b"1")
        fields = sock.recv(1024).decode().split(",")
    shannon = 1.4e6 * np.log2(1 + 10 ** (snr[0] / 10))
    assert float(fields[2]) == pytest.approx(shannon, rel=1e-9) and "." in fields[2]
    again = ask_tower("127.0.0.1", ports[0], 1)
    assert again == pytest.approx(snr[0], abs=1e-5)


def test_experiment_env_file_points_every_node_at_loopback() -> None:
    text = experiment_env(4)
    assert 'export AP_EXPENV_SET_NODES="0 LW1 LW2 LW3 LW4"' in text
    nodes = read_experiment_env(text, "env")
    assert nodes == {name: "127.0.0.1" for name in ("0", "LW1", "LW2", "LW3", "LW4")}
    with pytest.raises(SkymuleError, match="no AP_EXPENV_EVM_<n>_XM address"):
        read_experiment_env('AP_EXPENV_SET_NODES="0 LW1"\n', "env")


# --- the commands, as processes ----------------------------------------------------------------


def _start(*args: str, cwd: Path) -> subprocess.Popen[str]:
    return start_cli("aadm", *args, cwd=cwd)


def _ports(process: subprocess.Popen[str], count: int) -> list[tuple[int, str]]:
    assert process.stdout is not None
    lines = [process.stdout.readline() for _ in range(count)]
    found = [re.match(r"listening on 127\.0\.0\.1:(\d+) \((.+)\)", line) for line in lines]
    assert all(found), lines
    return [(int(m.group(1)), m.group(2)) for m in found if m]


def _finish(process: subprocess.Popen[str]) -> str:
    try:
        out, _ = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    return out


def test_sigterm_prints_the_score_like_ctrl_c(tmp_path: Path) -> None:
    process = _start(
        "controller", "paper-sim-autonomous", "--port", "0", "--telemetry-port", "0", cwd=tmp_path
    )
    try:
        (_, polls), (_, telemetry) = _ports(process, 2)
        assert polls == "UAV polls" and "telemetry" in telemetry
        process.send_signal(signal.SIGTERM)
    finally:
        out = _finish(process)
    assert process.returncode == 0
    assert "downloaded 0.0 Mbit in 0 polls; t1 0 s; score 0.0" in out


def test_a_lost_uav_ends_the_session_marked_incomplete(tmp_path: Path) -> None:
    process = _start(
        *("controller", "paper-sim-autonomous", "--port", "0", "--telemetry-port", "0"),
        *("--agent-timeout", "1"),
        cwd=tmp_path,
    )
    try:
        (port, _), (telemetry_port, _) = _ports(process, 2)
        with socket.create_connection(("127.0.0.1", telemetry_port), timeout=10) as sock:
            sock.sendall(b"alt:30,arm:1,rtl:0,land:0,lat:35.7274824,lon:-78.6962749")
            sock.recv(1024)
        ChallengeUav(port).poll()  # one poll, then the UAV goes silent
    finally:
        out = _finish(process)
    assert process.returncode == 1
    lines = out.strip().splitlines()
    assert re.fullmatch(r"no poll from the UAV for \d+ s: the flight was cut off", lines[-2])
    assert lines[-1].startswith("downloaded ") and "in 1 polls" in lines[-1]
    assert lines[-1].endswith("(INCOMPLETE: the UAV was lost)")


def test_towers_command_serves_and_writes_the_env_file(tmp_path: Path) -> None:
    process = _start(
        *("towers", "paper-sim-autonomous", "--first-port", "0", "--telemetry-port", "0"),
        *("--forward", "", "--write-env", "env.sh"),
        cwd=tmp_path,
    )
    try:
        ports = _ports(process, 5)
        assert [what for _, what in ports] == [*(f"tower LW{k}" for k in range(1, 5)), "telemetry"]
        assert process.stdout is not None and process.stdout.readline().startswith("wrote env.sh")
        # on the ground at the launch point: the controller's question gets an answer
        assert ask_tower("127.0.0.1", ports[0][0], 1) > -99
        process.send_signal(signal.SIGTERM)
    finally:
        _finish(process)
    assert process.returncode == 0
    nodes = read_experiment_env((tmp_path / "env.sh").read_text(), "env.sh")
    assert nodes["LW1"] == nodes["LW4"] == "127.0.0.1"


def test_write_env_does_not_replace_a_file_silently(tmp_path: Path) -> None:
    env = tmp_path / "env.sh"
    env.write_text('export AP_EXPENV_SET_NODES="0 LW1"\nexport AP_EXPENV_EVM_1_XM=10.0.0.9\n')
    done = run_cli(
        *("aadm", "towers", "paper-sim-autonomous", "--first-port", "0", "--telemetry-port"),
        *("0", "--forward", "", "--write-env", str(env)),
    )
    assert done.returncode == 2 and "pass --force to replace it" in done.stderr
    assert "10.0.0.9" in env.read_text()  # untouched


def test_towers_stop_forwarding_to_a_dead_controller_port_quietly(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # the testbed's controller stops listening on its telemetry port after the score line
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        dead = probe.getsockname()[1]
    mission = build_mission(load_scenario("paper-sim-autonomous"))
    radio = TowerRadio(mission)
    lat, lon = mission.frame.to_latlon(0.0, 0.0)
    line = f"alt:30.0,arm:1,rtl:0,land:0,lat:{float(lat)!r},lon:{float(lon)!r}".encode()
    replies = []
    with (
        caplog.at_level("INFO", logger="skymule.aadm.towers"),
        serve_towers(radio, telemetry_port=0, forward=("127.0.0.1", dead)) as towers,
    ):
        assert towers.telemetry_port is not None
        for _ in range(5):
            with socket.create_connection(("127.0.0.1", towers.telemetry_port), 10) as sock:
                sock.sendall(line)
                replies.append(sock.recv(1024).decode())
        assert ask_tower("127.0.0.1", towers.ports[0], 1) > -99  # the position still counts
    assert replies == ["None"] * 5
    said = [r for r in caplog.records if "does not answer" in r.getMessage()]
    assert len(said) == 1, [r.getMessage() for r in caplog.records]
