"""Solve-time benchmark for :func:`skymule.bounds.fixed_path_bound`.

Synthetic fixed path: a lawnmower sweep over a 1 km x 1 km field at 100 m altitude, with
four sensors at different positions and a free-space-like rate profile
``R = B log2(1 + snr0 / (d / d0)^2)``. Buffers are 500/800/700/1000 Mbit, ``dt = 1 s``.
The path has as many samples as the mission has slots (K = T).

Scale: the fixed-path bound for 3,600 slots x 16 sensors (target < 5 s; sensors on a 4 x 4
grid, buffers a quarter of the four-sensor ones), 3,600 slots x 4 sensors and 36,000 slots x 4
sensors (target < 10 s; buffers x 20), in CPU seconds, with the default method (prefix LPs by
column generation, ``solver="columns"``) and, in the same run, the previous method
(every column in each LP, ``solver="full"``, the plain reference) with the ratio and the
relative difference of the two bounds; the same for the paper's no-hover LP. Both use HiGHS
interior point.

Then the autonomous bound's reach rates and LP on its preset, and the fleet LP (two UAVs on
fixed paths, 16 sensors) with HiGHS interior point against the previous dual simplex.

Then, for the fixed presets ``paper-sim-fixed`` and ``aadm-default``: the bound (with and
without hovering), each policy's download and its gap to the bound (Mbit and fraction).

Run: ``python benchmarks/bench_bound.py`` (``--quick`` skips the 36,000-slot case;
``SKYMULE_BENCH_TINY=1``: one preset, 50-120-slot paths; ``--json PATH``, e.g.
``benchmarks/results/bound.json``: the speed table's bound row, docs/speed.md)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _results import json_option, table, write
from _sizes import size
from skymule.bounds.autonomous import best_rate_bps, time_sharing_lp
from skymule.bounds.fixed import LP_METHOD, fixed_path_bound
from skymule.bounds.fleet import fleet_time_sharing_lp
from skymule.bounds.mission import mission_bound
from skymule.scenario import load_scenario
from skymule.tasks.simulate import simulate
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


def grid_sensors(n_side: int, side_m: float = 1000.0) -> np.ndarray:
    """``(n_side**2, 2)`` sensor positions (m) on a regular grid inside the field."""
    ticks = (np.arange(n_side) + 0.5) * side_m / n_side
    xx, yy = np.meshgrid(ticks, ticks)
    return np.column_stack([xx.ravel(), yy.ravel()])


def rates_bps(track_xy: np.ndarray, sensors_xy: np.ndarray = SENSORS_XY_M) -> np.ndarray:
    """``(K, N)`` free-space-like rate (bit/s) from each track point to each sensor."""
    horiz = np.linalg.norm(track_xy[:, None, :] - sensors_xy[None, :, :], axis=2)
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


def _solve(
    rate: np.ndarray, buffers: np.ndarray, solver: str, hover: bool
) -> tuple[float, float, str]:
    """(CPU seconds, bound in bit, status) of the bound with ``solver=solver``."""
    start = time.process_time()
    res = fixed_path_bound(rate, buffers, SLOT_S, rate.shape[0], hover_allowed=hover, solver=solver)
    return time.process_time() - start, res.upper_bound_bit, res.status


def scale_case(
    label: str, rate: np.ndarray, buffers: np.ndarray, target_s: float
) -> tuple[float, float, float]:
    """Print, with and without hover, the new method's time (vs target for the hover bound),
    the previous method's time, the ratio and the bounds' relative difference; return the
    hover bound's (new CPU s, previous CPU s, relative difference)."""
    found = []
    for hover in (True, False):
        new_s, new_bit, status = _solve(rate, buffers, "columns", hover)
        old_s, old_bit, _ = _solve(rate, buffers, "full", hover)
        verdict = f" (target < {target_s:g} s: {'ok' if new_s < target_s else 'MISSED'})"
        print(
            f"{label} ({'hover' if hover else 'no hover'}): column generation {new_s:.2f} s CPU"
            f"{verdict if hover else ''}, bound {new_bit / 1e6:.3f} Mbit "
            f"[{status.split('(')[-1].rstrip(')')}]; previous (every column) {old_s:.2f} s "
            f"-> x{old_s / max(new_s, 1e-9):.1f}, bounds differ by "
            f"{abs(new_bit - old_bit) / old_bit:.1e} (relative)",
            flush=True,
        )
        found.append((new_s, old_s, abs(new_bit - old_bit) / old_bit))
    return found[0]


def other_bounds(n_slots: int) -> None:
    """CPU time of the autonomous bound's parts (its preset) and of the fleet LP, vs before."""
    mission = build_mission(load_scenario("paper-sim-autonomous"))
    start = time.process_time()
    rate, _ = best_rate_bps(mission)
    rates_s = time.process_time() - start
    start = time.process_time()
    time_sharing_lp(rate, mission.buffers_bit, mission.slot_s)
    print(
        f"autonomous bound paper-sim-autonomous: reach rates {rates_s:.3f} s + LP "
        f"{time.process_time() - start:.3f} s CPU (HiGHS {LP_METHOD}, unchanged)"
    )
    # two UAVs sweeping the lawnmower in opposite directions: best rate reached by each slot
    forward = rates_bps(lawnmower_xy(n_slots), grid_sensors(4))
    fleet_rate = np.stack([np.maximum.accumulate(r, axis=0) for r in (forward, forward[::-1])])
    buffers = np.resize(BUFFERS_BIT, 16) / 4
    took = {}
    for method in (LP_METHOD, "highs"):
        start = time.process_time()
        fleet_time_sharing_lp(fleet_rate, buffers, SLOT_S, lp_method=method)
        took[method] = time.process_time() - start
    print(
        f"fleet LP 2 UAVs x {n_slots} slots x 16 sensors: {LP_METHOD} {took[LP_METHOD]:.2f} s "
        f"CPU; previous (highs) {took['highs']:.2f} s -> "
        f"x{took['highs'] / max(took[LP_METHOD], 1e-9):.1f}",
        flush=True,
    )


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 36,000-slot case")
    args = parser.parse_args()
    short, long = size((3600, 36000), (60, 120))  # slots (tiny mode: a smoke run)
    cases = {}
    cases[short, 16] = scale_case(
        f"bound {short} slots x 16 sensors",
        rates_bps(lawnmower_xy(short), grid_sensors(4)),
        np.resize(BUFFERS_BIT, 16) / 4,
        5.0,
    )
    cases[short, 4] = scale_case(
        f"bound {short} slots x 4 sensors", rates_bps(lawnmower_xy(short)), BUFFERS_BIT, 5.0
    )
    if not args.quick:
        cases[long, 4] = scale_case(
            f"bound {long} slots x 4 sensors",
            rates_bps(lawnmower_xy(long)),
            BUFFERS_BIT * 20,  # ten hours: buffers large enough that the bound is not their sum
            10.0,
        )
    other_bounds(short)
    for preset in size(PRESETS, PRESETS[:1]):
        preset_gaps(preset)
    for n_slots in size((500, 3600), (50, 120)):
        rate = rates_bps(lawnmower_xy(n_slots))
        for hover in (True, False):
            start = time.process_time()
            res = fixed_path_bound(rate, BUFFERS_BIT, SLOT_S, n_slots, hover_allowed=hover)
            label = "hover" if hover else "no hover"
            print(
                f"bound {n_slots} slots x {rate.shape[1]} sensors ({label}): "
                f"{time.process_time() - start:.2f} s CPU, {res.upper_bound_bit / 1e6:.1f} Mbit "
                f"[last sample {res.last_sample}, {res.status}]"
            )
    write(json_path, {"speed-bound": speed_row(cases)})


def speed_row(cases: dict[tuple[int, int], tuple[float, float, float]]) -> dict[str, object]:
    """The speed table's bound row: (slots, sensors) -> (new s, previous s, difference)."""
    what = " / ".join(f"{slots:,} × {sensors}" for slots, sensors in cases)
    new = " / ".join(f"{new_s:.2f} s" for new_s, _, _ in cases.values())
    old = " / ".join(f"{old_s:.2f} s" for _, old_s, _ in cases.values())
    worst = max(diff for *_, diff in cases.values())
    row = [
        "fixed-path bound (column generation on HiGHS interior point), slots × sensors",
        f"{what}: {new} CPU (every-column LPs in the same run: {old}); bounds differ by at "
        f"most {worst:.0e} (relative)",
        "`python benchmarks/bench_bound.py`",
    ]
    return table(["what", "figure", "command"], [row], align="lll")


if __name__ == "__main__":
    main()
