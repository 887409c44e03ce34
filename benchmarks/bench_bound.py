"""Solve-time benchmark for :func:`skymule.bounds.fixed_path_bound`.

Synthetic fixed path: a lawnmower sweep over a 1 km x 1 km field at 100 m altitude, with
four sensors at different positions and a free-space-like rate profile
``R = B log2(1 + snr0 / (d / d0)^2)``. Buffers are 500/800/700/1000 Mbit, ``dt = 1 s``.
The path has as many samples as the mission has slots (K = T).

Then, for the fixed presets ``paper-sim-fixed`` and ``aadm-default``: the bound (with and
without hovering), each policy's download and its gap to the bound (Mbit and fraction).

Run: ``python benchmarks/bench_bound.py`` (``SKYMULE_BENCH_TINY=1``: one preset, 50/120-slot
paths)
"""

from __future__ import annotations

import numpy as np
from _sizes import size

from skymule.bounds.fixed import fixed_path_bound
from skymule.bounds.mission import mission_bound
from skymule.runner import simulate
from skymule.scenario import load_scenario
from skymule.world import build_mission

SENSORS_XY_M = np.array([[150.0, 200.0], [820.0, 310.0], [420.0, 760.0], [700.0, 900.0]])
BUFFERS_BIT = np.array([500e6, 800e6, 700e6, 1000e6])
ALTITUDE_M = 100.0
BANDWIDTH_HZ = 1e5
SNR_AT_D0 = 100.0
D0_M = 100.0
SLOT_S = 1.0
PRESETS = ("paper-sim-fixed", "aadm-default")
PRESET_POLICIES = ("greedy", "hgad", "optimal-fixed")


def lawnmower_xy(n_samples: int, side_m: float = 1000.0, n_legs: int = 6) -> np.ndarray:
    """``(n_samples, 2)`` evenly spaced points (m) along a boustrophedon over a square."""
    ys = np.linspace(0.0, side_m, n_legs)
    corners = []
    for j, y in enumerate(ys):
        xs = (0.0, side_m) if j % 2 == 0 else (side_m, 0.0)
        corners += [(xs[0], y), (xs[1], y)]
    pts = np.asarray(corners)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, arc[-1], n_samples)
    return np.column_stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])])


def rates_bps(track_xy: np.ndarray) -> np.ndarray:
    """``(K, 4)`` free-space-like rate (bit/s) from each track point to each sensor."""
    horiz = np.linalg.norm(track_xy[:, None, :] - SENSORS_XY_M[None, :, :], axis=2)
    dist = np.hypot(horiz, ALTITUDE_M)
    return BANDWIDTH_HZ * np.log2(1.0 + SNR_AT_D0 / (dist / D0_M) ** 2)


def preset_gaps(preset: str) -> None:
    """Print the bound and every policy's download and gap to it for one preset."""
    scenario = load_scenario(preset)
    mission = build_mission(scenario)
    bound = mission_bound(mission)
    upper = bound.upper_bound_bit / 1e6
    no_hover = (bound.no_hover_upper_bound_bit or 0.0) / 1e6
    print(
        f"{preset}: bound {upper:.1f} Mbit (no hover {no_hover:.1f}, buffers "
        f"{bound.total_buffer_bit / 1e6:.1f}), solved in {bound.solve_time_s:.3f} s"
    )
    for policy in PRESET_POLICIES:
        got = simulate(scenario, policy, mission=mission).summary["total_downloaded_mbit"]
        gap = upper - got
        print(f"  {policy:<14} {got:8.1f} Mbit  gap {gap:7.1f} Mbit ({gap / upper:6.2%})")


def main() -> None:
    for preset in size(PRESETS, PRESETS[:1]):
        preset_gaps(preset)
    for n_slots in size((500, 3600), (50, 120)):
        rate = rates_bps(lawnmower_xy(n_slots))
        for hover in (True, False):
            res = fixed_path_bound(rate, BUFFERS_BIT, SLOT_S, n_slots, hover_allowed=hover)
            label = "hover" if hover else "no hover"
            print(
                f"bound {n_slots} slots x {rate.shape[1]} sensors ({label}): "
                f"{res.solve_time_s:.2f} s, {res.upper_bound_bit / 1e6:.1f} Mbit "
                f"[last sample {res.last_sample}, {res.status}]"
            )


if __name__ == "__main__":
    main()
