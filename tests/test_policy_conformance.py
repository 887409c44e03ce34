"""Every registered policy obeys the slot contract on the presets it supports.

Policies that do not support a trajectory mode must say so with a one-line SkymuleError;
every policy must support at least one mode. Also: same seed, same mission (determinism),
and user policies given as ``module:Class`` import paths.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from conftest import preset_mission, run_cli
from skymule.errors import SkymuleError
from skymule.metrics.flights import NO_SENSOR, MissionLog
from skymule.policies import POLICIES, make_policy, unknown_policies
from skymule.policies.base import Action
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.tasks.simulate import simulate
from skymule.world import Mission, build_mission

PLUGINS = Path(__file__).parent / "plugins"
PRESETS = ("paper-sim-fixed", "paper-sim-autonomous")


def assert_slot_contract(mission: Mission, log: MissionLog) -> None:
    assert log.n_slots == mission.n_slots
    assert (log.remaining_bit >= 0).all()
    before = np.vstack([log.buffers_bit[None], log.remaining_bit[:-1]])
    decrement = before - log.remaining_bit
    np.testing.assert_allclose(decrement.sum(axis=1), log.downloaded_bit, atol=1e-6)
    changed = decrement > 0
    assert (changed.sum(axis=1) <= 1).all()  # at most one sensor per slot
    assert not changed[log.served == NO_SENSOR].any()
    served = log.served != NO_SENSOR
    rows = np.flatnonzero(served)
    expected = np.minimum(
        log.rate_bps[rows, log.served[rows]] * log.slot_s, before[rows, log.served[rows]]
    )
    np.testing.assert_allclose(log.downloaded_bit[rows], expected)  # y = min(R dt, Q)
    if mission.scenario.trajectory.mode == "autonomous":
        spec = mission.scenario.trajectory
        path = np.vstack([log.position_m, log.end_position_m[None]])
        assert mission.fence is not None
        inside = shapely.covers(mission.fence.buffer(1e-5), shapely.points(path[:, :2]))
        assert inside.all()
        steps = np.hypot(*np.diff(path[:, :2], axis=0).T)
        assert steps.max() <= spec.max_speed_mps * mission.slot_s + 1e-6
        assert np.hypot(*(log.end_position_m[:2] - log.home_m)) < 1e-6


@pytest.fixture(scope="module")
def missions() -> dict[str, Mission]:
    return {name: preset_mission(name) for name in PRESETS}


@pytest.mark.parametrize("policy_name", sorted(POLICIES))
def test_registered_policy_obeys_the_contract(
    policy_name: str, missions: dict[str, Mission]
) -> None:
    supported = 0
    for mission in missions.values():
        spec = mission.scenario.policy.model_copy(update={"name": policy_name})
        try:
            log = run_mission(mission, make_policy(spec))
        except SkymuleError as exc:
            assert "\n" not in str(exc)  # a mode it does not support: one clear line
            continue
        supported += 1
        assert_slot_contract(mission, log)
        assert log.policy == policy_name
        assert log.downloaded_bit.sum() > 0
    assert supported >= 1, f"{policy_name} supports neither fixed nor autonomous missions"


@pytest.mark.parametrize("preset", ["paper-sim-fixed", "paper-sim-autonomous"])
def test_same_seed_same_mission_with_shadowing_and_fading(preset: str) -> None:
    base = load_scenario(preset)
    noisy = base.model_copy(
        update={
            "radio": base.radio.model_copy(
                update={
                    "shadowing_std_db": 6.0,
                    "shadowing_decorrelation_m": 50.0,
                    "fading": "rician",
                    "rician_k_db": 6.0,
                }
            )
        }
    )
    first = simulate(noisy, "hgad").log
    second = simulate(noisy, "hgad").log
    np.testing.assert_array_equal(first.snr_db, second.snr_db)
    np.testing.assert_array_equal(first.served, second.served)
    other_seed = simulate(noisy.model_copy(update={"seed": noisy.seed + 1}), "hgad").log
    assert not np.array_equal(first.snr_db, other_seed.snr_db)


def test_user_policy_by_import_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))
    result = simulate(load_scenario("paper-sim-fixed"), "my_policies:LargestBufferFirst")
    assert result.summary["policy"] == "largest-buffer-first"
    assert_slot_contract(result.mission, result.log)
    # names are checked without importing anything: a bad import shows when the policy runs
    assert unknown_policies(["my_policies:Nope", "no_such_module:X", "greedy"]) == []
    assert unknown_policies(["my_policies", "no such:X", "greedx"]) == [
        "my_policies",
        "no such:X",
        "greedx",
    ]
    with pytest.raises(SkymuleError, match="has no 'Nope'"):
        simulate(load_scenario("paper-sim-fixed"), "my_policies:Nope")
    with pytest.raises(SkymuleError, match="has no reset, act"):
        simulate(load_scenario("paper-sim-fixed"), "my_policies:NotAPolicy")


def test_cli_runs_and_compares_a_user_policy(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a real process: the policy module is found through PYTHONPATH, as a user sets it
    command = [sys.executable, "-c", "from skymule.cli import main; main()"]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(PLUGINS), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [
            *command,
            "compare",
            "paper-sim-fixed",
            "--policies",
            "hgad,my_policies:LargestBufferFirst",
            "--out",
            str(tmp_path / "cmp"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "cmp" / "my_policies:LargestBufferFirst" / "summary.json").exists()
    monkeypatch.syspath_prepend(str(PLUGINS))
    done = run_cli("run", "paper-sim-fixed", "--policy", "my_policies:Missing")
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "my_policies" in done.stderr


class _Vandal:
    """A policy that tries to write into every array it is handed, then serves sensor 0."""

    name = "vandal"

    def __init__(self) -> None:
        self.refused: set[str] = set()
        self.context_refused: set[str] = set()

    def reset(self, context) -> None:  # type: ignore[no-untyped-def]
        for field in ("buffers_bit", "peak_rate_bps", "sensor_m", "track_rate_bps"):
            values = getattr(context, field)
            if values is None:
                continue
            try:
                values[...] = 0
            except ValueError:
                self.context_refused.add(field)

    def act(self, observation):  # type: ignore[no-untyped-def]
        writes = {
            "rate_bps": lambda: observation.rate_bps.__setitem__(slice(None), 1e12),
            "snr_db": lambda: observation.snr_db.__setitem__(slice(None), 99.0),
            "position_m": lambda: observation.position_m.__setitem__(slice(None), 0.0),
            "remaining_bit": lambda: observation.remaining_bit.__setitem__(slice(None), 0.0),
        }
        for field, write in writes.items():
            try:
                write()
            except ValueError:  # numpy: "assignment destination is read-only"
                self.refused.add(field)
        return Action(serve=0)


@pytest.mark.parametrize("preset", PRESETS)
def test_policies_cannot_write_into_the_engine(preset: str, missions: dict[str, Mission]) -> None:
    """Every observation and context array is read-only, and a shared Mission is unharmed."""
    mission = missions[preset]
    before = run_mission(
        mission, make_policy(mission.scenario.policy.model_copy(update={"name": "greedy"}))
    )
    vandal = _Vandal()
    log = run_mission(mission, vandal)
    assert vandal.refused == {"rate_bps", "snr_db", "position_m", "remaining_bit"}
    assert vandal.context_refused >= {"buffers_bit", "peak_rate_bps", "sensor_m"}
    assert_slot_contract(mission, log)
    # slot 0 downloads what the true rate allows, not 1e12 bit/s
    assert log.downloaded_bit[0] <= mission.buffers_bit[0]
    assert log.downloaded_bit[0] == pytest.approx(log.rate_bps[0, 0] * mission.slot_s)
    after = run_mission(
        mission, make_policy(mission.scenario.policy.model_copy(update={"name": "greedy"}))
    )
    for field in ("position_m", "served", "downloaded_bit", "remaining_bit", "snr_db"):
        np.testing.assert_array_equal(getattr(after, field), getattr(before, field))
    with pytest.raises(ValueError):
        mission.buffers_bit[0] = 0.0
    if mission.track is not None:
        with pytest.raises(ValueError):
            mission.track.position_m[0] = 0.0


def _out_of_reach(preset: str) -> Mission:
    """The preset with every sensor ~100 km away: every rate is 0 everywhere it can fly."""
    scenario = load_scenario(preset)
    far = [
        sensor.model_copy(
            update={"lat": None, "lon": None, "x_m": 100_000.0 + 50 * i, "y_m": 100_000.0}
        )
        for i, sensor in enumerate(scenario.sensors)
    ]
    return build_mission(scenario.model_copy(update={"sensors": far}))


@pytest.mark.parametrize("policy_name", sorted(POLICIES))
@pytest.mark.parametrize("preset", PRESETS)
def test_every_policy_serves_nothing_and_ends_when_no_rate_is_usable(
    policy_name: str, preset: str
) -> None:
    mission = _out_of_reach(preset)
    spec = mission.scenario.policy.model_copy(update={"name": policy_name})
    try:
        log = run_mission(mission, make_policy(spec))
    except SkymuleError as exc:  # a mode the policy does not support: one line
        assert "\n" not in str(exc)
        return
    assert not log.rate_bps.any()
    assert (log.served == NO_SENSOR).all()
    assert not log.downloaded_bit.any()
    assert_slot_contract(mission, log)


def test_docs_list_every_field_a_policy_is_given_and_returns() -> None:
    """docs/policies.md has a row for each field of MissionContext, Observation and Action,
    and no row for a field that does not exist."""
    import dataclasses
    import re

    from skymule.policies.base import Action, MissionContext, Observation

    text = (Path(__file__).resolve().parents[1] / "docs" / "policies.md").read_text()
    sections = re.split(r"^## ", text, flags=re.M)
    for cls in (MissionContext, Observation, Action):
        (section,) = [s for s in sections if s.startswith(cls.__name__)]
        rows = re.findall(r"^\| `(\w+)` \|", section, flags=re.M)
        assert rows == [f.name for f in dataclasses.fields(cls)], cls.__name__
