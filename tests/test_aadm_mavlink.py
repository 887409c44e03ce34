"""``--vehicle mavsdk`` flies a whole AADM mission against the kinematic MAVLink test vehicle.

The test vehicle (:mod:`skymule.aadm.mavlink_vehicle`) is not PX4 or ArduPilot: it checks
that skymule's MAVSDK vehicle sends what an autopilot needs (arm, take-off, position targets,
land) and reads what it sends (position, armed state, home). PX4 SIH or ArduPilot SITL is the
real check. Needs the ``fly`` extra (MAVSDK-Python and pymavlink); without it, the one-line
errors are checked.
"""

from __future__ import annotations

import importlib
import re
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli, start_cli, two_towers
from skymule.aadm.controller import ControllerCore, serve_controller
from skymule.errors import SkymuleError
from skymule.geo import LocalFrame
from skymule.scenario import load_scenario
from skymule.world import build_mission

SCENARIO = two_towers("aadm-mavlink", 40, (40, 30))


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_without_the_fly_extra_each_part_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from skymule.aadm import mavlink_vehicle, vehicle

    real = importlib.import_module

    def missing(name: str, package: str | None = None) -> object:
        if name.split(".")[0] in ("mavsdk", "mavsdk_grpc", "pymavlink"):
            raise ImportError(name)
        return real(name, package)

    monkeypatch.setattr(importlib, "import_module", missing)
    frame = LocalFrame(35.7274824, -78.6962749)
    with pytest.raises(SkymuleError, match=r"pip install 'skymule\[fly\]'"):
        vehicle.MavsdkVehicle("udpin://0.0.0.0:14540", frame)
    with pytest.raises(SkymuleError, match=r"pip install 'skymule\[fly\]'"):
        mavlink_vehicle.MavlinkTestVehicle(frame, 14540)


def test_mavsdk_vehicle_flies_a_whole_mission(tmp_path: Path) -> None:
    pytest.importorskip("pymavlink", reason="the MAVLink test vehicle needs the fly extra")
    pytest.importorskip("mavsdk_grpc", reason="--vehicle mavsdk needs the fly extra")
    from skymule.aadm.mavlink_vehicle import MavlinkTestVehicle

    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO)
    mission = build_mission(load_scenario(str(path)))
    port = _free_udp_port()
    # 20x the wall clock: a poll every 0.05 s is a 1-s slot of flight
    autopilot = MavlinkTestVehicle(mission.frame, port, time_scale=20.0)
    core = ControllerCore(mission)
    try:
        with serve_controller(core) as server:
            done = run_cli(
                *("aadm", "agent", str(path), "--policy", "hgad", "--vehicle", "mavsdk"),
                *("--mavsdk-address", f"udpin://127.0.0.1:{port}", "--poll-s", "0.05"),
                *("--port", str(server.port), "--telemetry-port", str(server.telemetry_port)),
            )
    finally:
        autopilot.close()
    assert done.returncode == 0, done.stderr
    assert core.received_mbit().sum() > 0 and core.disarmed  # served, then the disarm ended it
    assert {400, 22, 192, 21} <= set(autopilot.commands)  # arm, take-off, reposition, land
    assert not autopilot.armed and autopilot.z == 0.0
    assert np.hypot(*autopilot.xy) <= 5.0  # the testbed's landing rule
    assert not [t for t in threading.enumerate() if t.name == "mavlink-test-vehicle"]


# A plain MAVSDK-Python script, as a team would write it (nothing of skymule in it).
PLAIN_SCRIPT = """
import asyncio, math, sys
from mavsdk_grpc import System

async def main(address, grpc_port):
    drone = System(port=grpc_port)
    await drone.connect(system_address=address)
    async for state in drone.core.connection_state():
        if state.is_connected:
            break
    async for health in drone.telemetry.health():
        if health.is_global_position_ok and health.is_home_position_ok and health.is_armable:
            break
    async for home in drone.telemetry.home():
        break
    await drone.action.arm()
    await drone.action.set_takeoff_altitude(30.0)
    await drone.action.takeoff()
    async for where in drone.telemetry.position():
        if where.relative_altitude_m > 29.0:
            break
    lat, lon = home.latitude_deg + 0.0009, home.longitude_deg  # 100 m north
    await drone.action.goto_location(lat, lon, home.absolute_altitude_m + 30.0, 0.0)
    async for where in drone.telemetry.position():
        north = (where.latitude_deg - home.latitude_deg) * 111_320.0
        if abs(north - 100.0) < 1.0:
            break
    await drone.action.land()
    async for armed in drone.telemetry.armed():
        if not armed:
            break
    print(f"landed {north:.1f} m north of home")

asyncio.run(asyncio.wait_for(main(sys.argv[1], int(sys.argv[2])), 90))
"""


def _free_tcp_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_vehicle_command_address_errors_are_one_line() -> None:
    # no extra needed: the address is checked before the vehicle starts
    done = run_cli("aadm", "vehicle", "--mavlink", "tcp://:14540")
    assert done.returncode == 2 and "expected udp://[HOST]:PORT" in done.stderr
    assert "Traceback" not in done.stderr
    from skymule.aadm.mavlink_vehicle import parse_mavlink_address

    assert parse_mavlink_address("udp://:14540") == ("127.0.0.1", 14540)
    assert parse_mavlink_address("udpin://10.0.0.2:14550") == ("10.0.0.2", 14550)


def test_a_plain_mavsdk_script_flies_the_vehicle_command(tmp_path: Path) -> None:
    pytest.importorskip("pymavlink", reason="the MAVLink test vehicle needs the fly extra")
    pytest.importorskip("mavsdk_grpc", reason="the script needs MAVSDK-Python (the fly extra)")
    port = _free_udp_port()
    vehicle = start_cli("aadm", "vehicle", "--mavlink", f"udp://:{port}", "--time-scale", "10")
    try:
        assert vehicle.stdout is not None
        assert "MAVLink test vehicle" in vehicle.stdout.readline()
        script = tmp_path / "fly.py"
        script.write_text(PLAIN_SCRIPT)
        flown = subprocess.run(
            [sys.executable, str(script), f"udp://:{port}", str(_free_tcp_port())],
            capture_output=True,
            text=True,
            timeout=120,
        )
    finally:
        vehicle.send_signal(signal.SIGTERM)
        try:
            vehicle.communicate(timeout=15)
        finally:
            if vehicle.poll() is None:
                vehicle.kill()
                vehicle.communicate()
    assert flown.returncode == 0, flown.stderr[-2000:]
    landed = re.search(r"landed (\S+) m north of home", flown.stdout)
    assert landed and abs(float(landed.group(1)) - 100.0) < 2.0, flown.stdout
    assert vehicle.returncode == 0
