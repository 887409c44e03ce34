"""An upper bound on what any autonomous policy can download (time-expanded reach LP).

Setting (the slot contract of docs/contract.md and :mod:`skymule.sim.autonomous`)
------------------------------------------------------------------------------
``T`` slots of ``dt`` seconds; the UAV starts at home ``h``, flies at altitude ``z`` inside the
geofence ``F`` and moves at most ``s = v_max dt`` metres per slot along an in-fence path. In
slot ``t`` it sits at ``r_t``, serves at most one sensor ``i`` and gets
``y = min(R_i(r_t) dt, Q_i)`` bits, ``R_i(r) = f(SNR_i(r) + g[t, i])`` with ``f`` the
(non-decreasing) rate table and ``g`` the per-slot fading of the mission (zero without fading).

Reach sets. Every slot moves at most ``s`` of in-fence travel (geodesic) distance ``d_F``, so
``d_F(h, r_t) <= t s``. With ``return_home`` the engine keeps ``d_F(r_{t+1}, h) <= (T - t - 1) s``
after every slot (the UAV is home at ``T``), hence also ``d_F(h, r_t) <= (T - t) s``. So ``r_t``
lies in the geodesic ball ``B_t = {p in F : d_F(h, p) <= rho_t}``, ``rho_t = s min(t, T - t)``
(``s t`` without return home). Two supersets of ``B_t`` (``reach=``):

* ``"euclidean"``: ``E_t = F ∩ disc(h, rho_t)`` (straight-line distance never exceeds ``d_F``).
* ``"geodesic"`` (default): ``G_t = ∪_a disc(a, rho_t - g_a) ∩ V_a`` over the anchors ``a`` =
  home and the fence's reflex vertices with ``g_a = d_F(h, a) <= rho_t`` (the navigator's
  visibility graph), ``V_a`` a superset of the part of ``F`` visible from ``a``. A shortest
  in-fence path from ``h`` to ``p`` is a polyline bending only at reflex vertices; with ``a``
  its last bend (or ``h``), ``d_F(h, p) = g_a + |a - p|`` and the segment ``[a, p]`` lies in
  ``F``, so ``p in B_t`` implies ``|a - p| <= rho_t - g_a`` and ``p in V_a``: ``B_t ⊆ G_t``.
  ``V_a`` is ``F`` minus the shadows that the edges of ``F`` grown by 1 mm cast from ``a``
  (each shadow a convex polygon inside the true shadow): a segment inside ``F`` stays 1 mm
  clear of every grown edge, so no point visible from ``a`` is removed. Also
  ``G_t ⊆ disc(h, rho_t)`` since ``g_a >= |a - h|``: never looser than ``E_t`` (the code takes
  the larger of the two distances below, which makes that hold exactly). Without the
  visibility cut the home term alone would be ``E_t``. Points the UAV could only reach around
  a concave corner (Lake Wheeler's fence is not convex) are thereby excluded.

The navigator tests visibility with a 1e-6 m tolerance, so flown positions and its ``g_a`` may
differ from the exact geodesic by about that much: ``REACH_SLACK_M`` (1 mm) on every radius.

Best rate per slot. ``Rbar[t, i] = f(max_{r in A_t} SNR_i(r) + g[t, i])`` bounds the rate
sensor ``i`` can have in slot ``t`` under any policy.

* Distance-monotone models (``fspl``, ``log-distance``, ``al-hourani``, ``3gpp-rma-av``
  without shadowing): at a fixed altitude the SNR is a non-increasing function of the
  horizontal distance to the sensor (FSPL/log-distance: loss grows with the 3-D distance;
  Al-Hourani: free space plus an excess loss that falls as the elevation angle rises;
  3GPP RMa-AV: LoS probability non-increasing in d2D and ``PL_NLoS >= PL_LoS``). So the max
  over ``A_t`` (``E_t`` or ``G_t``) is the SNR at horizontal distance ``dist(sensor_i, A_t)``,
  which shapely computes exactly for polygons; every disc is replaced by a regular polygon
  *circumscribing* it (radius ``rho / cos(pi / n)``) and every geodesic radius
  ``rho_t - g_a`` is rounded *up* to a 1 mm grid (also the cache key): supersets, so the
  distance can only shrink and the bound stays valid. The distance to ``G_t`` is the minimum
  over anchors of the distance to ``disc(a, rho_t - g_a) ∩ V_a``, each evaluated once per
  distinct radius. This is the exact best rate over the superset (up to 8e-5 relative).
* Other sources (two-ray, 3GPP UMa-AV, shadowing, radio maps), always with the straight-line
  reach ``E_t``: the SNR is evaluated on a grid of spacing ``grid_m`` over the fence plus the
  hover points, a grid point counts for slot ``t`` when within ``rho_t + grid_m / sqrt(2)`` of
  home (every point of ``A_t`` has a grid point within ``grid_m / sqrt(2)``), and
  ``margin_db`` is added. This is a bound *for the
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
consecutive slots; ``G_t`` is a superset of the geodesic ball (``V_a`` is the whole visible
region rather than the part whose shortest paths end at ``a``; exact for convex fences, where
``G_t = E_t = B_t``). Without fading this reduces, for a long mission, to peak-rate time sharing
``min(sum Q, ...)`` with the out-and-back travel time to each sensor's hover point subtracted.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import shapely
from scipy.optimize import linprog
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

from skymule.bounds.fixed import LP_METHOD
from skymule.bounds.result import BoundResult
from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator
from skymule.radio.pathloss import PATHLOSS_MODELS
from skymule.rules.contract import seen_snr_db
from skymule.rules.home import home_budget
from skymule.world import Mission

__all__ = [
    "REACH_MODES",
    "BestRates",
    "autonomous_bound",
    "best_rate_bps",
    "best_rates",
    "closest_distances_m",
    "geodesic_closest_distances_m",
    "monotone_models",
    "reach_radii_m",
    "steepest_step_db",
]

#: Reach-set constructions (see the module docstring); the first is the default.
REACH_MODES = ("geodesic", "euclidean")


def monotone_models() -> list[str]:
    """Path-loss models whose SNR (no shadowing) is non-increasing in horizontal distance at
    a fixed UAV altitude (their registered ``monotone`` flag): the best in-set rate is at the
    set's point closest to the sensor."""
    return PATHLOSS_MODELS.where(lambda entry: entry.obj.monotone)


#: Sides of the regular polygon that circumscribes each reach disc.
DISC_SIDES = 256

#: Grid spacing [m] and SNR margin [dB] for sources that are not distance-monotone.
GRID_M = 5.0
MARGIN_DB = 1.0

#: Slack [m] added to every reach radius (the engine's feasibility slack and round-off).
REACH_SLACK_M = 1e-3

#: Largest number of grid points for the grid method (the spacing grows to respect it).
MAX_GRID_POINTS = 400_000

#: Geodesic reach: radii around each anchor are rounded UP to this grid [m] (cache key).
RADIUS_GRID_M = 1e-3

#: Outward growth [m] of the fence whose edges cast the visibility shadows (far above the
#: navigator's 1e-6 m tolerance and floating-point round-off).
VISIBILITY_MARGIN_M = 1e-3

#: Far points per shadow polygon (angular steps <= 15 degrees: an edge subtends < 180).
SHADOW_FAR_POINTS = 13


def reach_radii_m(n_slots: int, step_m: float, return_home: bool) -> np.ndarray:
    """(T,) radius [m] around home that bounds the UAV's position in each slot."""
    t = np.arange(n_slots, dtype=float)
    reach = t * step_m
    if return_home:
        reach = np.minimum(reach, home_budget(n_slots, t - 1, step_m))  # home by the end
    return reach + REACH_SLACK_M


def _circumscribed_disc(center: np.ndarray, radius_m: float) -> Polygon:
    """Regular polygon containing the disc (its inscribed circle has radius ``radius_m``)."""
    angles = np.linspace(0.0, 2.0 * np.pi, DISC_SIDES, endpoint=False)
    outer = radius_m / math.cos(math.pi / DISC_SIDES)
    return Polygon(
        np.column_stack([center[0] + outer * np.cos(angles), center[1] + outer * np.sin(angles)])
    )


def _circumscribed_discs(center: np.ndarray, radii_m: np.ndarray) -> np.ndarray:
    """(m,) array of regular polygons containing the discs of ``radii_m`` around ``center``."""
    angles = np.linspace(0.0, 2.0 * np.pi, DISC_SIDES, endpoint=False)
    outer = np.asarray(radii_m, float)[:, None] / math.cos(math.pi / DISC_SIDES)
    coords = np.stack(
        [center[0] + outer * np.cos(angles), center[1] + outer * np.sin(angles)], axis=-1
    )
    return np.asarray(shapely.polygons(coords))


def _round_up(values_m: np.ndarray, grid_m: float) -> np.ndarray:
    """``values_m`` rounded up to a multiple of ``grid_m`` (never below the input)."""
    up = np.ceil(values_m / grid_m) * grid_m
    return np.where(up < values_m, up + grid_m, up)


def visible_region(fence: Polygon, anchor_m: np.ndarray) -> BaseGeometry:
    """A superset of the part of ``fence`` visible from ``anchor_m`` (a point of the fence).

    ``fence`` minus the shadows cast from the anchor by the edges of the fence grown by
    ``VISIBILITY_MARGIN_M``: each shadow is the convex hull of an edge and far points on the
    rays through its ends, hence inside the set of points whose segment to the anchor crosses
    that edge; a segment inside the fence keeps ``VISIBILITY_MARGIN_M`` from every grown edge,
    so no visible point is removed (grazing segments included).
    """
    anchor = np.asarray(anchor_m, float)
    grown = fence.buffer(VISIBILITY_MARGIN_M, join_style="mitre")
    rings = [grown.exterior, *grown.interiors]
    coords = [np.asarray(ring.coords)[:, :2] for ring in rings]
    p0 = np.concatenate([c[:-1] for c in coords])
    p1 = np.concatenate([c[1:] for c in coords])
    d0, d1 = p0 - anchor, p1 - anchor
    cross = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
    delta = np.arctan2(cross, np.einsum("ij,ij->i", d0, d1))  # signed angle, |delta| < pi
    keep = np.abs(delta) > 1e-9  # an edge seen edge-on casts a zero-area shadow
    far_m = float(np.hypot(*(np.concatenate(coords) - anchor).T).max()) + 1.0
    half_step = math.pi / (2 * (SHADOW_FAR_POINTS - 1))
    radius = far_m / math.cos(half_step)  # the far polygon clears the disc of radius far_m
    angles = np.arctan2(d0[keep, 1], d0[keep, 0])[:, None] + delta[keep, None] * np.linspace(
        1.0, 0.0, SHADOW_FAR_POINTS
    )
    far = anchor + radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    ring = np.concatenate([p0[keep, None], p1[keep, None], far], axis=1)
    shadows = shapely.polygons(ring)
    return fence.difference(shapely.union_all(shadows))


def geodesic_closest_distances_m(
    navigator: Navigator, home_m: np.ndarray, sensor_xy_m: np.ndarray, radii_m: np.ndarray
) -> np.ndarray:
    """(U, N) horizontal distance [m] from each sensor to the geodesic reach set ``G`` of
    each radius (a lower bound on the distance to the in-fence geodesic ball; see the module
    docstring). Anchors are home and the reflex vertices within the radius."""
    home = np.asarray(home_m, float)
    sensors_xy = np.asarray(sensor_xy_m, float)[:, :2]
    radii = np.asarray(radii_m, float)
    fence = navigator.fence
    to_vertex = navigator.vertex_distances((float(home[0]), float(home[1])))
    finite = np.isfinite(to_vertex)
    anchors = np.vstack([home[None], navigator.vertices[finite]])
    anchor_g = np.concatenate([[0.0], to_vertex[finite]])
    sensors = shapely.points(sensors_xy[:, 0], sensors_xy[:, 1])
    best = np.full((len(radii), len(sensors_xy)), np.inf)
    grow = 1.0 / math.cos(math.pi / DISC_SIDES)  # circumscribed polygon / disc radius
    for anchor, g in zip(anchors, anchor_g, strict=True):  # home first: a good start for best
        rows = np.flatnonzero(radii >= g)
        if not len(rows):
            continue
        region = visible_region(fence, anchor)
        # the anchor itself is reachable (d_F(h, a) = g <= radius); also covers empty cuts
        to_anchor = np.hypot(*(sensors_xy - anchor).T)
        to_region = np.fmin(shapely.distance(region, sensors), to_anchor)
        rho_all = _round_up(radii[rows] - g, RADIUS_GRID_M)
        # skip radii where this anchor's term cannot beat the best so far for any sensor
        lower = np.minimum(
            np.maximum(to_region[None, :], to_anchor[None, :] - grow * rho_all[:, None]),
            to_anchor[None, :],
        )
        useful = (lower < best[rows]).any(axis=1)
        rows = rows[useful]
        if not len(rows):
            continue
        rho, inverse = np.unique(rho_all[useful], return_inverse=True)
        corners = shapely.get_coordinates(region)
        whole_m = float(np.hypot(*(corners - anchor).T).max()) if len(corners) else 0.0
        dist = np.empty((len(rho), len(sensors_xy)))
        whole = rho >= whole_m  # the disc covers the visible region
        dist[whole] = to_region
        if (~whole).any():
            parts = shapely.intersection(region, _circumscribed_discs(anchor, rho[~whole]))
            dist[~whole] = shapely.distance(parts[:, None], sensors[None, :])
        dist = np.fmin(dist, to_anchor[None, :])  # NaN (empty) -> the anchor
        best[rows] = np.minimum(best[rows], dist[inverse])
    return best


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
    mission: Mission,
    altitude_m: float,
    radii_m: np.ndarray,
    navigator: Navigator,
    home_m: np.ndarray,
    reach: str,
) -> np.ndarray:
    """(U, N) best SNR [dB] over the reach set of each radius (distance-monotone models)."""
    assert mission.source is not None
    sensors = mission.sensor_m
    dist = closest_distances_m(navigator.fence, home_m, sensors[:, :2], radii_m)
    if reach == "geodesic" and len(navigator.vertices):  # convex fence: G_t = E_t
        geodesic = geodesic_closest_distances_m(navigator, home_m, sensors[:, :2], radii_m)
        dist = np.maximum(dist, geodesic)  # both lower-bound the distance to B_t
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
) -> tuple[np.ndarray, float, float]:
    """(U, N) grid max SNR [dB] + margin over the inflated reach sets; the spacing used [m];
    the largest SNR change [dB] between neighbouring grid points (:func:`steepest_step_db`)."""
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
    snr = seen_snr_db(snr)
    on_grid = np.full((gx.size, snr.shape[1]), np.nan)
    on_grid[keep] = snr[: int(keep.sum())]
    steepest = steepest_step_db(on_grid.reshape(*gx.shape, snr.shape[1]))
    order = np.argsort(np.hypot(*(points - home_m).T))
    dist_sorted = np.hypot(*(points[order] - home_m).T)
    running = np.maximum.accumulate(snr[order], axis=0)
    index = np.searchsorted(dist_sorted, radii_m + spacing / math.sqrt(2.0), side="right") - 1
    return running[np.maximum(index, 0)] + margin_db, spacing, steepest


def steepest_step_db(snr_db: np.ndarray) -> float:
    """The largest SNR change [dB] between neighbouring points (along either axis) of a grid
    ``(rows, columns, N)``; NaN marks points off the grid, -inf a dead link (not a step).

    The grid method assumes the SNR varies by less than ``margin_db`` within ``s / sqrt(2)``
    of any point (``s`` the spacing). Two neighbours ``s`` apart that differ by more than
    ``2 margin_db`` break it for sure: the point halfway, ``s / 2`` from each, differs from
    one of them by more than ``margin_db``.
    """
    finite = np.where(np.isfinite(snr_db), snr_db, np.nan)
    steps = [np.abs(np.diff(finite, axis=axis)) for axis in (0, 1)]
    found = [float(np.nanmax(step)) for step in steps if np.isfinite(step).any()]
    return max(found, default=0.0)


@dataclass(frozen=True)
class BestRates:
    """What :func:`best_rates` finds: (T, N) rates [bit/s], how, and what may break it."""

    rate_bps: np.ndarray
    how: str
    warnings: tuple[str, ...] = ()


def best_rate_bps(
    mission: Mission,
    *,
    reach: str = "geodesic",
    grid_m: float = GRID_M,
    margin_db: float = MARGIN_DB,
) -> tuple[np.ndarray, str]:
    """(T, N) best rate [bit/s] any policy can have to each sensor in each slot, and how
    (:func:`best_rates` without its warnings)."""
    found = best_rates(mission, reach=reach, grid_m=grid_m, margin_db=margin_db)
    return found.rate_bps, found.how


def best_rates(
    mission: Mission,
    *,
    reach: str = "geodesic",
    grid_m: float = GRID_M,
    margin_db: float = MARGIN_DB,
) -> BestRates:
    """(T, N) best rate [bit/s] any policy can have to each sensor in each slot, how, and a
    warning when the grid method's condition visibly fails (:func:`steepest_step_db`).

    ``reach`` is ``"geodesic"`` (in-fence travel distance, the default) or ``"euclidean"``
    (straight-line disc, never tighter); the grid method always uses the straight-line disc.
    Raises SkymuleError (one line) for missions this bound does not cover.
    """
    warnings: list[str] = []
    if reach not in REACH_MODES:
        raise SkymuleError(
            f"autonomous bound: reach = {reach!r}; allowed: {', '.join(REACH_MODES)}"
        )
    if mission.mode != "autonomous":
        raise SkymuleError(
            f"autonomous bound: trajectory.mode = {mission.mode!r}; it needs 'autonomous' "
            "(use the fixed-trajectory bound for fixed paths)"
        )
    if mission.source is None:
        raise SkymuleError("autonomous bound: needs a position-queryable signal.source (model)")
    navigator, home_m, hover_m = mission.navigator, mission.home_m, mission.hover_points_m
    assert navigator is not None and home_m is not None and hover_m is not None
    fence = navigator.fence
    radii = reach_radii_m(mission.n_slots, mission.max_step_m, mission.return_home)
    unique, inverse = np.unique(radii, return_inverse=True)
    radio = mission.scenario.radio
    monotone = (
        mission.scenario.signal.source == "model"
        and PATHLOSS_MODELS.get(radio.model).monotone
        and radio.shadowing_std_db == 0
        and (radio.model != "al-hourani" or _al_hourani_monotone(mission))
    )
    if monotone:
        snr = _exact_best_snr(mission, mission.altitude_m, unique, navigator, home_m, reach)
        how = f"exact reach sets, {reach} reach ({radio.model} is distance-monotone)"
    else:
        snr, spacing, steepest = _grid_best_snr(
            mission,
            mission.altitude_m,
            unique,
            fence,
            home_m,
            hover_m,
            grid_m,
            margin_db,
        )
        within = spacing / math.sqrt(2)
        how = (
            f"grid reach sets, euclidean reach ({spacing:g} m grid + {margin_db:g} dB margin; "
            f"valid if the SNR varies < {margin_db:g} dB within {within:.1f} m)"
        )
        if steepest > 2 * margin_db:
            warnings.append(
                f"the grid bound's condition fails here: the SNR changes by up to "
                f"{steepest:.1f} dB between grid points {spacing:g} m apart, so by more than "
                f"{margin_db:g} dB within {within:.1f} m somewhere (shadowing or a fast-varying "
                "model); the bound may be below what a policy can download"
            )
    snr_t = snr[inverse]
    if mission.fading_db is not None:
        snr_t = snr_t + mission.fading_db
    return BestRates(mission.rate_bps(snr_t), how, tuple(warnings))


def _al_hourani_monotone(mission: Mission) -> bool:
    from skymule.radio.pathloss import AL_HOURANI_ENVIRONMENTS

    env = AL_HOURANI_ENVIRONMENTS[mission.scenario.radio.param("environment")]
    return env.eta_nlos_db >= env.eta_los_db


def time_sharing_lp(
    rate_bps: np.ndarray, buffers_bit: np.ndarray, slot_s: float, lp_method: str = LP_METHOD
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
        method=lp_method,
    )
    if res.status != 0:
        raise SkymuleError(f"autonomous bound: HiGHS failed ({res.message})")
    return float(min(-res.fun, buffers.sum())), str(res.message)


def autonomous_bound(mission: Mission, *, reach: str = "geodesic") -> BoundResult:
    """Upper bound [bit] on the download of any autonomous policy (see the module docstring).

    ``reach``: ``"geodesic"`` (default) or ``"euclidean"`` reach sets (see ``REACH_MODES``).
    ``served_time_s``/``dwell_time_s`` are empty ((0, N) and (0,)): there is no path to index;
    ``last_sample`` is -1.
    """
    start = time.perf_counter()
    found = best_rates(mission, reach=reach)
    bits, status = time_sharing_lp(found.rate_bps, mission.buffers_bit, mission.slot_s)
    return BoundResult(
        upper_bound_bit=bits,
        method=f"autonomous time-expanded reach LP: {found.how}; HiGHS",
        status=status,
        solve_time_s=time.perf_counter() - start,
        served_time_s=np.zeros((0, mission.n_sensors)),
        dwell_time_s=np.zeros(0),
        last_sample=-1,
        warnings=found.warnings,
    )
