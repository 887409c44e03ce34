"""Map and mission exports of a run folder: KML, GeoJSON and QGroundControl ``.plan``.

All three read the run's files only (``slots.csv``, ``summary.json``, ``scenario.json``).
Latitude/longitude come from the local ``x_m``/``y_m`` columns and the scenario's frame
origin (not from the rounded ``lat``/``lon`` columns), so an export is as exact as the run.

* KML / GeoJSON: the flown path (altitude relative to take-off), the towers, the geofence
  and the hover points (sensor, start, duration), for Google Earth and QGIS.
* ``.plan``: the QGroundControl mission of an *autonomous* run. The flown path is reduced
  to waypoints (MAV_CMD_NAV_WAYPOINT, command 16, frame 3 = global, relative altitude):
  every place the UAV stayed for whole slots becomes a waypoint whose param1 (hold time)
  is the time it stayed there, and the moving stretches in between are simplified
  (Ramer-Douglas-Peucker) so that the straight legs between waypoints stay within
  ``tolerance_m`` of every flown position. A fixed run's path is the scenario's own
  waypoint list, so exporting it as a plan is refused.

Each writer has a reader that parses the file back (used by the round-trip tests and handy
for checking a file edited by hand).
"""

from __future__ import annotations

import itertools
import json
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.io.run_folder import RunData, hover_segments, load_run
from skymule.io.runs import is_run_dir
from skymule.registry import Registry

KML_NS = "http://www.opengis.net/kml/2.2"
#: MAVLink MAV_CMD_NAV_WAYPOINT; param1 = hold time [s].
MAV_CMD_NAV_WAYPOINT = 16
#: MAV_FRAME_GLOBAL_RELATIVE_ALT: altitude relative to the home (take-off) point.
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
#: Two slot positions closer than this count as "the UAV stayed" [m].
STAY_TOLERANCE_M = 0.05


@dataclass(frozen=True)
class MapPoint:
    """A named point: tower, hover point or home (degrees; altitude [m] relative to take-off)."""

    name: str
    kind: str
    lat: float
    lon: float
    alt_m: float = 0.0
    properties: tuple[tuple[str, Any], ...] = ()


@dataclass(frozen=True)
class MapExport:
    """What KML/GeoJSON exports hold (and their readers return).

    Attributes:
        path_lat_lon_alt: (T, 3) flown path: lat [deg], lon [deg], altitude [m].
        fence_lat_lon: (K, 2) geofence ring, or None.
        points: towers, hover points and home.
    """

    path_lat_lon_alt: np.ndarray
    fence_lat_lon: np.ndarray | None
    points: tuple[MapPoint, ...]

    def of_kind(self, kind: str) -> list[MapPoint]:
        return [p for p in self.points if p.kind == kind]


def require_run(run_dir: Path) -> RunData:
    """A run folder's data; a compare folder or anything else is a one-line error."""
    if not is_run_dir(run_dir) and run_dir.is_dir():
        children = sorted(p.name for p in run_dir.iterdir() if is_run_dir(p))
        if children:
            raise SkymuleError(
                f"{run_dir}: a compare folder; export one of its runs "
                f"({', '.join(str(run_dir / c) for c in children)})"
            )
    return load_run(run_dir)


def map_export(run: RunData) -> MapExport:
    """The map content of a run (no file written)."""
    site, slots = run.site, run.slots
    lat, lon = site.latlon(slots["x_m"].to_numpy(float), slots["y_m"].to_numpy(float))
    alt = slots["z_m"].to_numpy(float) if "z_m" in slots else np.zeros(len(slots))
    fence = None
    if site.fence_xy_m is not None:
        f_lat, f_lon = site.latlon(site.fence_xy_m[:, 0], site.fence_xy_m[:, 1])
        fence = np.column_stack([f_lat, f_lon])
    points = []
    for index in site.known_sensors:
        x_m, y_m, z_m = site.sensor_xyz_m[index]
        t_lat, t_lon = site.latlon(x_m, y_m)
        points.append(MapPoint(site.sensor_names[index], "tower", float(t_lat), float(t_lon), z_m))
    for number, hover in enumerate(hover_segments(slots, run.slot_s), start=1):
        h_lat, h_lon = site.latlon(hover.x_m, hover.y_m)
        points.append(
            MapPoint(
                f"hover {number}: {hover.sensor} {hover.duration_s:g} s",
                "hover",
                float(h_lat),
                float(h_lon),
                hover.z_m,
                (
                    ("sensor", hover.sensor),
                    ("start_s", hover.start_s),
                    ("duration_s", hover.duration_s),
                    ("downloaded_mbit", round(hover.downloaded_mbit, 6)),
                ),
            )
        )
    home_lat, home_lon = site.latlon(*site.home_xy_m)
    points.append(MapPoint("home", "home", float(home_lat), float(home_lon), 0.0))
    return MapExport(np.column_stack([lat, lon, alt]), fence, tuple(points))


# ---------------------------------------------------------------------------
# GeoJSON
# ---------------------------------------------------------------------------


def _feature(geometry: dict[str, Any], properties: dict[str, Any]) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def geojson_document(export: MapExport, name: str) -> dict[str, Any]:
    """GeoJSON FeatureCollection (RFC 7946: [lon, lat, alt] order)."""
    path = export.path_lat_lon_alt
    features = [
        _feature(
            {"type": "LineString", "coordinates": [[lo, la, al] for la, lo, al in path.tolist()]},
            {"kind": "path", "name": f"{name} flown path", "altitude": "relative to take-off"},
        )
    ]
    if export.fence_lat_lon is not None:
        ring = [[lo, la] for la, lo in export.fence_lat_lon.tolist()]
        features.append(_feature({"type": "Polygon", "coordinates": [ring]}, {"kind": "geofence"}))
    for point in export.points:
        features.append(
            _feature(
                {"type": "Point", "coordinates": [point.lon, point.lat, point.alt_m]},
                {"kind": point.kind, "name": point.name, **dict(point.properties)},
            )
        )
    return {"type": "FeatureCollection", "name": name, "features": features}


# ---------------------------------------------------------------------------
# KML
# ---------------------------------------------------------------------------


def _sub(parent: ET.Element, tag: str, text: str | None = None) -> ET.Element:
    element = ET.SubElement(parent, f"{{{KML_NS}}}{tag}")
    if text is not None:
        element.text = text
    return element


def _coords(rows: list[list[float]]) -> str:
    return " ".join(",".join(f"{v:.9g}" for v in row) for row in rows)


def kml_document(export: MapExport, name: str) -> str:
    """KML 2.2 document: folders for the path, geofence, towers, hover points and home."""
    ET.register_namespace("", KML_NS)
    root = ET.Element(f"{{{KML_NS}}}kml")
    document = _sub(root, "Document")
    _sub(document, "name", name)
    folder = _sub(document, "Folder")
    _sub(folder, "name", "flight")
    mark = _sub(folder, "Placemark")
    _sub(mark, "name", "flown path")
    line = _sub(mark, "LineString")
    _sub(line, "altitudeMode", "relativeToGround")
    rows = [[lo, la, al] for la, lo, al in export.path_lat_lon_alt.tolist()]
    _sub(line, "coordinates", _coords(rows))
    if export.fence_lat_lon is not None:
        mark = _sub(folder, "Placemark")
        _sub(mark, "name", "geofence")
        ring = _sub(_sub(_sub(mark, "Polygon"), "outerBoundaryIs"), "LinearRing")
        _sub(ring, "coordinates", _coords([[lo, la] for la, lo in export.fence_lat_lon.tolist()]))
    for kind in ("tower", "hover", "home"):
        group = _sub(document, "Folder")
        _sub(group, "name", kind)
        for point in export.of_kind(kind):
            mark = _sub(group, "Placemark")
            _sub(mark, "name", point.name)
            data = _sub(mark, "ExtendedData")
            for key, value in (("kind", kind), *point.properties):
                item = _sub(data, "Data")
                item.set("name", key)
                _sub(item, "value", str(value))
            geometry = _sub(mark, "Point")
            _sub(geometry, "altitudeMode", "relativeToGround")
            _sub(geometry, "coordinates", _coords([[point.lon, point.lat, point.alt_m]]))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode")


# ---------------------------------------------------------------------------
# QGroundControl .plan
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Waypoint:
    """A plan waypoint in local metres with its hold time [s]."""

    x_m: float
    y_m: float
    z_m: float
    hold_s: float


def _rdp_keep(points: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Indices Ramer-Douglas-Peucker keeps of a (K, 3) polyline (both ends always)."""
    keep = np.zeros(len(points), bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        first, last = stack.pop()
        if last - first < 2:
            continue
        start, end = points[first], points[last]
        inner = points[first + 1 : last]
        chord = end - start
        length = float(np.linalg.norm(chord))
        if length == 0.0:
            distances = np.linalg.norm(inner - start, axis=1)
        else:
            along = np.clip((inner - start) @ chord / length**2, 0.0, 1.0)
            distances = np.linalg.norm(inner - (start + along[:, None] * chord), axis=1)
        worst = int(np.argmax(distances))
        if distances[worst] > tolerance_m:
            split = first + 1 + worst
            keep[split] = True
            stack += [(first, split), (split, last)]
    return np.flatnonzero(keep)


def plan_waypoints(
    positions_m: np.ndarray, slot_s: float, tolerance_m: float = 1.0
) -> list[Waypoint]:
    """Waypoints reproducing a flown path (T, 3): stays become holds, legs are simplified.

    A run of k slots starting at the same position holds there for (k - 1) slots: the last
    of them is spent flying on to the next position.
    """
    if len(positions_m) == 0:
        return []
    moved = np.linalg.norm(np.diff(positions_m, axis=0), axis=1) > STAY_TOLERANCE_M
    starts = np.flatnonzero(np.r_[True, moved])
    counts = np.diff(np.r_[starts, len(positions_m)])
    places = positions_m[starts]
    holds = (counts - 1) * slot_s
    anchors = np.flatnonzero(holds > 0).tolist()
    anchors = sorted({0, len(places) - 1, *anchors})
    keep: set[int] = set()
    for first, last in itertools.pairwise(anchors):
        keep.update((first + _rdp_keep(places[first : last + 1], tolerance_m)).tolist())
    keep.update(anchors)
    return [
        Waypoint(float(places[i, 0]), float(places[i, 1]), float(places[i, 2]), float(holds[i]))
        for i in sorted(keep)
    ]


def _mission_item(number: int, lat: float, lon: float, alt_m: float, hold_s: float) -> dict:
    return {
        "AMSLAltAboveTerrain": None,
        "Altitude": alt_m,
        "AltitudeMode": 1,
        "autoContinue": True,
        "command": MAV_CMD_NAV_WAYPOINT,
        "doJumpId": number,
        "frame": MAV_FRAME_GLOBAL_RELATIVE_ALT,
        "params": [hold_s, 0, 0, None, lat, lon, alt_m],
        "type": "SimpleItem",
    }


def plan_document(run: RunData, tolerance_m: float = 1.0) -> dict[str, Any]:
    """QGroundControl ``.plan`` JSON of an autonomous run (one-line error for a fixed run)."""
    if run.site.mode != "autonomous":
        raise SkymuleError(
            f"{run.path / 'scenario.json'}: trajectory.mode = {run.site.mode!r}; --plan exports "
            "the waypoints of an autonomous run (a fixed run flies the scenario's own waypoints)"
        )
    columns = ["x_m", "y_m", "z_m"] if "z_m" in run.slots else ["x_m", "y_m"]
    positions = run.slots[columns].to_numpy(float)
    if positions.shape[1] == 2:
        positions = np.column_stack([positions, np.zeros(len(positions))])
    waypoints = plan_waypoints(positions, run.slot_s, tolerance_m)
    site = run.site
    items = []
    for number, point in enumerate(waypoints, start=1):
        lat, lon = site.latlon(point.x_m, point.y_m)
        items.append(_mission_item(number, float(lat), float(lon), point.z_m, point.hold_s))
    home_lat, home_lon = site.latlon(*site.home_xy_m)
    fence = []
    if site.fence_xy_m is not None:
        f_lat, f_lon = site.latlon(site.fence_xy_m[:-1, 0], site.fence_xy_m[:-1, 1])
        fence = [
            {"inclusion": True, "polygon": np.column_stack([f_lat, f_lon]).tolist(), "version": 1}
        ]
    speed = float(run.scenario.get("trajectory", {}).get("max_speed_mps", 10.0))
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "geoFence": {"circles": [], "polygons": fence, "version": 2},
        "mission": {
            "cruiseSpeed": speed,
            "hoverSpeed": speed,
            "firmwareType": 12,
            "vehicleType": 2,
            "globalPlanAltitudeMode": 1,
            "items": items,
            "plannedHomePosition": [float(home_lat), float(home_lon), 0],
            "version": 2,
        },
        "rallyPoints": {"points": [], "version": 2},
    }


# ---------------------------------------------------------------------------
# Registry used by the CLI
# ---------------------------------------------------------------------------


def _write_geojson(run: RunData, out: Path) -> None:
    atomic.write_text(out, json.dumps(geojson_document(map_export(run), run.label), indent=1))


def _write_kml(run: RunData, out: Path) -> None:
    atomic.write_text(out, kml_document(map_export(run), run.label))


def _write_plan(run: RunData, out: Path) -> None:
    atomic.write_text(out, json.dumps(plan_document(run), indent=2))


EXPORTERS: Registry[Callable[[RunData, Path], None]] = Registry("export")
"""Export name -> writer(run, path); ``file`` (metadata) is the file it writes in the run folder."""

EXPORTERS.register("kml", _write_kml, file="flight.kml")
EXPORTERS.register("geojson", _write_geojson, file="flight.geojson")
EXPORTERS.register("plan", _write_plan, file="mission.plan")


def export_run(run_dir: Path, kinds: list[str]) -> list[Path]:
    """Write the requested exports into the run folder; returns their paths."""
    if not kinds:
        raise SkymuleError(f"choose at least one export: {', '.join('--' + k for k in EXPORTERS)}")
    for kind in kinds:
        EXPORTERS.entry(kind)  # every name checked before anything is written
    run = require_run(run_dir)
    written = []
    for kind in kinds:
        writer = EXPORTERS.get(kind)
        file_name = EXPORTERS.meta(kind, "file")
        writer(run, run_dir / file_name)
        written.append(run_dir / file_name)
    return written
