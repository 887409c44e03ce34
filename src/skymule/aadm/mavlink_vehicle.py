"""A kinematic MAVLink vehicle for tests: enough of an autopilot for ``--vehicle mavsdk``.

**This is not PX4 or ArduPilot.** It is a point mass that speaks a small part of MAVLink
(pymavlink, extra ``fly``) the way ArduCopter answers it, so that the MAVSDK vehicle of
:mod:`skymule.aadm.vehicle` can fly a whole AADM mission in a test without a simulator. The
real check before a flight is PX4 SIH or ArduPilot SITL.

What it answers (common MAVLink message set, mavlink.io):

* ``HEARTBEAT`` once a second (quadrotor, ArduPilot autopilot, GUIDED/LAND/RTL custom
  modes, the armed flag); ``GLOBAL_POSITION_INT`` ten times a second; ``HOME_POSITION``,
  ``EXTENDED_SYS_STATE``, ``SYS_STATUS`` (gyro, accelerometer, magnetometer, GPS and the
  pre-arm check present, enabled and healthy) and ``GPS_RAW_INT`` (3D fix, 12 satellites)
  once a second, so that MAVSDK's ``telemetry.health()`` reports a good global and home
  position and the vehicle armable, as a plain "wait for health" loop expects;
* ``COMMAND_LONG``/``COMMAND_INT``: arm/disarm, set mode, take-off (to param 7), land, return
  to launch, reposition (``DO_REPOSITION``), message requests (``AUTOPILOT_VERSION``,
  ``HOME_POSITION``) and message intervals, each with a ``COMMAND_ACK``; anything else is
  acknowledged as unsupported;
* ``SET_POSITION_TARGET_GLOBAL_INT`` (GUIDED position targets); ``SET_MODE``;
  ``PARAM_SET`` echoed as ``PARAM_VALUE``; ``PARAM_REQUEST_LIST`` answered with no
  parameter; ``MISSION_REQUEST_LIST`` with an empty mission.

It climbs and descends at ``climb_mps``/``descent_mps``, flies straight at ``speed_mps`` (no
geofence: the agent keeps inside it) and disarms on touching down. ``time_scale`` runs its
clock faster than the wall clock (a 60-s mission in 6 s at 10).
"""

from __future__ import annotations

import importlib
import math
import threading
import time
from typing import Any

from skymule.errors import SkymuleError
from skymule.geo import LocalFrame

#: ArduCopter custom modes (mavlink.io "ardupilotmega" COPTER_MODE).
GUIDED, RTL, LAND = 4, 6, 9
#: MAV_CMD numbers (common.xml).
CMD_NAV_RETURN_TO_LAUNCH, CMD_NAV_LAND, CMD_NAV_TAKEOFF = 20, 21, 22
CMD_DO_SET_MODE, CMD_DO_REPOSITION, CMD_ARM_DISARM = 176, 192, 400
CMD_SET_MESSAGE_INTERVAL, CMD_REQUEST_MESSAGE, CMD_REQUEST_CAPABILITIES = 511, 512, 520
MSG_AUTOPILOT_VERSION, MSG_HOME_POSITION = 148, 242


def parse_mavlink_address(text: str) -> tuple[str, int]:
    """(host, port) the vehicle sends to, from MAVSDK's listening address: ``udp://:14540``,
    ``udp://0.0.0.0:14540``, ``udpin://127.0.0.1:14540`` (an empty or 0.0.0.0 host is this
    machine's loopback); one-line SkymuleError otherwise."""
    scheme, sep, rest = text.partition("://")
    host, colon, port = rest.rpartition(":")
    if not sep or scheme not in ("udp", "udpin") or not colon or not port.isdigit():
        raise SkymuleError(f"--mavlink {text!r}: expected udp://[HOST]:PORT, like udp://:14540")
    number = int(port)
    if not 0 < number < 65536:
        raise SkymuleError(f"--mavlink {text!r}: port {number} is not 1..65535")
    return (host if host not in ("", "0.0.0.0") else "127.0.0.1"), number


def _mavutil() -> Any:
    try:
        return importlib.import_module("pymavlink.mavutil")
    except ImportError:
        raise SkymuleError(
            "the MAVLink test vehicle needs pymavlink: pip install 'skymule[fly]'"
        ) from None


class MavlinkTestVehicle:
    """A kinematic vehicle behind MAVLink on UDP, sending to ``host:port`` (a MAVSDK
    ``udpin`` address) from a port of its own; :meth:`close` stops it."""

    def __init__(
        self,
        frame: LocalFrame,
        port: int,
        *,
        host: str = "127.0.0.1",
        home_xy_m: tuple[float, float] = (0.0, 0.0),
        speed_mps: float = 10.0,
        climb_mps: float = 2.5,
        descent_mps: float = 1.5,
        time_scale: float = 1.0,
    ) -> None:
        mavutil = _mavutil()
        self.mavlink = mavutil.mavlink
        self.frame = frame
        self.link = mavutil.mavlink_connection(
            f"udpout:{host}:{port}", source_system=1, source_component=1, dialect="ardupilotmega"
        )
        self.home = (float(home_xy_m[0]), float(home_xy_m[1]))
        self.xy = self.home
        self.z = 0.0
        self.goal = self.home
        self.target_z = 0.0
        self.armed = False
        self.mode = GUIDED
        self.speed_mps, self.climb_mps, self.descent_mps = speed_mps, climb_mps, descent_mps
        self.time_scale = time_scale
        self.commands: list[int] = []  # every command number received, for tests
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mavlink-test-vehicle", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.link.close()

    # -- the loop ------------------------------------------------------------------------------

    def _run(self) -> None:
        last = time.monotonic()
        next_slow = next_fast = last
        while not self._stop.is_set():
            while (message := self.link.recv_match(blocking=False)) is not None:
                self._handle(message)
            now = time.monotonic()
            with self._lock:
                self._fly((now - last) * self.time_scale)
            last = now
            if now >= next_fast:  # 10 Hz of the vehicle's own clock (at most 100 Hz)
                self._send_position()
                next_fast = now + max(0.01, 0.1 / self.time_scale)
            if now >= next_slow:
                self._send_status()
                next_slow = now + 1.0
            self._stop.wait(0.01)

    def _fly(self, dt_s: float) -> None:
        if not self.armed:
            return
        rate = self.descent_mps if self.target_z < self.z else self.climb_mps
        self.z += max(-rate * dt_s, min(rate * dt_s, self.target_z - self.z))
        if self.mode == RTL and self.z >= self.target_z - 1e-6 and self.xy == self.home:
            self.mode, self.target_z = LAND, 0.0
        if self.z > 0.5 and self.mode != LAND:
            dx, dy = self.goal[0] - self.xy[0], self.goal[1] - self.xy[1]
            far = math.hypot(dx, dy)
            step = min(far, self.speed_mps * dt_s)
            self.xy = self.goal if far <= step else (
                self.xy[0] + dx / far * step,
                self.xy[1] + dy / far * step,
            )  # fmt: skip
        if self.mode == LAND and self.z <= 0.0:
            self.z, self.armed, self.mode = 0.0, False, GUIDED

    # -- what it sends -------------------------------------------------------------------------

    def _latlon_e7(self, xy: tuple[float, float]) -> tuple[int, int]:
        lat, lon = self.frame.to_latlon(xy[0], xy[1])
        return round(float(lat) * 1e7), round(float(lon) * 1e7)

    def _send_position(self) -> None:
        with self._lock:
            lat, lon = self._latlon_e7(self.xy)
            z_mm = round(self.z * 1000)
        boot_ms = int(time.monotonic() * 1000) & 0xFFFFFFFF
        self.link.mav.global_position_int_send(boot_ms, lat, lon, z_mm, z_mm, 0, 0, 0, 65535)

    def _send_status(self) -> None:
        mav = self.mavlink
        with self._lock:
            armed, mode, z = self.armed, self.mode, self.z
        flags = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mav.MAV_MODE_FLAG_GUIDED_ENABLED
        flags |= mav.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0
        state = mav.MAV_STATE_ACTIVE if armed else mav.MAV_STATE_STANDBY
        self.link.mav.heartbeat_send(
            mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, flags, mode, state
        )
        self._send_home()
        self._send_health()
        landed = mav.MAV_LANDED_STATE_IN_AIR if z > 0.1 else mav.MAV_LANDED_STATE_ON_GROUND
        self.link.mav.extended_sys_state_send(mav.MAV_VTOL_STATE_UNDEFINED, landed)

    def _send_health(self) -> None:
        mav = self.mavlink
        sensors = (
            mav.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | mav.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | mav.MAV_SYS_STATUS_SENSOR_3D_MAG
            | mav.MAV_SYS_STATUS_SENSOR_GPS
            | mav.MAV_SYS_STATUS_PREARM_CHECK
        )
        # present, enabled, healthy; no load, 16.8 V, current unknown, 100 %, no errors
        self.link.mav.sys_status_send(
            sensors, sensors, sensors, 0, 16800, -1, 100, 0, 0, 0, 0, 0, 0
        )
        with self._lock:
            lat, lon = self._latlon_e7(self.xy)
            z_mm = round(self.z * 1000)
        boot_us = int(time.monotonic() * 1e6)
        fix_3d = mav.GPS_FIX_TYPE_3D_FIX
        self.link.mav.gps_raw_int_send(boot_us, fix_3d, lat, lon, z_mm, 80, 120, 0, 0, 12)

    def _send_home(self) -> None:
        lat, lon = self._latlon_e7(self.home)
        self.link.mav.home_position_send(lat, lon, 0, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0, 0, 0)

    def _ack(self, command: int, ok: bool = True) -> None:
        mav = self.mavlink
        result = mav.MAV_RESULT_ACCEPTED if ok else mav.MAV_RESULT_UNSUPPORTED
        self.link.mav.command_ack_send(command, result)

    # -- what it answers -----------------------------------------------------------------------

    def _handle(self, message: Any) -> None:
        kind = message.get_type()
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._command(message, kind == "COMMAND_INT")
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self._go(message.lat_int / 1e7, message.lon_int / 1e7, message.alt)
        elif kind == "SET_MODE":
            with self._lock:
                self._set_mode(int(message.custom_mode))
        elif kind == "PARAM_SET":
            self.link.mav.param_value_send(
                message.param_id.encode(), message.param_value, message.param_type, 1, 0
            )
        elif kind == "PARAM_REQUEST_LIST":
            pass  # no parameters
        elif kind == "MISSION_REQUEST_LIST":
            self.link.mav.mission_count_send(255, 0, 0, getattr(message, "mission_type", 0))

    def _command(self, message: Any, is_int: bool) -> None:
        number = int(message.command)
        self.commands.append(number)
        ok = True
        with self._lock:
            if number == CMD_ARM_DISARM:
                self.armed = message.param1 > 0.5
                if not self.armed:
                    self.z, self.target_z = 0.0, 0.0
            elif number == CMD_DO_SET_MODE:
                self._set_mode(int(message.param2))
            elif number == CMD_NAV_TAKEOFF:
                ok = self.armed
                if ok:
                    self.mode, self.target_z = GUIDED, float(message.param7)
            elif number == CMD_NAV_LAND:
                self.mode, self.target_z = LAND, 0.0
            elif number == CMD_NAV_RETURN_TO_LAUNCH:
                self._set_mode(RTL)
            elif number == CMD_DO_REPOSITION:
                lat = message.x / 1e7 if is_int else message.param5
                lon = message.y / 1e7 if is_int else message.param6
                self._go_locked(lat, lon, message.z if is_int else message.param7)
            elif number not in (CMD_SET_MESSAGE_INTERVAL, CMD_REQUEST_MESSAGE,
                                CMD_REQUEST_CAPABILITIES):  # fmt: skip
                ok = False
        self._ack(number, ok)
        if number in (CMD_REQUEST_MESSAGE, CMD_REQUEST_CAPABILITIES):
            wanted = int(message.param1) if number == CMD_REQUEST_MESSAGE else MSG_AUTOPILOT_VERSION
            if wanted == MSG_AUTOPILOT_VERSION:
                self._send_version()
            elif wanted == MSG_HOME_POSITION:
                self._send_home()

    def _send_version(self) -> None:
        mav = self.mavlink
        capabilities = (
            mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | mav.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
        )
        self.link.mav.autopilot_version_send(
            capabilities, 0, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0, [0] * 18
        )

    def _set_mode(self, mode: int) -> None:
        self.mode = mode
        if mode == RTL:
            self.goal, self.target_z = self.home, max(self.z, 15.0)
        elif mode == LAND:
            self.target_z = 0.0

    def _go(self, lat: float, lon: float, alt_m: float) -> None:
        with self._lock:
            self._go_locked(lat, lon, alt_m)

    def _go_locked(self, lat: float, lon: float, alt_m: float) -> None:
        if math.isfinite(lat) and math.isfinite(lon) and (lat or lon):
            x_m, y_m = self.frame.to_local(lat, lon)
            self.goal = (float(x_m), float(y_m))
        if math.isfinite(alt_m) and alt_m > 0:
            self.target_z = float(alt_m)
        self.mode = GUIDED
