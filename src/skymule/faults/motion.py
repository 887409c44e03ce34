r"""UAV-side faults that act on motion: steady wind and a battery that forces the return.

Both are deterministic given their parameters (nothing to draw) and pure: the engine passes
in what it commanded or used so far and gets back what is achieved or allowed.

Wind (wind triangle). The autopilot holds the commanded course :math:`\hat u` and may not
exceed the commanded ground speed :math:`g_c = |s| / \Delta t`. With wind vector :math:`w`
and the largest airspeed :math:`V`, the air-relative velocity :math:`g \hat u - w` must satisfy
:math:`|g \hat u - w| \le V`, so the largest ground speed along the course is

.. math:: g_{max} = \hat u \cdot w + \sqrt{V^2 - |w|^2 + (\hat u \cdot w)^2}

(0 when the root is imaginary or the result negative: no headway), and the achieved
ground speed is :math:`\min(g_c, g_{max})`. A headwind of 5 m/s against a 10 m/s UAV
halves its ground speed; a tailwind never makes it fly faster than commanded. Along a
polyline (the in-fence way to a goal or home) each leg is flown at its own ground speed:
:func:`leg_speeds_mps`, :func:`path_time_s` (how long the way takes) and :func:`fly_for`
(where one slot of it ends) are what the autonomous engine keeps its return home with.

Battery. Energy used so far is the propulsion energy of what was flown
(:func:`skymule.energy.propulsion_power_w`): each leg of a slot's path at its power for the
time on it, hovering for the rest of the slot (:meth:`Battery.flight_energy_j`). The power is
the model's at the airspeed :math:`|g \hat u - w|` (hovering in a wind: at :math:`|w|`). The engine
allows a move only if the energy used, plus the move's, plus the way home from where it ends
(:meth:`Battery.path_energy_j`, leg by leg at the ground speed the wind allows) fits the usable
energy, capacity x (1 - reserve) (:meth:`Battery.affords`); otherwise it flies home, so the
reserve is never flown on (``docs/faults.md``, step 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skymule.energy import DEFAULT_PARAMS, RotaryWingParams, propulsion_power_w

J_PER_WH = 3600.0

#: Round-off guard [J] in the battery's test of a move (:meth:`Battery.affords`).
ENERGY_SLACK_J = 1e-6


@dataclass(frozen=True)
class Wind:
    """Steady wind.

    Attributes:
        speed_mps: wind speed [m/s].
        from_deg: direction the wind blows from [deg clockwise from north] (270: a westerly,
            pushing the UAV east).
    """

    speed_mps: float
    from_deg: float

    @property
    def vector_mps(self) -> np.ndarray:
        """(2,) wind velocity (east, north) [m/s]: it blows toward from_deg + 180."""
        toward = math.radians(self.from_deg + 180.0)
        return np.array([math.sin(toward), math.cos(toward)]) * self.speed_mps

    def reachable_by(self, max_airspeed_mps: float) -> bool:
        """True when a UAV of this largest airspeed makes headway in every direction (the wind
        is slower than it): then every in-fence point, home included, stays reachable."""
        return self.speed_mps < max_airspeed_mps

    def max_ground_speed_mps(self, course: np.ndarray, max_airspeed_mps: float) -> np.ndarray:
        """Largest ground speed [m/s] along unit course vector(s) ``(..., 2)`` (0: no headway).

        g_max = u.w + sqrt(V^2 - |w|^2 + (u.w)^2), 0 when imaginary or negative; it grows with
        u.w, so the direct headwind is the slowest course: V - |w|.
        """
        return wind_triangle_ground_speed_mps(course, self.vector_mps, max_airspeed_mps)

    def achieved_step_m(
        self, commanded_step_m: np.ndarray, slot_s: float, max_airspeed_mps: float
    ) -> np.ndarray:
        """Achieved horizontal step(s) [m] for commanded step(s) ``(..., 2)`` over one slot.

        Same direction as commanded, never longer; shorter when the wind leaves too little
        airspeed to hold the commanded ground speed (see the module docstring).
        """
        step = np.asarray(commanded_step_m, dtype=float)
        length = np.linalg.norm(step, axis=-1)
        course = np.divide(
            step, length[..., None], out=np.zeros_like(step), where=length[..., None] > 0
        )
        g_max = self.max_ground_speed_mps(course, max_airspeed_mps)
        achieved = np.minimum(length / slot_s, g_max) * slot_s
        return course * achieved[..., None]


def wind_triangle_ground_speed_mps(
    course: np.ndarray, wind_mps: np.ndarray, max_airspeed_mps: float
) -> np.ndarray:
    """Largest ground speed [m/s] along unit course vector(s) ``(..., 2)`` under the wind
    velocity ``wind_mps`` (2,) at airspeed V: g = u.w + sqrt(V^2 - |w|^2 + (u.w)^2), 0 when
    imaginary or negative (no headway). The one statement of the wind triangle: the engine's
    :class:`Wind` and the planner's estimated wind both use it."""
    wind = np.asarray(wind_mps, dtype=float)
    along = np.asarray(course, dtype=float) @ wind
    root = max_airspeed_mps**2 - float(wind @ wind) + along**2
    g_max = np.where(root >= 0, along + np.sqrt(np.maximum(root, 0.0)), 0.0)
    return np.asarray(np.maximum(g_max, 0.0))


def leg_speeds_mps(
    path_m: np.ndarray, wind: Wind | None, speed_mps: float, max_airspeed_mps: float
) -> np.ndarray:
    """(K - 1,) ground speed [m/s] on each leg of a polyline ``(K, 2)`` flown at the commanded
    ``speed_mps``: min(speed, g_max of the leg's course) under ``wind``, the speed without."""
    legs = np.diff(np.asarray(path_m, dtype=float).reshape(-1, 2), axis=0)
    if wind is None:
        return np.full(len(legs), float(speed_mps))
    length = np.hypot(legs[:, 0], legs[:, 1])
    course = np.divide(legs, length[:, None], out=np.zeros_like(legs), where=length[:, None] > 0)
    return np.minimum(float(speed_mps), wind.max_ground_speed_mps(course, max_airspeed_mps))


def path_time_s(path_m: np.ndarray, speeds_mps: np.ndarray) -> float:
    """Time [s] to fly a polyline ``(K, 2)`` with ground speed ``speeds_mps[k]`` on leg k
    (``inf`` when a leg of positive length has no headway)."""
    legs = np.diff(np.asarray(path_m, dtype=float).reshape(-1, 2), axis=0)
    length = np.hypot(legs[:, 0], legs[:, 1])
    moving = length > 0
    if np.any(moving & (speeds_mps <= 0)):
        return math.inf
    return float(np.sum(length[moving] / speeds_mps[moving]))


def fly_for(path_m: np.ndarray, seconds: float, speeds_mps: np.ndarray) -> tuple[float, float]:
    """Point reached after flying ``seconds`` along a polyline ``(K, 2)`` at ``speeds_mps[k]``
    on leg k: exactly the last point once the time covers the whole path."""
    path = np.asarray(path_m, dtype=float).reshape(-1, 2)
    left = float(seconds)
    for k in range(len(path) - 1):
        a, b = path[k], path[k + 1]
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        if length == 0.0:
            continue
        if speeds_mps[k] <= 0:
            return float(a[0]), float(a[1])  # no headway on this leg: held at its start
        need = length / speeds_mps[k]
        if left < need:
            t = left / need
            return float(a[0] + t * (b[0] - a[0])), float(a[1] + t * (b[1] - a[1]))
        left -= need
    return float(path[-1, 0]), float(path[-1, 1])


def leg_seconds(path_m: np.ndarray, seconds: float, speeds_mps: np.ndarray) -> np.ndarray:
    """(K - 1,) seconds spent on each leg of a polyline ``(K, 2)`` in ``seconds`` of flight
    from its start at ``speeds_mps[k]`` on leg k: the legs :func:`fly_for` covers, whole legs
    at their full time, the leg it stops on at the part flown (0 after it). Their sum is less
    than ``seconds`` when the polyline ends first (the UAV is then at its last point)."""
    legs = np.diff(np.asarray(path_m, dtype=float).reshape(-1, 2), axis=0)
    length = np.hypot(legs[:, 0], legs[:, 1])
    speeds = np.asarray(speeds_mps, dtype=float)
    headway = speeds > 0
    need = np.where(length > 0, np.inf, 0.0)  # a leg of positive length without headway
    np.divide(length, speeds, out=need, where=headway & (length > 0))
    start = np.concatenate([[0.0], np.cumsum(need)[:-1]])
    return np.asarray(np.clip(seconds - start, 0.0, need))


@dataclass(frozen=True)
class Battery:
    """Battery limit on propulsion energy.

    Attributes:
        capacity_j: usable pack energy [J].
        reserve_fraction: share of the capacity kept for landing (never planned with).
        return_speed_mps: speed the UAV flies home at [m/s].
        airframe: propulsion model parameters (Zeng, Xu & Zhang 2019 defaults).
    """

    capacity_j: float
    reserve_fraction: float = 0.2
    return_speed_mps: float = 10.0
    airframe: RotaryWingParams = DEFAULT_PARAMS

    @property
    def usable_j(self) -> float:
        return self.capacity_j * (1.0 - self.reserve_fraction)

    def slot_energy_j(self, speed_mps: np.ndarray | float, slot_s: float) -> np.ndarray:
        """Energy [J] of one slot flown at the airspeed ``speed_mps`` (vectorised)."""
        return propulsion_power_w(speed_mps, self.airframe) * slot_s

    def return_energy_j(self, distance_home_m: np.ndarray | float) -> np.ndarray:
        """Energy [J] to fly ``distance_home_m`` at the return speed in calm air (vectorised)."""
        power = float(propulsion_power_w(self.return_speed_mps, self.airframe))
        return power * np.asarray(distance_home_m, dtype=float) / self.return_speed_mps

    def hover_power_w(self, wind: Wind | None = None) -> float:
        """Power [W] to hold position: P(0) in calm air, P(|w|) in a steady wind (the rotor
        meets the air at the wind speed)."""
        return float(propulsion_power_w(0.0 if wind is None else wind.speed_mps, self.airframe))

    def leg_power_w(
        self, path_m: np.ndarray, speeds_mps: np.ndarray, wind: Wind | None = None
    ) -> np.ndarray:
        """(K - 1,) propulsion power [W] on each leg of a polyline ``(K, 2)`` flown at ground
        speed ``speeds_mps[k]``: P at the airspeed |g_k u_k - w| (Zeng et al. model the power
        of level flight through the air); P(g_k) without wind."""
        speeds = np.asarray(speeds_mps, dtype=float)
        if wind is None:
            return propulsion_power_w(speeds, self.airframe)
        legs = np.diff(np.asarray(path_m, dtype=float).reshape(-1, 2), axis=0)
        length = np.hypot(legs[:, 0], legs[:, 1])
        course = np.divide(
            legs, length[:, None], out=np.zeros_like(legs), where=length[:, None] > 0
        )
        air = course * speeds[:, None] - wind.vector_mps
        return propulsion_power_w(np.hypot(air[:, 0], air[:, 1]), self.airframe)

    def leg_energy_j(
        self, path_m: np.ndarray, speeds_mps: np.ndarray, wind: Wind | None = None
    ) -> np.ndarray:
        """(K - 1,) energy [J] to fly each leg of a polyline ``(K, 2)`` at ground speed
        ``speeds_mps[k]`` (power :meth:`leg_power_w` for ℓ_k / g_k seconds); ``inf`` on a leg
        of positive length without headway, 0 on a leg of length 0."""
        legs = np.diff(np.asarray(path_m, dtype=float).reshape(-1, 2), axis=0)
        length = np.hypot(legs[:, 0], legs[:, 1])
        speeds = np.asarray(speeds_mps, dtype=float)
        moving = length > 0
        energy = np.where(moving, np.inf, 0.0)
        flying = moving & (speeds > 0)
        power = self.leg_power_w(path_m, speeds, wind)
        energy[flying] = power[flying] * length[flying] / speeds[flying]
        return energy

    def path_energy_j(
        self, path_m: np.ndarray, speeds_mps: np.ndarray, wind: Wind | None = None
    ) -> float:
        """Energy [J] to fly a polyline ``(K, 2)`` at ground speed ``speeds_mps[k]`` on leg k
        (:meth:`leg_energy_j` summed; under a wind the legs' speeds come from
        :func:`leg_speeds_mps`); ``inf`` without headway."""
        return float(np.sum(self.leg_energy_j(path_m, speeds_mps, wind)))

    def flight_energy_j(
        self,
        path_m: np.ndarray,
        seconds: float,
        speeds_mps: np.ndarray,
        wind: Wind | None = None,
        hover_rest: bool = True,
    ) -> float:
        """Energy [J] of ``seconds`` of flight from the start of a polyline ``(K, 2)``, leg k at
        ground speed ``speeds_mps[k]`` (:func:`leg_seconds`, as :func:`fly_for` flies it):
        each leg's power for the time on it, and, when the polyline ends first, the rest of
        the time hovering at its end (``hover_rest``; False: the UAV lands there, paid from
        the reserve)."""
        flown = leg_seconds(path_m, seconds, speeds_mps)
        power = self.leg_power_w(path_m, speeds_mps, wind)
        on_legs = flown > 0
        energy = float(np.sum(power[on_legs] * flown[on_legs]))
        rest = seconds - float(np.sum(flown))
        if hover_rest and rest > 0:
            energy += self.hover_power_w(wind) * rest
        return energy

    def affords(
        self,
        used_j: np.ndarray | float,
        move_j: np.ndarray | float,
        home_j: np.ndarray | float,
    ) -> np.ndarray:
        """True where the energy used so far, plus a slot's move, plus the way home from where
        that move ends, stays within the usable energy (less :data:`ENERGY_SLACK_J` against
        round-off): the engine allows a move only then (vectorised over missions)."""
        total = np.asarray(used_j, dtype=float) + np.asarray(move_j, dtype=float)
        return np.asarray(total + np.asarray(home_j, dtype=float) <= self.usable_j - ENERGY_SLACK_J)

    def exhausted(self, used_j: np.ndarray | float) -> np.ndarray:
        """True where the usable energy is spent: the UAV lands where it is."""
        return np.asarray(np.asarray(used_j, dtype=float) >= self.usable_j)
