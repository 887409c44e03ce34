"""QGroundControl .plan files: read as a fixed path + geofence; export --plan reads back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.geo import LocalFrame, load_geofence
from skymule.io.exports import plan_waypoints
from skymule.io.qgc_plan import read_qgc_plan
from skymule.scenario import load_scenario
from skymule.world import build_mission

FRAME = LocalFrame(35.7274824, -78.6962749)  # AADM launch point: the presets' origin


@pytest.fixture(scope="module")
def exported_plan(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("plan")
    done = run_cli("run", "paper-sim-autonomous", "--out", "run", cwd=folder)
    assert done.returncode == 0, done.stderr
    done = run_cli("export", "run", "--plan", cwd=folder)
    assert done.returncode == 0, done.stderr
    return folder / "run", folder / "run" / "mission.plan"


def test_export_plan_reads_back_to_the_same_path(exported_plan: tuple[Path, Path]) -> None:
    run_dir, path = exported_plan
    plan = read_qgc_plan(path)
    slots = pd.read_csv(run_dir / "slots.csv")
    flown = slots[["x_m", "y_m", "z_m"]].to_numpy(float)
    expected = np.array([[w.x_m, w.y_m, w.z_m] for w in plan_waypoints(flown, 1.0)])
    np.testing.assert_allclose(plan.waypoints_m(FRAME), expected, atol=0.01)
    # every waypoint lies on the flown path, which starts and ends at home
    waypoints = plan.waypoints_m(FRAME)
    gaps = np.linalg.norm(waypoints[:, None, :2] - flown[None, :, :2], axis=2).min(axis=1)
    assert gaps.max() < 0.01
    # the fence is the scenario's (Lake Wheeler phase 1)
    fence = plan.fence_m(FRAME)
    site = load_geofence("lake-wheeler", FRAME)
    assert fence is not None
    assert fence.symmetric_difference(site).area < 1.0


def test_a_plan_is_a_fixed_path_and_geofence(
    exported_plan: tuple[Path, Path], tmp_path: Path
) -> None:
    _, path = exported_plan
    scenario = tmp_path / "plan.toml"
    scenario.write_text(
        f"""
name = "from-plan"
[mission]
duration_s = 300
[[sensors]]
name = "LW1"
lat = 35.727451
lon = -78.695974
buffer_mbit = 500
[trajectory]
mode = "fixed"
waypoints = "{path}"
speed_mps = 10.0
"""
    )
    mission = build_mission(load_scenario(str(scenario)))
    assert mission.fence is not None  # from the plan, no site.geofence given
    assert mission.track is not None
    waypoints = read_qgc_plan(path).waypoints_m(mission.frame)
    np.testing.assert_allclose(mission.track.position_m[0], waypoints[0], atol=1e-6)
    done = run_cli("run", str(scenario), cwd=tmp_path)
    assert done.returncode == 0, done.stderr


def _plan(**mission: object) -> dict:
    return {"fileType": "Plan", "mission": {"items": [], **mission}, "geoFence": {"polygons": []}}


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (None, "no such .plan file"),
        ("{not json", "invalid JSON"),
        (json.dumps({"fileType": "Plan"}), "no mission.items list"),
        (
            json.dumps(
                _plan(items=[{"type": "SimpleItem", "command": 16, "params": [0, 0, 0, 0, "x"]}])
            ),
            r"mission.items\[0\].params: expected 7 values",
        ),
        (
            json.dumps(
                _plan(
                    items=[{"type": "SimpleItem", "command": 16, "params": [0, 0, 0, 0, 95, 1, 30]}]
                )
            ),
            "is not a latitude/longitude",
        ),
    ],
)
def test_bad_plan_is_one_clear_line(tmp_path: Path, content: str | None, problem: str) -> None:
    path = tmp_path / "aadm.plan"
    if content is not None:
        path.write_text(content)
    with pytest.raises(SkymuleError, match=problem):
        read_qgc_plan(path)


def test_cli_with_a_missing_plan_is_exit_2(tmp_path: Path) -> None:
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        'name = "x"\n[mission]\nduration_s = 10\n[[sensors]]\nname = "A"\nx_m = 0\ny_m = 0\n'
        'buffer_mbit = 1\n[trajectory]\nwaypoints = "missing.plan"\n'
    )
    done = run_cli("run", str(scenario), cwd=tmp_path)
    assert done.returncode == 2
    assert "missing.plan: no such .plan file" in done.stderr
    assert "Traceback" not in done.stderr
