"""An upper bound on what any autonomous policy can download (time-expanded reach LP).

Setting (the slot contract of DESIGN.md and :mod:`skymule.engine_autonomous`)
------------------------------------------------------------------------------
``T`` slots of ``dt`` seconds; the UAV starts at home ``h``, flies at altitude ``z`` inside the
geofence ``F`` and moves at most ``s = v_max dt`` metres per slot along an in-fence path. In
slot ``t`` it sits at ``r_t``, serves at most one sensor ``i`` and gets
``y = min(R_i(r_t) dt, Q_i)`` bits, ``R_i(r) = f(SNR_i(r) + g[t, i])`` with ``f`` the
(non-decreasing) rate table and ``g`` the per-slot fading of the mission (zero without fading).

Reach sets. Every slot moves at most ``s`` of in-fence travel distance, and Euclidean distance
never exceeds travel distance, so ``|r_t - h| <= t s``. With ``return_home`` the engine keeps
``d_home(r_{t+1}) <= (T - t - 1) s`` after every slot (the UAV is home at ``T``), hence also
``|r_t - h| <= (T - t) s``. So ``r_t`` lies in ``A_t = F  ∩  disc(h, rho_t)`` with
``rho_t = s min(t, T - t)`` (``s t`` without return home).

Best rate per slot. ``Rbar[t, i] = f(max_{r in A_t} SNR_i(r) + g[t, i])`` bounds the rate
sensor ``i`` can have in slot ``t`` under any policy.

* Distance-monotone models (``fspl``, ``log-distance``, ``al-hourani``, ``3gpp-rma-av``
  without shadowing): at a fixed altitude the SNR is a non-increasing function of the
  horizontal distance to the sensor (FSPL/log-distance: loss grows with the 3-D distance;
  Al-Hourani: free space plus an excess loss that falls as the elevation angle rises;
  3GPP RMa-AV: LoS probability non-increasing in d2D and ``PL_NLoS >= PL_LoS``). So the max
  over ``A_t`` is the SNR at horizontal distance ``dist(sensor_i, A_t)``, which shapely
  computes exactly for the polygon ``F ∩ P_t``; ``P_t`` is a regular polygon *circumscribing*
  the disc (radius ``rho_t / cos(pi / n)``), a superset, so the distance can only shrink and
  the bound stays valid. This is the exact best rate (up to that polygon, 2e-5 relative).
* Other sources (two-ray, 3GPP UMa-AV, shadowing, radio maps): the SNR is evaluated on a grid
  of spacing ``grid_m`` over the fence plus the hover points, a grid point counts for slot
  ``t`` when within ``rho_t + grid_m / sqrt(2)`` of home (every point of ``A_t`` has a grid
  point within ``grid_m / sqrt(2)``), and ``margin_db`` is added. This is a bound *for the
  grid*: valid when the SNR varies by less than ``margin_db`` within ``grid_m / sqrt(2)``; the
  method string says so.

The LP. With ``x[t, i]`` the fraction of slot ``t`` spent serving ``i``::

    max  sum_{t,i} Rbar[t,i] dt x[t,i]
    s.t. sum_i x[t,i] <= 1,   sum_t Rbar[t,i] dt x[t,i] <= Q_i,   x >= 0.

Validity: any run of any policy maps to ``x[t, i] = y_t / (Rbar[t, i] dt)`` for its served
sensor (``y_t <= R_i(r_t) dt <= Rbar[t, i] dt``, so ``x <= 1``), buffers cap what each sensor
gives, and the objective equals the run's download. So the LP optimum bounds every policy
(greedy, HGAD, planner...). Slots with identical ``Rbar`` rows are merged (``s[k, i]``
seconds with ``sum_i s[k, i] <= c_k dt``), which has the same optimum; solved with HiGHS.

What it ignores (why it is not tight): the UAV cannot be near two distant sensors in
consecutive slots; the reach sets use straight-line rather than in-fence travel distance (exact
for convex fences). Without fading this reduces, for a long mission, to peak-rate time sharing
``min(sum Q, ...)`` with the out-and-back travel time to each sensor's hover point subtracted.
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse as sp
import shapely
from scipy.optimize import linprog
from shapely.geometry import Point, Polygon

from skymule.bounds import BoundResult
from skymule.engine_autonomous import build_geometry
from skymule.errors import SkymuleError
from skymule.world import Mission

__all__ = ["MONOTONE_MODELS", "autonomous_bound", "best_rate_bps", "reach_radii_m"]

#: Path-loss models whose SNR (no shadowing) is non-increasing in horizontal distance at a
#: fixed UAV altitude: the best in-set rate is at the set's point closest to the sensor.
MONOTONE_MODELS = frozenset({"fspl", "free-space", "log-distance", "al-hourani", "3gpp-rma-av"})

#: Sides of the regular polygon that circumscribes each reach disc.
DISC_SIDES = 256

#: Grid spacing [m] and SNR margin [dB] for sources that are not distance-monotone.
GRID_M = 5.0
MARGIN_DB = 1.0

#: Slack [m] added to every reach radius (the engine's feasibility slack and round-off).
REACH_SLACK_M = 1e-3

#: Largest number of grid points for the grid method (the spacing grows to respect it).
MAX_GRID_POINTS = 400_000


def reach_radii_m(n_slots: int, step_m: float, return_home: bool) -> np.ndarray:
    """(T,) radius [m] around home that bounds the UAV's position in each slot."""
    t = np.arange(n_slots, dtype=float)
    reach = t * step_m
    if return_home:
        reach = np.minimum(reach, (n_slots - t) * step_m)
    return reach + REACH_SLACK_M


def _circumscribed_disc(center: np.ndarray, radius_m: float) -> Polygon:
    """Regular polygon containing the disc (its inscribed circle has radius ``radius_m``)."""
    angles = np.linspace(0.0, 2.0 * np.pi, DISC_SIDES, endpoint=False)
    outer = radius_m / math.cos(math.pi / DISC_SIDES)
    return Polygon(
        np.column_stack([center[0] + outer * np.cos(angles), center[1] + outer * np.sin(angles)])
    )


def closest_distances_m(
    fence: Polygon, home_m: np.ndarray, sensor_xy_m: np.ndarray, radii_m: np.ndarray
) -> np.ndarray:
    """(U, N) horizontal distance [m] from each sensor to fence ∩ disc(home, radius) (a lower
    bound: the disc is replaced by a circumscribed polygon)."""
    home = np.asarray(home_m, float)
    corners = np.asarray(fence.exterior.coords)[:, :2]
    far_m = float(np.hypot(*(corners - home).T).max())
    sensors = shapely.points(sensor_xy_m[:, 0], sensor_xy_m[:, 1])
    out = np.empty((len(radii_m), len(sensor_xy_m)))
    for u, radius in enumerate(radii_m):
        if radius >= far_m:
            region = fence
        else:
            region = fence.intersection(_circumscribed_disc(home, float(radius)))
            if region.is_empty:  # only round-off can get here: home is in the fence
                region = Point(home)
        out[u] = shapely.distance(region, sensors)
    return out


def _exact_best_snr(
    mission: Mission, altitude_m: float, radii_m: np.ndarray, fence: Polygon, home_m: np.ndarray
) -> np.ndarray:
    """(U, N) best SNR [dB] over the reach set of each radius (distance-monotone models)."""
    assert mission.source is not None
    sensors = mission.sensor_m
    dist = closest_distances_m(fence, home_m, sensors[:, :2], radii_m)
    n = mission.n_sensors
    # a UAV position at exactly that horizontal distance from sensor i, at flight altitude
    probe = np.empty((len(radii_m), n, 3))
    probe[..., 0] = sensors[None, :, 0] + dist
    probe[..., 1] = sensors[None, :, 1]
    probe[..., 2] = altitude_m
    snr = mission.source.snr_db(probe.reshape(-1, 3)).reshape(len(radii_m), n, n)
    return snr[:, np.arange(n), np.arange(n)]


def _grid_best_snr(
    mission: Mission,
    altitude_m: float,
    radii_m: np.ndarray,
    fence: Polygon,
    home_m: np.ndarray,
    hover_m: np.ndarray,
    grid_m: float,
    margin_db: float,
) -> tuple[np.ndarray, float]:
    """(U, N) grid max SNR [dB] + margin over the inflated reach sets; the spacing used [m]."""
    assert mission.source is not None
    region = fence.intersection(_circumscribed_disc(home_m, float(radii_m.max()) + grid_m))
    x0, y0, x1, y1 = region.bounds
    spacing = max(grid_m, math.sqrt((x1 - x0) * (y1 - y0) / MAX_GRID_POINTS))
    gx, gy = np.meshgrid(np.arange(x0, x1 + spacing, spacing), np.arange(y0, y1 + spacing, spacing))
    keep = shapely.covers(region.buffer(spacing), shapely.points(gx.ravel(), gy.ravel()))
    points = np.vstack(
        [
            np.column_stack([gx.ravel()[keep], gy.ravel()[keep]]),
            home_m[None],
            hover_m[np.all(np.isfinite(hover_m), axis=1)],
        ]
    )
    snr = mission.source.snr_db(np.column_stack([points, np.full(len(points), altitude_m)]))
    snr = np.nan_to_num(snr, nan=-np.inf)
    order = np.argsort(np.hypot(*(points - home_m).T))
    dist_sorted = np.hypot(*(points[order] - home_m).T)
    running = np.maximum.accumulate(snr[order], axis=0)
    index = np.searchsorted(dist_sorted, radii_m + spacing / math.sqrt(2.0), side="right") - 1
    return running[np.maximum(index, 0)] + margin_db, spacing


def best_rate_bps(
    mission: Mission, *, grid_m: float = GRID_M, margin_db: float = MARGIN_DB
) -> tuple[np.ndarray, str]:
    """(T, N) best rate [bit/s] any policy can have to each sensor in each slot, and how.

    Raises SkymuleError (one line) for missions this bound does not cover.
    """
    spec = mission.scenario.trajectory
    if spec.mode != "autonomous":
        raise SkymuleError(
            f"autonomous bound: trajectory.mode = {spec.mode!r}; it needs 'autonomous' "
            "(use the fixed-trajectory bound for fixed paths)"
        )
    if mission.source is None:
        raise SkymuleError("autonomous bound: needs a position-queryable signal.source (model)")
    geometry = build_geometry(mission)
    fence = geometry.navigator.fence
    radii = reach_radii_m(mission.n_slots, geometry.max_step_m, spec.return_home)
    unique, inverse = np.unique(radii, return_inverse=True)
    radio = mission.scenario.radio
    monotone = (
        mission.scenario.signal.source == "model"
        and radio.model in MONOTONE_MODELS
        and radio.shadowing_std_db == 0
        and (radio.model != "al-hourani" or _al_hourani_monotone(mission))
    )
    if monotone:
        snr = _exact_best_snr(mission, geometry.altitude_m, unique, fence, geometry.home_m)
        how = f"exact reach sets ({radio.model} is distance-monotone)"
    else:
        snr, spacing = _grid_best_snr(
            mission,
            geometry.altitude_m,
            unique,
            fence,
            geometry.home_m,
            geometry.hover_points_m,
            grid_m,
            margin_db,
        )
        how = (
            f"grid reach sets ({spacing:g} m grid + {margin_db:g} dB margin; valid if the "
            f"SNR varies < {margin_db:g} dB within {spacing / math.sqrt(2):.1f} m)"
        )
    snr_t = snr[inverse]
    if mission.fading_db is not None:
        snr_t = snr_t + mission.fading_db
    return mission.rate_bps(snr_t), how


def _al_hourani_monotone(mission: Mission) -> bool:
    from skymule.radio.pathloss import AL_HOURANI_ENVIRONMENTS

    env = AL_HOURANI_ENVIRONMENTS[mission.scenario.radio.environment]
    return env.eta_nlos_db >= env.eta_los_db


def time_sharing_lp(
    rate_bps: np.ndarray, buffers_bit: np.ndarray, slot_s: float
) -> tuple[float, str]:
    """Optimum [bit] and status of max sum R s, sum_i s[t,i] <= dt, sum_t R s <= Q.

    ``rate_bps`` (T, N) [bit/s]; identical rows are merged. Returns (bits, status).
    """
    rate = np.asarray(rate_bps, float)
    buffers = np.asarray(buffers_bit, float)
    rate = np.where(buffers[None, :] > 0, rate, 0.0)
    rows, counts = np.unique(rate, axis=0, return_counts=True)
    k, n = rows.shape
    col_k, col_i = np.nonzero(rows > 0)
    if not len(col_k):
        return 0.0, "no rate"
    r = rows[col_k, col_i]
    m = len(r)
    a_time = sp.csr_array((np.ones(m), (col_k, np.arange(m))), shape=(k, m))
    a_buf = sp.csr_array((r, (col_i, np.arange(m))), shape=(n, m))
    res = linprog(
        -r,
        A_ub=sp.vstack([a_time, a_buf]).tocsr(),
        b_ub=np.concatenate([counts * slot_s, buffers]),
        bounds=(0, None),
        method="highs",
    )
    if res.status != 0:
        raise SkymuleError(f"autonomous bound: HiGHS failed ({res.message})")
    return float(min(-res.fun, buffers.sum())), str(res.message)


def autonomous_bound(mission: Mission) -> BoundResult:
    """Upper bound [bit] on the download of any autonomous policy (see the module docstring).

    ``served_time_s``/``dwell_time_s`` are empty ((0, N) and (0,)): there is no path to index;
    ``last_sample`` is -1.
    """
    start = time.perf_counter()
    rate, how = best_rate_bps(mission)
    bits, status = time_sharing_lp(rate, mission.buffers_bit, mission.slot_s)
    return BoundResult(
        upper_bound_bit=bits,
        method=f"autonomous time-expanded reach LP: {how}; HiGHS",
        status=status,
        solve_time_s=time.perf_counter() - start,
        served_time_s=np.zeros((0, mission.n_sensors)),
        dwell_time_s=np.zeros(0),
        last_sample=-1,
    )
