"""Site geometry of a run, read back from its ``scenario.json`` (never from a simulation).

Reports and exports need the geofence, the sensor (tower) positions and the home point in
the same local east/north frame as ``slots.csv``. They are all in the scenario the run wrote
next to its results, so a run folder copied elsewhere still draws. A geofence given as a file
path that no longer resolves is left out (with a note), never an error: the flight itself is
still worth a report.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.geo import BUILTIN_SITES, LocalFrame, load_geofence

#: Default frame origin of a scenario without ``site.origin`` (the AADM launch point).
DEFAULT_ORIGIN = (35.7274824, -78.6962749)


@dataclass(frozen=True)
class SiteGeometry:
    """Geofence, sensors and home of one run, in local metres.

    Attributes:
        origin_lat_deg, origin_lon_deg: origin of the local frame [deg].
        fence_xy_m: (K, 2) closed geofence ring [m], or None when the scenario has none
            (or its file is gone; see ``notes``).
        sensor_names: (N,) names in scenario order.
        sensor_xyz_m: (N, 3) antenna positions [m]; NaN rows where the scenario gives none.
        home_xy_m: (2,) home point [m].
        mode: ``"fixed"`` or ``"autonomous"``.
        notes: what could not be resolved, for the report.
    """

    origin_lat_deg: float
    origin_lon_deg: float
    fence_xy_m: np.ndarray | None
    sensor_names: tuple[str, ...]
    sensor_xyz_m: np.ndarray
    home_xy_m: np.ndarray
    mode: str = "fixed"
    notes: tuple[str, ...] = ()
    frame: LocalFrame = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "frame", LocalFrame(self.origin_lat_deg, self.origin_lon_deg))

    def latlon(self, x_m: Any, y_m: Any) -> tuple[np.ndarray, np.ndarray]:
        """Local metres -> (lat, lon) degrees (vectorised)."""
        return self.frame.to_latlon(x_m, y_m)

    @property
    def known_sensors(self) -> list[int]:
        """Indices of sensors with a position."""
        return [i for i in range(len(self.sensor_names)) if np.isfinite(self.sensor_xyz_m[i]).all()]


def _sensor_xyz(sensor: dict[str, Any], frame: LocalFrame) -> list[float]:
    height = float(sensor.get("height_m", 10.0))
    if "lat" in sensor and "lon" in sensor:
        x_m, y_m = frame.to_local(sensor["lat"], sensor["lon"])
        return [float(x_m), float(y_m), height]
    if "x_m" in sensor and "y_m" in sensor:
        return [float(sensor["x_m"]), float(sensor["y_m"]), height]
    return [np.nan, np.nan, np.nan]


def _home_xy(home: Any, frame: LocalFrame) -> np.ndarray:
    if isinstance(home, dict) and "lat" in home and "lon" in home:
        x_m, y_m = frame.to_local(home["lat"], home["lon"])
        return np.array([float(x_m), float(y_m)])
    if isinstance(home, list | tuple) and len(home) >= 2:
        return np.array([float(home[0]), float(home[1])])
    return np.zeros(2)


def _fence(spec: str | None, frame: LocalFrame, run_dir: Path) -> tuple[np.ndarray | None, str]:
    if not spec:
        return None, ""
    candidates = [spec] if spec in BUILTIN_SITES or Path(spec).is_absolute() else []
    candidates += [str(run_dir / spec), spec]
    for candidate in candidates:
        if candidate in BUILTIN_SITES or Path(candidate).is_file():
            try:
                polygon = load_geofence(candidate, frame)
            except SkymuleError as exc:
                return None, f"geofence {spec!r} left out ({exc})"
            return np.asarray(polygon.exterior.coords)[:, :2], ""
    return None, f"geofence file {spec!r} not found next to the run; drawn without it"


def site_geometry(scenario: dict[str, Any], run_dir: Path) -> SiteGeometry:
    """Site geometry from a run's ``scenario.json`` contents."""
    site = scenario.get("site", {})
    origin = site.get("origin", {})
    lat0 = float(origin.get("lat", DEFAULT_ORIGIN[0]))
    lon0 = float(origin.get("lon", DEFAULT_ORIGIN[1]))
    frame = LocalFrame(lat0, lon0)
    sensors = scenario.get("sensors", [])
    fence, note = _fence(site.get("geofence"), frame, run_dir)
    trajectory = scenario.get("trajectory", {})
    xyz = np.array([_sensor_xyz(s, frame) for s in sensors], float).reshape(-1, 3)
    return SiteGeometry(
        origin_lat_deg=lat0,
        origin_lon_deg=lon0,
        fence_xy_m=fence,
        sensor_names=tuple(str(s.get("name", f"S{i + 1}")) for i, s in enumerate(sensors)),
        sensor_xyz_m=xyz,
        home_xy_m=_home_xy(trajectory.get("home"), frame),
        mode=str(trajectory.get("mode", "fixed")),
        notes=(note,) if note else (),
    )
