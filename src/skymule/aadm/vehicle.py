"""The vehicle the agent flies: a small interface and two implementations.

* :class:`KinematicVehicle`: inside skymule, for offline runs. Time advances only when the
  agent calls ``tick(dt)`` (lock-step with the emulated controller clock): it climbs at
  ``climb_mps``, flies at most ``max_speed_mps`` along the shortest path inside the geofence
  (:class:`~skymule.flight.navigation.Navigator`), descends at ``descent_mps`` and disarms on
  touching down.
* :class:`MavsdkVehicle`: a real vehicle or SITL through MAVSDK-Python (``pip install
  'skymule[fly]'``), GUIDED-style ``goto_location``; time is real time and ``tick`` does
  nothing. The test suite flies it against :mod:`skymule.aadm.mavlink_vehicle`, a kinematic
  MAVLink stand-in, not against PX4 or ArduPilot (their SITL is the real check).

Positions are local metres of the scenario's frame: x east, y north, z above the launch point.
"""

from __future__ import annotations

import asyncio
import importlib
import socket
import threading
from collections.abc import Coroutine
from typing import Any, Protocol

import numpy as np

from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator, hover_point
from skymule.geo import LocalFrame

#: AADM: take off to 25 m, fly at <= 10 m/s.
TAKEOFF_ALTITUDE_M = 25.0
MAX_SPEED_MPS = 10.0
#: ArduCopter defaults: WPNAV_SPEED_UP 2.5 m/s; landing descent about 1.5 m/s above 10 m.
CLIMB_MPS = 2.5
DESCENT_MPS = 1.5


class Vehicle(Protocol):
    """What the agent needs from a vehicle."""

    def position_m(self) -> np.ndarray: ...

    @property
    def armed(self) -> bool: ...

    def takeoff(self, altitude_m: float) -> None: ...

    def goto(self, xy_m: tuple[float, float]) -> None: ...

    def land(self) -> None: ...

    def tick(self, dt_s: float) -> None: ...


class KinematicVehicle:
    """A point mass with a speed cap, a geofence and take-off/landing (see module docstring)."""

    def __init__(
        self,
        navigator: Navigator,
        home_xy_m: tuple[float, float],
        *,
        max_speed_mps: float = MAX_SPEED_MPS,
        climb_mps: float = CLIMB_MPS,
        descent_mps: float = DESCENT_MPS,
    ) -> None:
        self.navigator = navigator
        self._xy = (float(home_xy_m[0]), float(home_xy_m[1]))
        self._z = 0.0
        self._goal = self._xy
        self._target_z = 0.0
        self._armed = False
        self._landing = False
        self.max_speed_mps = max_speed_mps
        self.climb_mps = climb_mps
        self.descent_mps = descent_mps
        self.distance_m = 0.0

    def position_m(self) -> np.ndarray:
        return np.array([self._xy[0], self._xy[1], self._z])

    @property
    def armed(self) -> bool:
        return self._armed

    @property
    def airborne(self) -> bool:
        return self._z > 0.0

    def takeoff(self, altitude_m: float = TAKEOFF_ALTITUDE_M) -> None:
        self._armed, self._landing, self._target_z = True, False, float(altitude_m)

    def goto(self, xy_m: tuple[float, float]) -> None:
        """Fly toward ``xy_m`` (a goal outside the fence becomes the nearest fence point)."""
        goal = (float(xy_m[0]), float(xy_m[1]))
        fence = self.navigator.fence
        if not fence.buffer(1e-6).covers(_point(goal)):
            goal = hover_point(fence, goal, margin_m=0.0)
        self._goal = goal

    def land(self) -> None:
        self._landing, self._target_z = True, 0.0

    def tick(self, dt_s: float) -> None:
        """Advance ``dt_s`` seconds: climb first, then fly; land where it is."""
        if not self._armed:
            return
        if not self._landing and self._z >= self._target_z - 1e-9:
            moved = self.navigator.step(self._xy, self._goal, self.max_speed_mps * dt_s)
            self.distance_m += float(np.hypot(moved[0] - self._xy[0], moved[1] - self._xy[1]))
            self._xy = moved
        rate = self.descent_mps if self._landing else self.climb_mps
        change = float(np.clip(self._target_z - self._z, -rate * dt_s, rate * dt_s))
        self._z += change
        if self._landing and self._z <= 0.0:
            self._z, self._armed = 0.0, False


def _mavsdk_python() -> Any:
    """MAVSDK-Python's gRPC API: ``mavsdk_grpc`` (its name since MAVSDK 4), or ``mavsdk``
    below 4 (``mavsdk`` 4 and later is the native binding, another API)."""
    for name in ("mavsdk_grpc", "mavsdk"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        if name == "mavsdk_grpc" or _below_4(module):
            return module
    raise SkymuleError("--vehicle mavsdk needs MAVSDK-Python: pip install 'skymule[fly]'")


def _below_4(module: Any) -> bool:
    version = str(getattr(module, "__version__", "0"))
    return version.split(".")[0].isdigit() and int(version.split(".")[0]) < 4


def _point(xy: tuple[float, float]) -> Any:
    from shapely.geometry import Point

    return Point(xy)


def _free_grpc_port() -> int:
    """A free loopback TCP port for this vehicle's own ``mavsdk_server``: MAVSDK's default,
    50051, is one port for the whole machine, so two flights at once (or a test run beside
    another) would share one server, or fail to start theirs."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


class MavsdkVehicle:
    """MAVSDK-Python behind the :class:`Vehicle` interface (optional extra ``fly``).

    A private asyncio loop in a background thread runs MAVSDK; every method blocks until
    MAVSDK acknowledged the command. Tested against the kinematic MAVLink stand-in of
    :mod:`skymule.aadm.mavlink_vehicle` only, not against PX4 or ArduPilot SITL.
    """

    def __init__(self, address: str, frame: LocalFrame, timeout_s: float = 30.0) -> None:
        system_module = _mavsdk_python()
        self.frame = frame
        self.timeout_s = timeout_s
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()
        self._drone: Any = system_module.System(port=_free_grpc_port())
        self._home_amsl_m = 0.0
        # the latest telemetry, kept by two subscriptions (a new one per call costs a round
        # trip through mavsdk_server each time)
        self._latest_position: np.ndarray | None = None
        self._latest_armed: bool | None = None
        try:
            self._run(self._connect(address))
        except BaseException as exc:
            self.close()
            if isinstance(exc, TimeoutError):
                raise SkymuleError(
                    f"--mavsdk-address {address}: no vehicle answered within {timeout_s:g} s"
                ) from None
            raise

    def _run(self, coroutine: Coroutine[Any, Any, Any]) -> Any:
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop).result(self.timeout_s)

    async def _connect(self, address: str) -> None:
        await self._drone.connect(system_address=address)
        async for state in self._drone.core.connection_state():
            if state.is_connected:
                break
        async for home in self._drone.telemetry.home():
            self._home_amsl_m = float(home.absolute_altitude_m)
            break
        self._watchers = [
            asyncio.ensure_future(self._watch_position()),
            asyncio.ensure_future(self._watch_armed()),
        ]

    async def _watch_position(self) -> None:
        async for where in self._drone.telemetry.position():
            x_m, y_m = self.frame.to_local(where.latitude_deg, where.longitude_deg)
            self._latest_position = np.array(
                [float(x_m), float(y_m), float(where.relative_altitude_m)]
            )

    async def _watch_armed(self) -> None:
        async for armed in self._drone.telemetry.armed():
            self._latest_armed = bool(armed)

    async def _position(self) -> np.ndarray:
        async for where in self._drone.telemetry.position():
            x_m, y_m = self.frame.to_local(where.latitude_deg, where.longitude_deg)
            return np.array([float(x_m), float(y_m), float(where.relative_altitude_m)])
        raise SkymuleError("MAVSDK: no position telemetry")

    async def _armed(self) -> bool:
        async for armed in self._drone.telemetry.armed():
            return bool(armed)
        return False

    async def _takeoff(self, altitude_m: float) -> None:
        await self._drone.action.set_takeoff_altitude(altitude_m)
        await self._drone.action.arm()
        await self._drone.action.takeoff()

    async def _goto(self, xy_m: tuple[float, float], altitude_m: float) -> None:
        lat, lon = self.frame.to_latlon(xy_m[0], xy_m[1])
        amsl = self._home_amsl_m + altitude_m
        await self._drone.action.goto_location(float(lat), float(lon), amsl, float("nan"))

    def position_m(self) -> np.ndarray:
        if self._latest_position is not None:
            return self._latest_position.copy()
        return np.asarray(self._run(self._position()))

    @property
    def armed(self) -> bool:
        if self._latest_armed is not None:
            return self._latest_armed
        return bool(self._run(self._armed()))

    def takeoff(self, altitude_m: float = TAKEOFF_ALTITUDE_M) -> None:
        self._altitude_m = altitude_m
        self._run(self._takeoff(altitude_m))

    def goto(self, xy_m: tuple[float, float]) -> None:
        self._run(self._goto(xy_m, getattr(self, "_altitude_m", TAKEOFF_ALTITUDE_M)))

    def land(self) -> None:
        self._run(self._drone.action.land())

    #: It flies in real time (``tick`` does nothing): the agent gives it the goal one slot
    #: further on, so that it does not stop between polls.
    real_time = True

    def tick(self, dt_s: float) -> None:
        """Real time: the agent's own pacing lets the vehicle fly."""

    def close(self) -> None:
        """Stop MAVSDK's loop and its ``mavsdk_server`` process."""
        for watcher in getattr(self, "_watchers", []):
            self._loop.call_soon_threadsafe(watcher.cancel)
        stop_server = getattr(self._drone, "_stop_mavsdk_server", None)
        if callable(stop_server):
            stop_server()
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)
