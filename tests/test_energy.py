"""Tests for skymule.energy (Zeng, Xu & Zhang 2019 rotary-wing propulsion power, eq. (12))."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from skymule.energy import (
    RotaryWingParams,
    max_endurance_speed_mps,
    max_range_speed_mps,
    mission_energy_j,
    propulsion_power_w,
)


def test_table_one_derived_quantities() -> None:
    p = RotaryWingParams()
    # P0 = delta/8 rho s A Omega^3 R^3 = 0.0015 * 1.225 * 0.05 * 0.503 * 2.7e7 * 0.064
    assert p.blade_profile_power_w == pytest.approx(79.85628, abs=1e-5)
    # Pi = (1 + k) W^1.5 / sqrt(2 rho A) = 1.1 * 89.4427 / sqrt(1.23235)
    assert p.induced_power_w == pytest.approx(88.6279, abs=1e-3)
    assert p.tip_speed_mps == 120.0
    # v0 = sqrt(20 / 1.23235) = sqrt(16.2292)
    assert p.hover_induced_velocity_mps == pytest.approx(4.0285, abs=1e-3)


def test_hover_power_by_hand() -> None:
    # At V = 0 eq. (12) reduces to P0 + Pi.
    p0 = 0.012 / 8.0 * 1.225 * 0.05 * 0.503 * 300.0**3 * 0.4**3
    pi = (1.0 + 0.1) * 20.0**1.5 / math.sqrt(2.0 * 1.225 * 0.503)
    assert p0 + pi == pytest.approx(168.48, abs=0.01)
    assert float(propulsion_power_w(0.0)) == pytest.approx(p0 + pi, abs=0.01)
    assert float(propulsion_power_w(0.0)) == pytest.approx(RotaryWingParams().hover_power_w)


def test_power_at_10_mps_by_hand() -> None:
    v = 10.0
    p0 = 79.85628  # W, see above
    pi = 88.62794  # W
    u_tip = 120.0  # m/s
    v0_sq = 20.0 / (2.0 * 1.225 * 0.503)  # 16.2292 m^2/s^2
    blade = p0 * (1.0 + 3.0 * v**2 / u_tip**2)  # 79.85628 * 1.0208333 = 81.5200 W
    induced = pi * math.sqrt(math.sqrt(1.0 + v**4 / (4.0 * v0_sq**2)) - v**2 / (2.0 * v0_sq))
    parasite = 0.5 * 0.6 * 1.225 * 0.05 * 0.503 * v**3  # 0.00924263 * 1000 = 9.2426 W
    assert blade == pytest.approx(81.5200, abs=1e-3)
    assert induced == pytest.approx(35.2544, abs=1e-3)
    assert parasite == pytest.approx(9.2426, abs=1e-3)
    assert float(propulsion_power_w(v)) == pytest.approx(blade + induced + parasite, abs=1e-4)
    assert float(propulsion_power_w(v)) == pytest.approx(126.017, abs=1e-3)


def test_vectorised_matches_scalar_loop() -> None:
    speeds = np.linspace(0.0, 40.0, 81).reshape(9, 9)
    vec = propulsion_power_w(speeds)
    assert vec.shape == speeds.shape
    loop = np.array([float(propulsion_power_w(float(s))) for s in speeds.ravel()])
    np.testing.assert_allclose(vec.ravel(), loop, rtol=0, atol=1e-12)


def test_power_minimum_speed() -> None:
    # Eq. (12) with Table I is minimised at V ≈ 10.2 m/s (max-endurance speed, P ≈ 126.0 W);
    # the ~18.3 m/s speed visible in the paper's Fig. 2 is the max-range speed, which
    # minimises energy per metre P(V)/V (tangent from the origin), not P(V) itself.
    grid = np.linspace(0.0, 40.0, 40001)
    power = propulsion_power_w(grid)
    v_min = grid[np.argmin(power)]
    assert 10.0 < v_min < 20.0
    assert v_min == pytest.approx(10.21, abs=0.05)
    assert power.min() == pytest.approx(125.99, abs=0.01)
    assert max_endurance_speed_mps() == pytest.approx(v_min, abs=1e-3)

    per_metre = power[1:] / grid[1:]
    v_range = grid[1:][np.argmin(per_metre)]
    assert v_range == pytest.approx(18.29, abs=0.05)
    assert max_range_speed_mps() == pytest.approx(v_range, abs=1e-3)


def test_mission_energy() -> None:
    speeds = np.array([0.0, 10.0, 10.0, 25.0])
    slot = 0.5
    expected = sum(float(propulsion_power_w(v)) for v in speeds) * slot
    assert mission_energy_j(speeds, slot) == pytest.approx(expected)
    # One minute of hover.
    assert mission_energy_j(np.zeros(60), 1.0) == pytest.approx(60 * 168.484, abs=0.1)
    assert mission_energy_j(np.array([]), 1.0) == 0.0


def test_custom_params_and_validation() -> None:
    heavy = RotaryWingParams(W=40.0)
    assert float(propulsion_power_w(0.0, heavy)) > float(propulsion_power_w(0.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        heavy.W = 10.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        RotaryWingParams(rho=0.0)
    with pytest.raises(ValueError):
        propulsion_power_w(np.array([1.0, -1.0]))
    with pytest.raises(ValueError):
        mission_energy_j(np.ones(3), -1.0)
