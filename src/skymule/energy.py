r"""Rotary-wing UAV propulsion power and mission energy.

Model: Y. Zeng, J. Xu and R. Zhang, "Energy minimization for wireless communication with
rotary-wing UAV", IEEE Trans. Wireless Commun. 18(4):2329-2345, 2019, eq. (12), for level
flight at constant speed ``V`` (m/s):

.. math::

    P(V) = P_0 \left(1 + \frac{3V^2}{U_{tip}^2}\right)
         + P_i \left(\sqrt{1 + \frac{V^4}{4 v_0^4}} - \frac{V^2}{2 v_0^2}\right)^{1/2}
         + \tfrac12 d_0 \rho s A V^3

with blade-profile power :math:`P_0 = \frac{\delta}{8} \rho s A \Omega^3 R^3`, induced
hover power :math:`P_i = (1 + k) W^{3/2} / \sqrt{2 \rho A}`, rotor tip speed
:math:`U_{tip} = \Omega R` and mean rotor induced velocity in hover
:math:`v_0 = \sqrt{W / (2 \rho A)}` (paper eq. (12) and Table I).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RotaryWingParams:
    """Rotor/airframe parameters of Zeng, Xu & Zhang (2019), Table I defaults.

    Attributes:
        delta: profile drag coefficient (dimensionless).
        rho: air density, kg/m^3.
        s: rotor solidity (dimensionless).
        A: rotor disc area, m^2.
        omega: blade angular velocity, rad/s.
        R: rotor radius, m.
        k: incremental correction factor to induced power (dimensionless).
        W: aircraft weight, N.
        d0: fuselage drag ratio (dimensionless).
    """

    delta: float = 0.012
    rho: float = 1.225
    s: float = 0.05
    A: float = 0.503
    omega: float = 300.0
    R: float = 0.4
    k: float = 0.1
    W: float = 20.0
    d0: float = 0.6

    def __post_init__(self) -> None:
        for name in ("rho", "s", "A", "omega", "R", "W"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be > 0")
        for name in ("delta", "k", "d0"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")

    @property
    def blade_profile_power_w(self) -> float:
        """P0 = delta/8 · rho · s · A · Omega^3 · R^3, W (≈ 79.86 W with the defaults)."""
        return self.delta / 8.0 * self.rho * self.s * self.A * self.omega**3 * self.R**3

    @property
    def induced_power_w(self) -> float:
        """Pi = (1 + k) · W^(3/2) / sqrt(2 · rho · A), W (≈ 88.63 W with the defaults)."""
        return (1.0 + self.k) * self.W**1.5 / math.sqrt(2.0 * self.rho * self.A)

    @property
    def tip_speed_mps(self) -> float:
        """U_tip = Omega · R, m/s (120 m/s with the defaults)."""
        return self.omega * self.R

    @property
    def hover_induced_velocity_mps(self) -> float:
        """v0 = sqrt(W / (2 · rho · A)), m/s (≈ 4.03 m/s with the defaults)."""
        return math.sqrt(self.W / (2.0 * self.rho * self.A))

    @property
    def hover_power_w(self) -> float:
        """P(0) = P0 + Pi, W (≈ 168.48 W with the defaults)."""
        return self.blade_profile_power_w + self.induced_power_w


DEFAULT_PARAMS = RotaryWingParams()


def propulsion_power_w(
    speed_mps: np.ndarray | float, params: RotaryWingParams = DEFAULT_PARAMS
) -> np.ndarray:
    """Propulsion power (W) at horizontal speed ``speed_mps`` (m/s), Zeng et al. eq. (12).

    Vectorised: returns an array with the same shape as ``speed_mps`` (0-d for a scalar).
    Speeds must be non-negative.
    """
    v = np.asarray(speed_mps, dtype=float)
    if np.any(v < 0):
        raise ValueError("speed must be non-negative")
    p0 = params.blade_profile_power_w
    pi = params.induced_power_w
    u_tip = params.tip_speed_mps
    v0 = params.hover_induced_velocity_mps
    v2 = v * v
    blade = p0 * (1.0 + 3.0 * v2 / u_tip**2)
    induced = pi * np.sqrt(np.sqrt(1.0 + v2 * v2 / (4.0 * v0**4)) - v2 / (2.0 * v0**2))
    parasite = 0.5 * params.d0 * params.rho * params.s * params.A * v2 * v
    return blade + induced + parasite


def mission_energy_j(
    speed_mps: np.ndarray, slot_s: float, params: RotaryWingParams = DEFAULT_PARAMS
) -> float:
    """Propulsion energy (J) of a trajectory flown at ``speed_mps[n]`` (m/s) in slot ``n``.

    Each slot lasts ``slot_s`` seconds; energy = sum_n P(V_n) · slot_s.  ``speed_mps`` may
    have any shape (all elements are summed).
    """
    if slot_s < 0:
        raise ValueError(f"slot_s must be >= 0, got {slot_s}")
    return float(np.sum(propulsion_power_w(speed_mps, params)) * slot_s)


def max_endurance_speed_mps(params: RotaryWingParams = DEFAULT_PARAMS) -> float:
    """Speed (m/s) minimising propulsion power P(V) (≈ 10.2 m/s with the defaults)."""
    from scipy.optimize import minimize_scalar  # ~0.3 s to import: only when asked

    upper = params.tip_speed_mps
    res = minimize_scalar(
        lambda v: float(propulsion_power_w(v, params)),
        bounds=(0.0, upper),
        method="bounded",
        options={"xatol": 1e-6},
    )
    return float(res.x)


def max_range_speed_mps(params: RotaryWingParams = DEFAULT_PARAMS) -> float:
    """Speed (m/s) minimising energy per metre P(V)/V (≈ 18.3 m/s with the defaults)."""
    from scipy.optimize import minimize_scalar  # ~0.3 s to import: only when asked

    upper = params.tip_speed_mps
    res = minimize_scalar(
        lambda v: float(propulsion_power_w(v, params)) / v,
        bounds=(1e-3, upper),
        method="bounded",
        options={"xatol": 1e-6},
    )
    return float(res.x)
