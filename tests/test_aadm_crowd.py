"""The emulator under abuse: a crowd of idle connections, spoofed or garbage telemetry.

Loopback only, port 0; the crowd comes from other loopback addresses (127.0.0.2 ...), as
other machines on the experiment network would.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from conftest import two_towers
from skymule.aadm import net, protocol
from skymule.aadm.agent import AadmAgent, fly_tcp
from skymule.aadm.controller import ControllerCore, RunningController, serve_controller
from skymule.aadm.loopback import kinematic_vehicle
from skymule.aadm.towers import TowerRadio, ask_tower, serve_towers
from skymule.policies import make_policy
from skymule.scenario import load_scenario
from skymule.world import Mission, build_mission

SMALL = two_towers("aadm-crowd", 40, (40, 30))


@pytest.fixture
def small(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


@pytest.fixture(autouse=True)
def _no_server_left_behind() -> Iterator[None]:
    yield
    assert not [t for t in threading.enumerate() if t.name in ("aadm-controller", "aadm-towers")]


def _fly(small: Path, crowd_per_port: int) -> tuple[ControllerCore, float]:
    scenario = load_scenario(str(small))
    mission = build_mission(scenario)
    agent = AadmAgent(mission, make_policy(scenario.policy))
    vehicle = kinematic_vehicle(agent)
    core = ControllerCore(mission, clock="poll")
    idle: list[socket.socket] = []
    with serve_controller(core) as server:
        try:
            for port in (server.port, server.telemetry_port):
                for k in range(crowd_per_port):  # 25 addresses, 4 connections each
                    source = f"127.0.0.{2 + k // 4}"
                    idle.append(socket.create_connection((server.host, port), 10, (source, 0)))
            started = time.monotonic()
            record = fly_tcp(
                agent,
                vehicle,
                server.host,
                server.port,
                server.telemetry_port,
                pace_s=0.0,
                altitude_m=30.0,
            )
            elapsed = time.monotonic() - started
        finally:
            for sock in idle:
                sock.close()
    assert not vehicle.armed and record.end_distance_to(agent.home_xy()) <= 0.5
    return core, elapsed


def test_the_uav_scores_beside_200_idle_connections_as_alone(
    small: Path, caplog: pytest.LogCaptureFixture
) -> None:
    alone, _ = _fly(small, 0)
    with caplog.at_level(logging.INFO, logger="skymule.aadm.net"):
        crowded, elapsed = _fly(small, 100)
    assert alone.served_polls > 5 and alone.score()["aadm_complete"]
    assert crowded.per_poll_bit == alone.per_poll_bit  # poll by poll, to the bit
    assert crowded.score() == alone.score()
    refused = [r for r in caplog.records if "refused" in r.getMessage()]
    assert refused  # the crowd filled the slots: 64 held per port, the rest closed at once
    # at most one line a second per server (two servers), whatever the crowd's size
    assert len(refused) <= 2 * (elapsed + 2), [r.getMessage() for r in refused]
    dropped = [r for r in caplog.records if "dropped" in r.getMessage()]
    assert len(dropped) <= 2 * (elapsed + 2)


UP = (0.0, 0.0, 30.0)


def _tell(server: RunningController, text: str, source: str = "127.0.0.1") -> str:
    assert server.telemetry_port is not None
    address = (server.host, server.telemetry_port)
    with socket.create_connection(address, 10, (source, 0)) as sock:
        sock.sendall(text.encode())
        return net.receive_all(sock).decode()


def _line(mission: Mission, alt: float = 30.0) -> str:
    lat, lon = mission.frame.to_latlon(0.0, 0.0)
    return f"alt:{alt},arm:1,rtl:0,land:0,lat:{float(lat)!r},lon:{float(lon)!r}"


@pytest.fixture(scope="module")
def mission() -> Mission:
    return build_mission(load_scenario("paper-sim-autonomous"))


@pytest.mark.parametrize(
    ("field", "value"),
    [("alt", "1e308"), ("alt", "-50"), ("alt", "250"), ("lat", "91"), ("lon", "-181")],
)
def test_telemetry_out_of_range_is_refused_and_claims_nothing(
    mission: Mission, field: str, value: str
) -> None:
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        bad = _line(mission).replace(f"{field}:", f"{field}:{value},x:", 1)
        answer = _tell(server, bad, "127.0.0.2")
        assert answer.startswith(f"Error: telemetry field {field}:{value}: allowed"), answer
        # garbage from another address first: the real UAV still owns the session
        assert _tell(server, _line(mission)) == protocol.NOT_STARTED
        assert core.telemetry_host == "127.0.0.1"
        assert _tell(server, _line(mission), "127.0.0.2").startswith("Error: telemetry from")
    assert core.received_mbit().sum() == 0 and core.shared_at is None


def test_towers_take_positions_only_from_the_sessions_owner(mission: Mission) -> None:
    radio = TowerRadio(mission)
    with serve_towers(radio, telemetry_port=0) as served:
        assert served.telemetry_port is not None
        address = (served.host, served.telemetry_port)

        def tell(text: str, source: str) -> str:
            with socket.create_connection(address, 10, (source, 0)) as sock:
                sock.sendall(text.encode())
                return net.receive_all(sock).decode()

        assert tell("alt:1e308,lat:1e308", "127.0.0.3").startswith("Error: telemetry field")
        assert tell(_line(mission), "127.0.0.1") == protocol.NOTHING_NEW  # the owner
        heard = [ask_tower(served.host, port, k + 1) for k, port in enumerate(served.ports)]
        lat, lon = mission.frame.to_latlon(5000.0, 5000.0)
        far = f"alt:30,arm:1,lat:{float(lat)!r},lon:{float(lon)!r}"
        assert tell(far, "127.0.0.3").startswith("Error: telemetry from 127.0.0.3")
        again = [ask_tower(served.host, port, k + 1) for k, port in enumerate(served.ports)]
    assert again == heard and max(heard) > -99
    np.testing.assert_array_less(-99.0, np.array(heard))
