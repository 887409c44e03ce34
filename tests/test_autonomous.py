"""Autonomous missions: Table II orders, engine invariants, return home, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Point

from conftest import preset_mission, run_cli
from skymule.metrics.flights import NO_SENSOR
from skymule.metrics.summary import summarize
from skymule.policies import HGAD, make_policy
from skymule.policies.base import Action, MissionContext, Observation
from skymule.scenario import PolicySpec, load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"

# paper Table II: buffers (LW1..LW4) [Mbit] -> HGAD navigation order
TABLE_II = [
    ((700, 500, 800, 1000), ["LW4", "LW3", "LW1", "LW2"]),
    ((500, 800, 1000, 700), ["LW3", "LW2", "LW4", "LW1"]),
    ((800, 500, 700, 1000), ["LW4", "LW1", "LW3", "LW2"]),
    ((500, 1000, 700, 800), ["LW2", "LW4", "LW3", "LW1"]),
]


def _with(scenario, buffers=None, **trajectory):
    update = {}
    if buffers is not None:
        update["sensors"] = [
            s.model_copy(update={"buffer_mbit": float(b)})
            for s, b in zip(scenario.sensors, buffers, strict=True)
        ]
    if trajectory:
        update["trajectory"] = scenario.trajectory.model_copy(update=trajectory)
    return scenario.model_copy(update=update)


@pytest.mark.parametrize(("buffers", "order"), TABLE_II)
def test_hgad_reproduces_table_ii_navigation_order(buffers, order):
    mission = build_mission(_with(load_scenario(PRESET), buffers))
    summary = summarize(run_mission(mission, HGAD()), "t")
    assert summary["visit_order"] == order
    assert summary["landed_within_5m"]


def test_ranking_by_remaining_data_breaks_table_ii():
    """The literal "next-largest remaining buffer" lets en-route downloads reorder the tour."""
    buffers, order = TABLE_II[2]
    mission = build_mission(_with(load_scenario(PRESET), buffers))
    summary = summarize(run_mission(mission, HGAD(priority="remaining")), "t")
    assert summary["visit_order"] != order


def _assert_invariants(mission, log):
    spec = mission.scenario.trajectory
    path = np.vstack([log.position_m, log.end_position_m[None]])
    inside = shapely.covers(mission.fence.buffer(1e-5), shapely.points(path[:, 0], path[:, 1]))
    assert inside.all()
    steps = np.hypot(*np.diff(path[:, :2], axis=0).T)
    assert steps.max() <= spec.max_speed_mps * mission.slot_s + 1e-6
    assert np.hypot(*(log.end_position_m[:2] - log.home_m)) < 1e-6
    assert (log.remaining_bit >= 0).all()
    before = np.vstack([log.buffers_bit[None], log.remaining_bit[:-1]])
    decrement = before - log.remaining_bit
    assert np.allclose(decrement.sum(axis=1), log.downloaded_bit)
    # at most one sensor's buffer changes per slot, and it is the served one
    changed = decrement > 0
    assert (changed.sum(axis=1) <= 1).all()
    served_changed = changed[np.arange(log.n_slots), np.maximum(log.served, 0)]
    assert np.array_equal(changed.any(axis=1), served_changed & (log.served != NO_SENSOR))


def test_invariants_on_random_autonomous_missions():
    rng = np.random.default_rng(7)
    base = load_scenario(PRESET)
    fence = build_mission(base).fence
    minx, miny, maxx, maxy = fence.bounds
    for _ in range(8):
        while True:
            home = rng.uniform([minx, miny], [maxx, maxy])
            if fence.buffer(-2.0).covers(Point(home)):
                break
        sensors = [
            s.model_copy(
                update={
                    "lat": None,
                    "lon": None,
                    "x_m": float(rng.uniform(minx - 300, maxx + 300)),
                    "y_m": float(rng.uniform(miny - 300, maxy + 300)),
                    "buffer_mbit": float(rng.uniform(0, 600)),
                }
            )
            for s in base.sensors
        ]
        scenario = base.model_copy(
            update={
                "sensors": sensors,
                "mission": base.mission.model_copy(
                    update={"duration_s": float(rng.integers(150, 260))}
                ),
                "trajectory": base.trajectory.model_copy(
                    update={
                        "home": [float(home[0]), float(home[1])],
                        "max_speed_mps": float(rng.uniform(4, 15)),
                    }
                ),
                "policy": PolicySpec(
                    name=base.policy.name, params={"max_hover_s": float(rng.uniform(5, 60))}
                ),
            }
        )
        mission = build_mission(scenario)
        for name in ("greedy", "hgad"):
            log = run_mission(
                mission, make_policy(scenario.policy.model_copy(update={"name": name}))
            )
            _assert_invariants(mission, log)


class _Runaway:
    """Always flies to the far south-east corner; never serves."""

    name = "runaway"

    def reset(self, context: MissionContext) -> None:
        self._goal = (1e5, -1e5)  # far outside the fence: the engine must clamp it

    def act(self, observation: Observation) -> Action:
        return Action(serve=None, goto_m=self._goal)


def test_engine_brings_a_runaway_policy_home_in_time():
    mission = preset_mission(PRESET)
    log = run_mission(mission, _Runaway())
    _assert_invariants(mission, log)
    # it did get far away before turning back
    assert np.hypot(*log.position_m[:, :2].T).max() > 300


def test_greedy_never_hovers_while_touring_and_hgad_hovers():
    scenario = load_scenario(PRESET)
    mission = build_mission(scenario)
    greedy = run_mission(
        mission, make_policy(scenario.policy.model_copy(update={"name": "greedy"}))
    )
    hgad = run_mission(mission, make_policy(scenario.policy))
    has_data = greedy.remaining_bit.sum(axis=1) > 0
    tour = greedy.target != NO_SENSOR
    assert not (greedy.hovering & has_data & tour).any()
    assert (hgad.hovering & (hgad.served != NO_SENSOR)).sum() > 0
    # nearest-first from the launch point: LW1 stands next to it, then LW4's hover point
    assert summarize(greedy, "t")["visit_order"][0] == "LW4"


def test_summary_and_slots_have_energy_and_aadm_fields(tmp_path):
    out = tmp_path / "run"
    run_cli("run", PRESET, "--out", out, check=True)
    import json

    import pandas as pd

    summary = json.loads((out / "summary.json").read_text())
    slots = pd.read_csv(out / "slots.csv")
    assert summary["landed_within_5m"] is True
    assert summary["distance_to_home_m"] == pytest.approx(0.0, abs=1e-6)
    assert summary["energy_kj"] == pytest.approx(slots["power_w"].sum() / 1e3, rel=1e-4)
    assert slots["power_w"].min() > 0 and slots["speed_mps"].max() <= 10.0 + 1e-6
    assert set(summary["visit_order"]) <= {"LW1", "LW2", "LW3", "LW4"}
    # all 3000 Mbit by time t1 (the AADM rule in force): S = (500 - t1) + 100
    t_done = float(slots.index[slots.filter(like="remaining_mbit").sum(axis=1) <= 0][0] + 1)
    assert summary["aadm_complete"] is True and summary["aadm_t1_s"] == t_done
    assert summary["aadm_score"] == pytest.approx(100.0 + 500.0 - t_done)
    run_cli("plot", out, check=True)
    assert (out / "trajectory.png").stat().st_size > 10_000


def _write_scenario(
    tmp_path: Path, trajectory: str = "", site: str = "", mission: str = ""
) -> Path:
    text = f"""
name = "bad"
[mission]
duration_s = {mission or 500}
[site]
{site or 'geofence = "lake-wheeler"'}
[[sensors]]
name = "A"
x_m = 100.0
y_m = 100.0
buffer_mbit = 10
[trajectory]
mode = "autonomous"
{trajectory}
"""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    return path


def _bowtie(tmp_path: Path) -> str:
    ring = [[-78.697, 35.727], [-78.695, 35.729], [-78.695, 35.727], [-78.697, 35.729]]
    ring.append(ring[0])
    feature = {"type": "Polygon", "coordinates": [ring]}
    import json

    (tmp_path / "bowtie.geojson").write_text(json.dumps(feature))
    return 'geofence = "bowtie.geojson"'


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("home_outside", "trajectory.home"),
        ("bowtie", "not a valid polygon"),
        ("zero_speed", "max_speed_mps"),
        ("too_short", "mission.duration_s"),
    ],
)
def test_bad_autonomous_input_exits_2_with_one_line(tmp_path, case, expected):
    if case == "home_outside":
        path = _write_scenario(tmp_path, trajectory="home = [5000.0, 0.0]")
    elif case == "bowtie":
        path = _write_scenario(tmp_path, site=_bowtie(tmp_path))
    elif case == "zero_speed":
        path = _write_scenario(tmp_path, trajectory="max_speed_mps = 0")
    else:
        path = _write_scenario(tmp_path, mission="10")
    proc = run_cli("run", path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], proc.stderr
