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
halves its ground speed; a tailwind never makes it fly faster than commanded.

Battery. Energy used so far is the sum of propulsion power :math:`P(V_t)\,\Delta t`
(:func:`skymule.energy.propulsion_power_w`). The UAV must turn home at the start of a slot
when the usable energy left, capacity x (1 - reserve) - used, no longer covers flying home at
the return speed, :math:`P(v_r)\,d_{home}/v_r`, plus one more slot at the hover power (the
decision is taken at the slot's start and the slot is spent before the next check).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skymule.energy import DEFAULT_PARAMS, RotaryWingParams, propulsion_power_w

J_PER_WH = 3600.0


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
        wind = self.vector_mps
        along = course @ wind
        root = max_airspeed_mps**2 - float(wind @ wind) + along**2
        g_max = np.where(root >= 0, along + np.sqrt(np.maximum(root, 0.0)), 0.0)
        achieved = np.minimum(length / slot_s, np.maximum(g_max, 0.0)) * slot_s
        return course * achieved[..., None]


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
        """Energy [J] of one slot flown at ``speed_mps`` (vectorised)."""
        return propulsion_power_w(speed_mps, self.airframe) * slot_s

    def return_energy_j(self, distance_home_m: np.ndarray | float) -> np.ndarray:
        """Energy [J] to fly ``distance_home_m`` at the return speed (vectorised)."""
        power = float(propulsion_power_w(self.return_speed_mps, self.airframe))
        return power * np.asarray(distance_home_m, dtype=float) / self.return_speed_mps

    def must_return(
        self, used_j: np.ndarray | float, distance_home_m: np.ndarray | float, slot_s: float
    ) -> np.ndarray:
        """True where the UAV must head home now (vectorised over missions)."""
        margin = float(propulsion_power_w(0.0, self.airframe)) * slot_s  # one more slot
        left = self.usable_j - np.asarray(used_j, dtype=float)
        return np.asarray(left <= self.return_energy_j(distance_home_m) + margin)

    def exhausted(self, used_j: np.ndarray | float) -> np.ndarray:
        """True where the usable energy is spent: the UAV lands where it is."""
        return np.asarray(np.asarray(used_j, dtype=float) >= self.usable_j)
