"""QGroundControl ``.plan`` files as a fixed path and a geofence (the challenge's ``aadm.plan``).

A ``.plan`` is JSON (QGroundControl's plan file format, ``fileType = "Plan"``):

* ``mission.items``: ``SimpleItem`` entries; ``command`` 16 (MAV_CMD_NAV_WAYPOINT) and 22
  (MAV_CMD_NAV_TAKEOFF) are path points, ``params[4:7]`` = latitude, longitude, altitude
  (relative to home; ``frame`` 3). A take-off item without coordinates (0 or null) takes
  off above ``mission.plannedHomePosition``. Other commands (speed changes, RTL...) are
  skipped: they do not move the path.
* ``geoFence.polygons``: ``{"inclusion": true, "polygon": [[lat, lon], ...]}``; the UAV must
  stay inside the inclusion polygon(s) (their union must be one polygon).

Everything comes out in local metres of the scenario's frame. A missing or malformed file is
one :class:`~skymule.errors.SkymuleError` line naming the file and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from shapely.geometry import Polygon
from shapely.ops import unary_union

from skymule.errors import SkymuleError
from skymule.geo import LocalFrame, load_geofence, polygon_from_lonlat
from skymule.io.textfiles import parse_json

if TYPE_CHECKING:
    from skymule.scenario import Scenario

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_TAKEOFF = 22
PATH_COMMANDS = (MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_TAKEOFF)


@dataclass(frozen=True)
class QgcPlan:
    """A plan's path and fence in geodetic coordinates.

    Attributes:
        path: path file.
        points_lat_lon_alt: (K, 3) degrees, degrees, metres above home, in flight order.
        fences_lat_lon: inclusion polygons, each (V, 2) degrees.
        home_lat_lon: planned home position, or None.
    """

    path: Path
    points_lat_lon_alt: np.ndarray
    fences_lat_lon: tuple[np.ndarray, ...]
    home_lat_lon: tuple[float, float] | None

    def waypoints_m(self, frame: LocalFrame) -> np.ndarray:
        """(K, 3) path points in local metres (x east, y north, z above home)."""
        points = self.points_lat_lon_alt
        x_m, y_m = frame.to_local(points[:, 0], points[:, 1])
        return np.column_stack([np.asarray(x_m, float), np.asarray(y_m, float), points[:, 2]])

    def fence_m(self, frame: LocalFrame) -> Polygon | None:
        """The inclusion geofence in local metres (None when the plan has none)."""
        if not self.fences_lat_lon:
            return None
        polygons = [
            polygon_from_lonlat(ring[:, ::-1], frame, f"{self.path}: geoFence.polygons[{i}]")
            for i, ring in enumerate(self.fences_lat_lon)
        ]
        union = unary_union(polygons)
        if not isinstance(union, Polygon):
            raise SkymuleError(
                f"{self.path}: geoFence.polygons: the inclusion polygons are disjoint; "
                "skymule needs one connected fence"
            )
        return union


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SkymuleError(f"{where}: {value!r} is not a number")
    return float(value)


def _home(mission: dict[str, Any], path: Path) -> tuple[float, float] | None:
    home = mission.get("plannedHomePosition")
    if home is None:
        return None
    if not isinstance(home, list) or len(home) < 2:
        raise SkymuleError(f"{path}: mission.plannedHomePosition {home!r} is not [lat, lon, alt]")
    where = f"{path}: mission.plannedHomePosition"
    return _number(home[0], where), _number(home[1], where)


def _points(items: list[Any], home: tuple[float, float] | None, path: Path) -> np.ndarray:
    rows = []
    for index, item in enumerate(items):
        where = f"{path}: mission.items[{index}]"
        if not isinstance(item, dict):
            raise SkymuleError(f"{where} is not an object")
        if item.get("type") != "SimpleItem" or item.get("command") not in PATH_COMMANDS:
            continue
        params = item.get("params")
        if not isinstance(params, list) or len(params) < 7:
            raise SkymuleError(f"{where}.params: expected 7 values (lat, lon, alt at 4..6)")
        alt = _number(params[6], f"{where}.params[6] (altitude)")
        located = params[4] not in (None, 0) and params[5] not in (None, 0)
        if item["command"] == MAV_CMD_NAV_TAKEOFF and not located:
            if home is None:
                raise SkymuleError(f"{where}: a take-off without position needs a home position")
            rows.append([home[0], home[1], alt])
            continue
        lat = _number(params[4], f"{where}.params[4] (latitude)")
        lon = _number(params[5], f"{where}.params[5] (longitude)")
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise SkymuleError(f"{where}: ({lat}, {lon}) is not a latitude/longitude")
        rows.append([lat, lon, alt])
    return np.asarray(rows, float).reshape(-1, 3)


def _fences(data: dict[str, Any], path: Path) -> tuple[np.ndarray, ...]:
    fence = data.get("geoFence") or {}
    polygons = fence.get("polygons", []) if isinstance(fence, dict) else None
    if not isinstance(polygons, list):
        raise SkymuleError(f"{path}: geoFence.polygons is not a list")
    out = []
    for index, entry in enumerate(polygons):
        where = f"{path}: geoFence.polygons[{index}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("polygon"), list):
            raise SkymuleError(
                f"{where}: expected {{'inclusion': true, 'polygon': [[lat, lon]...]}}"
            )
        if not entry.get("inclusion", True):
            continue  # exclusion zones: not supported by the navigator, and not used by AADM
        ring = [[_number(v, f"{where}.polygon") for v in p[:2]] for p in entry["polygon"]]
        if len(ring) < 3 or any(len(p) != 2 for p in ring):
            raise SkymuleError(f"{where}.polygon: needs at least 3 [lat, lon] vertices")
        out.append(np.asarray(ring, float))
    return tuple(out)


def read_qgc_plan(path: Path) -> QgcPlan:
    """Read a QGroundControl ``.plan`` (one-line error for a missing or malformed file)."""
    try:
        data = parse_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SkymuleError(f"{path}: no such .plan file") from None
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read ({exc.strerror})") from None
    except ValueError as exc:
        raise SkymuleError(f"{path}: not a QGroundControl .plan (invalid JSON: {exc})") from None
    mission = data.get("mission") if isinstance(data, dict) else None
    if not isinstance(mission, dict) or not isinstance(mission.get("items"), list):
        raise SkymuleError(f"{path}: not a QGroundControl .plan (no mission.items list)")
    home = _home(mission, path)
    return QgcPlan(path, _points(mission["items"], home, path), _fences(data, path), home)


def plan_waypoints_m(path: Path, frame: LocalFrame) -> np.ndarray:
    """(K, 3) waypoints [m] of a plan, for ``[trajectory] waypoints = "x.plan"``."""
    return read_qgc_plan(path).waypoints_m(frame)


def plan_fence_m(path: Path, frame: LocalFrame) -> Polygon:
    """The plan's inclusion geofence [m] (one-line error if the plan has none)."""
    fence = read_qgc_plan(path).fence_m(frame)
    if fence is None:
        raise SkymuleError(f"{path}: geoFence.polygons has no inclusion polygon")
    return fence


def is_plan(spec: object) -> bool:
    return isinstance(spec, str) and spec.lower().endswith(".plan")


def scenario_fence(scenario: Scenario, frame: LocalFrame) -> Polygon | None:
    """A scenario's geofence [m]: ``site.geofence`` (site name, KML, GeoJSON or ``.plan``),
    else the inclusion fence of a ``.plan`` given as ``trajectory.waypoints``, else None."""
    spec = scenario.site.geofence
    if is_plan(spec):
        assert spec is not None
        return plan_fence_m(scenario.resolve_path(spec), frame)
    if spec:
        return load_geofence(spec, frame, Path(scenario.base_dir))
    waypoints = scenario.trajectory.waypoints
    if isinstance(waypoints, str) and is_plan(waypoints):
        return read_qgc_plan(scenario.resolve_path(waypoints)).fence_m(frame)
    return None
