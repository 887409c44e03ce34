"""Geodesy and geofences.

Inside skymule every position is in a local east/north/up frame in metres whose origin is the
scenario's ``[site] origin``. Latitude/longitude only appear at the edges (scenario files,
recorded traces, exports). The projection is an azimuthal equidistant projection centred on
the origin (pyproj), which keeps distances from the origin exact and is well below a
centimetre off anywhere within a few kilometres, the scale of a data-mule site.

Geofences are shapely polygons in the same local frame, loaded from a built-in name
(``"lake-wheeler"``), a GeoJSON file or a KML file.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pyproj
import shapely
from shapely.geometry import Polygon

from skymule.errors import SkymuleError
from skymule.io.textfiles import parse_json

#: Built-in site files shipped as package data.
#: ``lake_wheeler.geojson`` holds the AERPAW Lake Wheeler phase-1 UAV geofence, the AADM
#: launch point and towers LW1..LW5 (coordinates from AERPAW Dataset 12 ``locations.txt``,
#: antenna heights relative to LW1's ground from its terrain model plus 10 m of mast).
BUILTIN_SITES: dict[str, str] = {"lake-wheeler": "lake_wheeler.geojson"}


@dataclass(frozen=True)
class LocalFrame:
    """Local east/north frame in metres centred on ``(origin_lat_deg, origin_lon_deg)``."""

    origin_lat_deg: float
    origin_lon_deg: float
    _proj: pyproj.Proj = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        proj = pyproj.Proj(
            proj="aeqd", lat_0=self.origin_lat_deg, lon_0=self.origin_lon_deg, datum="WGS84"
        )
        object.__setattr__(self, "_proj", proj)

    def to_local(self, lat_deg: Any, lon_deg: Any) -> tuple[np.ndarray, np.ndarray]:
        """Latitude/longitude in degrees -> (x east, y north) in metres (vectorised)."""
        x_m, y_m = self._proj(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        return np.asarray(x_m, float), np.asarray(y_m, float)

    def to_latlon(self, x_m: Any, y_m: Any) -> tuple[np.ndarray, np.ndarray]:
        """(x east, y north) in metres -> latitude/longitude in degrees (vectorised)."""
        lon, lat = self._proj(np.asarray(x_m, float), np.asarray(y_m, float), inverse=True)
        return np.asarray(lat, float), np.asarray(lon, float)


@dataclass(frozen=True)
class SitePoint:
    """A named point of a built-in site (tower or launch point)."""

    name: str
    kind: str
    lat_deg: float
    lon_deg: float
    antenna_height_m: float | None = None


@dataclass(frozen=True)
class Site:
    """A built-in site: geofence ring (lon, lat) and named points."""

    name: str
    geofence_lonlat: tuple[tuple[float, float], ...]
    points: tuple[SitePoint, ...]

    def point(self, name: str) -> SitePoint:
        for point in self.points:
            if point.name == name:
                return point
        raise KeyError(name)

    @property
    def towers(self) -> tuple[SitePoint, ...]:
        return tuple(p for p in self.points if p.kind == "tower")

    @property
    def launch(self) -> SitePoint:
        return next(p for p in self.points if p.kind == "launch")


@functools.cache
def load_site(name: str) -> Site:
    """Load a built-in site by name (e.g. ``"lake-wheeler"``); read once per process (a
    site is immutable, and every mission built on it asks)."""
    if name not in BUILTIN_SITES:
        raise SkymuleError(
            f"site {name!r} is not built in; built-in sites: {', '.join(sorted(BUILTIN_SITES))}"
        )
    text = resources.files("skymule").joinpath("data", BUILTIN_SITES[name]).read_text()
    collection = parse_json(text)
    ring: tuple[tuple[float, float], ...] = ()
    points: list[SitePoint] = []
    for feature in collection["features"]:
        props = feature.get("properties", {})
        geometry = feature["geometry"]
        if props.get("kind") == "geofence":
            ring = tuple((float(lon), float(lat)) for lon, lat in geometry["coordinates"][0])
        elif geometry["type"] == "Point":
            lon, lat = geometry["coordinates"][:2]
            points.append(
                SitePoint(
                    name=props.get("name", ""),
                    kind=props.get("kind", "point"),
                    lat_deg=float(lat),
                    lon_deg=float(lon),
                    antenna_height_m=props.get("antenna_height_m"),
                )
            )
    # the launch point's feature name is descriptive; expose it under a short name too
    return Site(name=name, geofence_lonlat=ring, points=tuple(points))


def polygon_from_lonlat(ring_lonlat: Any, frame: LocalFrame, source: str) -> Polygon:
    """Project a lon/lat ring to a local polygon and check that it is a valid polygon."""
    ring = np.asarray(ring_lonlat, float)
    if ring.ndim != 2 or ring.shape[0] < 3:
        raise SkymuleError(f"{source}: geofence needs at least 3 vertices, got {len(ring)}")
    x_m, y_m = frame.to_local(ring[:, 1], ring[:, 0])
    polygon = Polygon(np.column_stack([x_m, y_m]))
    if not polygon.is_valid or polygon.area <= 0:
        reason = shapely.is_valid_reason(polygon)
        raise SkymuleError(f"{source}: geofence is not a valid polygon ({reason})")
    return polygon


def _geojson_ring(path: Path) -> list[list[float]]:
    try:
        data = parse_json(path.read_text())
    except (OSError, ValueError) as exc:
        raise SkymuleError(f"{path}: cannot read GeoJSON geofence ({exc})") from None
    features = data.get("features", [data]) if isinstance(data, dict) else []
    for feature in features:
        geometry = feature.get("geometry", feature) if isinstance(feature, dict) else None
        if isinstance(geometry, dict) and geometry.get("type") == "Polygon":
            return geometry["coordinates"][0]
        if isinstance(geometry, dict) and geometry.get("type") == "MultiPolygon":
            return geometry["coordinates"][0][0]
    raise SkymuleError(f"{path}: no Polygon geometry found in GeoJSON geofence")


def _kml_ring(path: Path) -> list[list[float]]:
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise SkymuleError(f"{path}: cannot read KML geofence ({exc})") from None
    for element in root.iter():
        if element.tag.endswith("Polygon"):
            for coords in element.iter():
                if coords.tag.endswith("coordinates") and coords.text:
                    ring = []
                    for token in coords.text.split():
                        parts = token.split(",")
                        try:
                            ring.append([float(parts[0]), float(parts[1])])
                        except (ValueError, IndexError):
                            raise SkymuleError(
                                f"{path}: bad KML coordinate {token!r}; expected lon,lat[,alt]"
                            ) from None
                    return ring
    raise SkymuleError(f"{path}: no Polygon with coordinates found in KML geofence")


def load_geofence(spec: str, frame: LocalFrame, base_dir: Path | None = None) -> Polygon:
    """Geofence polygon in local metres from a built-in site name or a KML/GeoJSON path."""
    if spec in BUILTIN_SITES:
        site = load_site(spec)
        return polygon_from_lonlat(site.geofence_lonlat, frame, f"site {spec!r}")
    path = Path(spec)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    if not path.exists():
        raise SkymuleError(
            f"site.geofence: {spec!r} is neither a built-in site "
            f"({', '.join(sorted(BUILTIN_SITES))}) nor an existing KML/GeoJSON file"
        )
    suffix = path.suffix.lower()
    if suffix == ".kml":
        ring = _kml_ring(path)
    elif suffix in {".geojson", ".json"}:
        ring = _geojson_ring(path)
    else:
        raise SkymuleError(f"site.geofence: {path} has suffix {suffix!r}; allowed: .kml, .geojson")
    return polygon_from_lonlat(ring, frame, str(path))


def sensor_positions_m(sensors: Any, frame: LocalFrame) -> np.ndarray:
    """(N, 3) antenna positions [m] of scenario sensors (NaN rows where none is given).

    Each sensor gives ``lat``/``lon`` (projected into ``frame``) or ``x_m``/``y_m``, and
    ``height_m``.
    """
    out = np.full((len(sensors), 3), np.nan)
    for index, sensor in enumerate(sensors):
        if sensor.lat is not None and sensor.lon is not None:
            x_m, y_m = frame.to_local(sensor.lat, sensor.lon)
            out[index] = [float(x_m), float(y_m), sensor.height_m]
        elif sensor.x_m is not None and sensor.y_m is not None:
            out[index] = [sensor.x_m, sensor.y_m, sensor.height_m]
    return out


def covers(fence: Polygon, x_m: Any, y_m: Any, tolerance_m: float = 1e-6) -> np.ndarray:
    """Boolean mask: which points lie inside or on the fence (within ``tolerance_m``)."""
    grown = fence.buffer(tolerance_m)
    return np.asarray(shapely.covers(grown, shapely.points(np.asarray(x_m), np.asarray(y_m))))
