"""Robust HGAD (hgad-robust) and the resilience study (issue 15), on small hand-checked cases."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from conftest import preset_mission, run_cli
from skymule.metrics.flights import MissionLog
from skymule.policies import make_policy
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import PolicySpec, Scenario, load_scenario, scenario_from_dict
from skymule.sim.run import run_mission
from skymule.tasks.resilience import LEVELS, leveled, run_study
from skymule.world import Mission, build_mission


def _with(preset: str, faults: list[dict[str, Any]] | None = None) -> Scenario:
    base = load_scenario(preset)
    data = base.to_toml_dict()
    if faults:
        data["faults"] = faults
    return scenario_from_dict(data, preset, Path(base.base_dir))


def _run(mission: Mission, name: str, **params: Any) -> MissionLog:
    return run_mission(mission, make_policy(PolicySpec(name=name, params=params)))


@pytest.mark.parametrize("preset", ["paper-sim-fixed", "paper-sim-autonomous"])
def test_robust_hgad_without_faults_and_smoothing_is_hgad(preset: str) -> None:
    mission = preset_mission(preset)
    plain = _run(mission, "hgad")
    robust = _run(mission, "hgad-robust", window_slots=1, arrive_m=0.0)
    assert np.array_equal(plain.served, robust.served)
    assert np.array_equal(plain.downloaded_bit, robust.downloaded_bit)
    # with its default smoothing it loses under 1 % on the fault-free preset
    smoothed = _run(mission, "hgad-robust")
    assert smoothed.downloaded_bit.sum() >= 0.99 * plain.downloaded_bit.sum()


def _first_hover(log: MissionLog) -> tuple[int, int]:
    """(slot, sensor) of the first slot of the first hover of at least 10 slots."""
    for t in range(log.n_slots - 10):
        if log.hovering[t : t + 10].all() and (log.served[t : t + 10] == log.served[t]).all():
            return t, int(log.served[t])
    raise AssertionError("no hover of 10 slots")


def _dead_run(log: MissionLog, sensor: int) -> int:
    """Longest run of slots in which the policy chose ``sensor`` and nothing was delivered."""
    assert log.chosen is not None
    dead = (log.chosen == sensor) & (log.served == NO_SENSOR)
    longest = run = 0
    for flag in dead:
        run = run + 1 if flag else 0
        longest = max(longest, run)
    return longest


def test_robust_hgad_leaves_a_tower_that_goes_silent_mid_hover() -> None:
    clean = preset_mission("paper-sim-fixed")
    start, sensor = _first_hover(_run(clean, "hgad"))
    name = clean.sensor_names[sensor]
    outage = {
        "kind": "outage",
        "params": {"sensors": [name], "start_s": start + 2, "duration_s": 120},
    }
    mission = build_mission(_with("paper-sim-fixed", [outage]))
    plain, robust = _run(mission, "hgad"), _run(mission, "hgad-robust", fail_slots=3)
    assert _dead_run(plain, sensor) > 3  # plain HGAD keeps hovering on the dead tower
    assert _dead_run(robust, sensor) <= 3  # robust gives up after 3 silent slots
    assert robust.downloaded_bit.sum() > plain.downloaded_bit.sum()


def test_robust_tour_leaves_a_silent_tower_on_an_autonomous_mission() -> None:
    names = load_scenario("paper-sim-autonomous").sensors
    outage = {
        "kind": "outage",
        "params": {"sensors": [names[0].name], "start_s": 0, "duration_s": 1e4},
    }
    mission = build_mission(_with("paper-sim-autonomous", [outage]))
    plain, robust = _run(mission, "hgad"), _run(mission, "hgad-robust", fail_slots=2)
    assert _dead_run(robust, 0) <= 2 < _dead_run(plain, 0)
    assert robust.downloaded_bit.sum() >= plain.downloaded_bit.sum()


def test_robust_tour_hovers_despite_gps_error() -> None:
    gps = {"kind": "gps-error", "params": {"std_m": 5.0}}
    mission = build_mission(_with("paper-sim-autonomous", [gps]))
    plain, robust = _run(mission, "hgad"), _run(mission, "hgad-robust", arrive_m=10.0)
    # the reported position never equals a hover point: plain HGAD's tour never starts a
    # hover (it keeps asking to fly there, serving en route); the robust one does
    assert robust.downloaded_bit.sum() > 1.02 * plain.downloaded_bit.sum()


def test_robust_hgad_parameters_are_validated() -> None:
    from skymule.errors import ScenarioError

    base = load_scenario("paper-sim-fixed")
    data = base.to_toml_dict()
    data["policy"] = {"name": "hgad-robust", "params": {"fail_slots": 0}}
    with pytest.raises(ScenarioError, match="fail_slots"):
        scenario_from_dict(data, "x", Path(base.base_dir))
    data["policy"] = {"name": "hgad-robust", "params": {"fail_slots": 2, "window_slots": 4}}
    policy = make_policy(scenario_from_dict(data, "x", Path(base.base_dir)).policy)
    assert (policy.fail_slots, policy.window_slots) == (2, 4)  # type: ignore[attr-defined]


def test_resilience_command_writes_the_table_and_figure(tmp_path: Path) -> None:
    out = tmp_path / "res"
    result = run_cli(
        "resilience", "paper-sim-fixed", "--fault", "outage", "--levels", "0,120",
        "--policies", "hgad,hgad-robust", "--missions", "2", "--out", out,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    frame = pd.read_csv(out / "resilience.csv")
    assert list(frame["policy"]) == ["hgad", "hgad", "hgad-robust", "hgad-robust"]
    assert list(frame["level"]) == [0.0, 120.0, 0.0, 120.0]
    assert (frame["missions"] == 2).all()
    # the fault-free bound holds at every level and every mean is below it
    assert (frame["mbit_mean"] <= frame["bound_mbit_mean"] + 1e-6).all()
    assert (out / "resilience.png").stat().st_size > 0
    # level 0 is the fault-free mission: what `skymule run` gives on mission 0 ...
    clean = frame[(frame["policy"] == "hgad") & (frame["level"] == 0)]
    study = run_study(load_scenario("paper-sim-fixed"), "outage", [0.0], ["hgad"], 2, False)
    assert float(clean["mbit_mean"].iloc[0]) == pytest.approx(study.rows["mbit"].mean(), abs=1e-3)
    # ... and paired: mission 0 at level 0 is mission 0 of the study with no fault at all
    first = leveled(load_scenario("paper-sim-fixed"), "outage", 0.0, 0)
    assert first.faults is None
    alone = run_mission(build_mission(first), make_policy(first.policy)).downloaded_bit.sum()
    assert study.rows["mbit"].iloc[0] == pytest.approx(alone / 1e6, rel=1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--fault", "meteor", "--levels", "0"), "--fault 'meteor' is not a fault kind"),
        (("--fault", "outage", "--levels", "0,abc"), "'abc' is not a number"),
        (("--fault", "missed-polls", "--levels", "0,1"), "allowed: in [0, 1)"),
        (("--fault", "outage", "--levels", "-5"), "allowed: >= 0"),
        (("--fault", "wind", "--levels", "12"), "speed_mps"),
        (("--fault", "outage", "--levels", "0", "--policies", "nope"), "--policies"),
    ],
)
def test_resilience_command_mistakes_are_one_line(
    tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    result = run_cli("resilience", "paper-sim-fixed", *args, "--out", tmp_path / "r")
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


def test_levels_help_gives_each_fault_its_unit() -> None:
    """``--levels`` means seconds for an outage and dB for an SNR error: the help names the
    unit of every fault kind as the study labels its axis (LEVELS)."""
    shown = " ".join(run_cli("resilience", "--help", check=True).stdout.split())
    for kind, (meaning, _) in LEVELS.items():
        unit = re.search(r"\[(.+?)\]", meaning)
        expected = rf"{kind} [^,]*\[{re.escape(unit.group(1))}\]" if unit else kind
        assert re.search(expected, shown), (kind, meaning, shown)
    assert "(dB)" not in shown
