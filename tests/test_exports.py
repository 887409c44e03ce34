"""KML / GeoJSON / QGroundControl .plan exports: re-read each file and compare with the run."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from skymule.geo import LocalFrame, load_site
from skymule.io.exports import (
    KML_NS,
    MAV_CMD_NAV_WAYPOINT,
    MapExport,
    MapPoint,
    export_run,
    plan_waypoints,
)
from skymule.io.runs import write_run
from skymule.report.inputs import hover_segments, load_run

# --- readers of what the exporters write (the round trips below) ---------------------------


def read_geojson_export(path: Path) -> MapExport:
    """Parse a GeoJSON written by :func:`geojson_document` back."""
    data = json.loads(path.read_text())
    track = np.zeros((0, 3))
    fence = None
    points = []
    for feature in data["features"]:
        geometry, props = feature["geometry"], dict(feature["properties"])
        kind = props.pop("kind", "")
        if kind == "path":
            track = np.array([[la, lo, al] for lo, la, al in geometry["coordinates"]], float)
        elif kind == "geofence":
            fence = np.array([[la, lo] for lo, la in geometry["coordinates"][0]], float)
        elif geometry["type"] == "Point":
            lon, lat, alt = geometry["coordinates"]
            name = props.pop("name", "")
            points.append(MapPoint(name, kind, lat, lon, alt, tuple(props.items())))
    return MapExport(track, fence, tuple(points))


def _parse_coords(text: str) -> np.ndarray:
    return np.array([[float(v) for v in token.split(",")] for token in text.split()], float)


def _value(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text


def read_kml_export(path: Path) -> MapExport:
    """Parse a KML written by :func:`kml_document` back."""
    ns = {"k": KML_NS}
    root = ET.parse(path).getroot()
    track = np.zeros((0, 3))
    fence = None
    points = []
    for mark in root.iter(f"{{{KML_NS}}}Placemark"):
        name = mark.findtext("k:name", default="", namespaces=ns)
        line = mark.find("k:LineString/k:coordinates", ns)
        ring = mark.find(".//k:LinearRing/k:coordinates", ns)
        point = mark.find("k:Point/k:coordinates", ns)
        if line is not None and line.text:
            lon_lat_alt = _parse_coords(line.text)
            track = lon_lat_alt[:, [1, 0, 2]]
        elif ring is not None and ring.text:
            fence = _parse_coords(ring.text)[:, [1, 0]]
        elif point is not None and point.text:
            lon, lat, alt = _parse_coords(point.text)[0]
            data = {
                d.get("name", ""): _value(d.findtext("k:value", default="", namespaces=ns))
                for d in mark.findall("k:ExtendedData/k:Data", ns)
            }
            kind = str(data.pop("kind", ""))
            points.append(MapPoint(name, kind, lat, lon, alt, tuple(data.items())))
    return MapExport(track, fence, tuple(points))


@dataclass(frozen=True)
class PlanItem:
    """A NAV_WAYPOINT read back from a .plan: degrees, altitude [m], hold [s]."""

    lat: float
    lon: float
    alt_m: float
    hold_s: float


def read_plan(path: Path) -> list[PlanItem]:
    """NAV_WAYPOINT items of a QGroundControl ``.plan`` (one-line error if it is not one)."""
    try:
        data = json.loads(path.read_text())
        items = data["mission"]["items"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise AssertionError(f"{path}: not a QGroundControl .plan ({exc})") from None
    return [
        PlanItem(
            float(i["params"][4]),
            float(i["params"][5]),
            float(i["params"][6]),
            float(i["params"][0]),
        )
        for i in items
        if i.get("type") == "SimpleItem" and i.get("command") == MAV_CMD_NAV_WAYPOINT
    ]


ORIGIN = (35.7274824, -78.6962749)
FRAME = LocalFrame(*ORIGIN)


def _slots(xyz: np.ndarray, served: list[str], hovering: list[int]) -> pd.DataFrame:
    """A slots.csv frame in the run-folder format for sensors LW1, LW3."""
    n = len(xyz)
    lat, lon = FRAME.to_latlon(xyz[:, 0], xyz[:, 1])
    got = np.where(np.array(served) != "", 2.0, 0.0)
    step = np.r_[np.linalg.norm(np.diff(xyz, axis=0), axis=1), 0.0]
    return pd.DataFrame(
        {
            "t_s": np.arange(n, dtype=float),
            "x_m": xyz[:, 0],
            "y_m": xyz[:, 1],
            "z_m": xyz[:, 2],
            "lat": lat,
            "lon": lon,
            "served": served,
            "snr_db_LW1": np.linspace(30, 10, n),
            "snr_db_LW3": np.linspace(10, 30, n),
            "remaining_mbit_LW1": 100 - np.cumsum(np.where(np.array(served) == "LW1", got, 0)),
            "remaining_mbit_LW3": 100 - np.cumsum(np.where(np.array(served) == "LW3", got, 0)),
            "rate_mbps": got,
            "downloaded_mbit": got,
            "hovering": hovering,
            "distance_m": np.cumsum(step),
            "speed_mps": step,
        }
    )


def make_run(folder: Path, mode: str) -> Path:
    """A hand-built run: out east, hover 5 slots on LW3, turn north, hover 3 on LW1, home."""
    leg1 = np.column_stack([np.arange(0, 100, 10.0), np.zeros(10), np.full(10, 30.0)])
    stay1 = np.tile([100.0, 0.0, 30.0], (6, 1))
    leg2 = np.column_stack([np.full(8, 100.0), np.arange(10, 90, 10.0), np.full(8, 30.0)])
    stay2 = np.tile([100.0, 90.0, 30.0], (4, 1))
    back = np.column_stack([np.linspace(90, 0, 10), np.linspace(81, 0, 10), np.full(10, 30.0)])
    xyz = np.vstack([leg1, stay1, leg2, stay2, back])
    served = [""] * 10 + ["LW3"] * 6 + [""] * 8 + ["LW1"] * 4 + [""] * 10
    hovering = [0] * 10 + [1] * 5 + [0] * 9 + [1] * 3 + [0] * 11
    slots = _slots(xyz, served, hovering)
    site = load_site("lake-wheeler")
    towers = {t.name: t for t in site.towers}
    scenario = {
        "name": "hand",
        "mission": {"duration_s": float(len(xyz)), "slot_s": 1.0},
        "site": {"origin": {"lat": ORIGIN[0], "lon": ORIGIN[1]}, "geofence": "lake-wheeler"},
        "sensors": [
            {"name": n, "lat": towers[n].lat_deg, "lon": towers[n].lon_deg, "buffer_mbit": 100.0}
            for n in ("LW1", "LW3")
        ],
        "trajectory": {"mode": mode, "max_speed_mps": 10.0, "altitude_m": 30.0},
        "policy": {"name": "hand"},
    }
    summary = {
        "scenario": "hand",
        "policy": "hand",
        "slots": len(xyz),
        "slot_s": 1.0,
        "total_downloaded_mbit": float(slots["downloaded_mbit"].sum()),
        "total_buffer_mbit": 200.0,
        "per_sensor_downloaded_mbit": {"LW1": 8.0, "LW3": 12.0},
        "per_sensor_buffer_mbit": {"LW1": 100.0, "LW3": 100.0},
        "completion": 0.1,
        "hover_time_s": 8.0,
        "visit_order": ["LW3", "LW1"],
    }
    write_run(folder, summary, slots, scenario)
    return folder


@pytest.fixture
def autonomous_run(tmp_path: Path) -> Path:
    return make_run(tmp_path / "auto", "autonomous")


def _local(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return np.column_stack(FRAME.to_local(lat, lon))


@pytest.mark.parametrize("kind", ["kml", "geojson"])
def test_map_export_round_trip(autonomous_run: Path, kind: str) -> None:
    (path,) = export_run(autonomous_run, [kind])
    back = (read_kml_export if kind == "kml" else read_geojson_export)(path)
    run = load_run(autonomous_run)
    # flown path: every slot, within a centimetre, altitude kept
    xy = _local(back.path_lat_lon_alt[:, 0], back.path_lat_lon_alt[:, 1])
    np.testing.assert_allclose(xy, run.slots[["x_m", "y_m"]].to_numpy(), atol=0.01)
    np.testing.assert_allclose(back.path_lat_lon_alt[:, 2], run.slots["z_m"], atol=1e-6)
    # towers where the scenario puts them
    towers = {p.name: p for p in back.of_kind("tower")}
    assert set(towers) == {"LW1", "LW3"}
    site = load_site("lake-wheeler")
    for tower in site.towers:
        if tower.name in towers:
            assert towers[tower.name].lat == pytest.approx(tower.lat_deg, abs=1e-7)
            assert towers[tower.name].lon == pytest.approx(tower.lon_deg, abs=1e-7)
    # geofence: the built-in ring
    assert back.fence_lat_lon is not None
    ring = np.array(site.geofence_lonlat)[:, ::-1]
    np.testing.assert_allclose(back.fence_lat_lon, ring, atol=1e-7)
    # hover points: sensor, start, duration and place
    hovers = back.of_kind("hover")
    expected = hover_segments(run.slots, 1.0)
    assert [dict(h.properties)["sensor"] for h in hovers] == ["LW3", "LW1"]
    for got, want in zip(hovers, expected, strict=True):
        props = dict(got.properties)
        assert float(props["duration_s"]) == want.duration_s
        assert float(props["start_s"]) == want.start_s
        np.testing.assert_allclose(
            _local(np.array([got.lat]), np.array([got.lon]))[0], [want.x_m, want.y_m], atol=0.01
        )
    assert [p.name for p in back.of_kind("home")] == ["home"]


def test_plan_round_trip(autonomous_run: Path) -> None:
    (path,) = export_run(autonomous_run, ["plan"])
    data = json.loads(path.read_text())
    assert data["fileType"] == "Plan" and data["groundStation"] == "QGroundControl"
    items = data["mission"]["items"]
    assert all(i["command"] == MAV_CMD_NAV_WAYPOINT == 16 for i in items)
    assert [i["doJumpId"] for i in items] == list(range(1, len(items) + 1))
    assert data["geoFence"]["polygons"][0]["inclusion"] is True
    plan = read_plan(path)
    run = load_run(autonomous_run)
    xy = _local(np.array([p.lat for p in plan]), np.array([p.lon for p in plan]))
    holds = {(round(x), round(y)): p.hold_s for (x, y), p in zip(xy, plan, strict=True)}
    # stays become holds: 6 slots at (100, 0) -> 5 s, 4 slots at (100, 90) -> 3 s
    assert holds[(100, 0)] == 5.0
    assert holds[(100, 90)] == 3.0
    assert sum(p.hold_s for p in plan) == 8.0
    # the straight legs cover the flown path: corners kept, straight stretches dropped
    assert len(plan) == 4  # start, hover 1 and hover 2 (the corners), back at the start
    np.testing.assert_allclose(xy[0], [0, 0], atol=0.01)
    np.testing.assert_allclose(xy[-1], run.slots[["x_m", "y_m"]].to_numpy()[-1], atol=0.01)
    assert all(p.alt_m == 30.0 for p in plan)


def test_plan_waypoints_stay_within_tolerance() -> None:
    rng = np.random.default_rng(3)
    walk = np.cumsum(rng.normal(0, 3, (200, 3)) * np.array([1, 1, 0]), axis=0) + np.array(
        [0, 0, 25]
    )
    walk[50:60] = walk[50]  # a 9-slot stay
    points = plan_waypoints(walk, 1.0, tolerance_m=1.0)
    legs = np.array([[p.x_m, p.y_m, p.z_m] for p in points])
    for position in walk:
        starts, ends = legs[:-1], legs[1:]
        chord = ends - starts
        along = np.clip(
            np.einsum("ij,ij->i", position - starts, chord)
            / np.maximum(np.einsum("ij,ij->i", chord, chord), 1e-12),
            0,
            1,
        )
        assert np.min(np.linalg.norm(starts + along[:, None] * chord - position, axis=1)) <= 1.0
    assert [p.hold_s for p in points if p.hold_s > 0] == [9.0]
    assert len(points) < len(walk)


def test_plan_of_fixed_run_is_one_line_error(tmp_path: Path) -> None:
    fixed = make_run(tmp_path / "fixed", "fixed")
    done = run_cli("export", fixed, "--plan")
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1
    assert "trajectory.mode = 'fixed'" in done.stderr and "autonomous" in done.stderr
    assert not (fixed / "mission.plan").exists()


def test_cli_export_writes_kml_and_geojson(autonomous_run: Path) -> None:
    done = run_cli("export", autonomous_run, "--kml", "--geojson")
    assert done.returncode == 0, done.stderr
    assert read_kml_export(autonomous_run / "flight.kml").path_lat_lon_alt.shape == (38, 3)
    assert read_geojson_export(autonomous_run / "flight.geojson").fence_lat_lon is not None
