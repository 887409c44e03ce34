"""One registry type, per-component parameters, and the README's own-policy example."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from conftest import run_cli
from skymule.bounds.autonomous import monotone_models
from skymule.errors import SkymuleError
from skymule.experiments.executors import EXECUTORS, open_executor
from skymule.io.exports import EXPORTERS
from skymule.io.traces import TRACE_FORMATS
from skymule.policies import POLICIES, HGADParams, make_policy
from skymule.radio.pathloss import PATHLOSS_MODELS, LogDistance
from skymule.radio.rates import BUILTIN_RATE_TABLES, resolve_rate_table
from skymule.radio.sources import build_pathloss
from skymule.registry import Registry
from skymule.scenario import PolicySpec, RadioSpec, load_scenario, presets
from skymule.tasks.simulate import simulate

ROOT = Path(__file__).parents[1]


def test_registry_lookup_names_and_one_line_error() -> None:
    registry: Registry[int] = Registry("colour")
    registry.register("red", 1, warm=True)
    registry.register("blue", 2, warm=False)
    assert registry["red"] == 1 and registry.names() == ["red", "blue"]
    assert registry.meta("red", "warm") is True and registry.where(lambda e: e.meta["warm"])
    with pytest.raises(SkymuleError) as error:
        registry.get("rde")
    assert str(error.value) == "unknown colour 'rde'; allowed: red, blue; did you mean 'red'?"
    with pytest.raises(ValueError, match="already registered"):
        registry.register("red", 3)


@pytest.mark.parametrize(
    ("lookup", "needle"),
    [
        (lambda: POLICIES.get("gredy"), "unknown policy 'gredy'; allowed: greedy, hgad"),
        (lambda: PATHLOSS_MODELS.get("fpsl"), "did you mean 'fspl'?"),
        (lambda: resolve_rate_table("shanon"), "unknown radio.rate_table 'shanon'"),
        (lambda: open_executor("proces"), "unknown --executor 'proces'"),
        (lambda: EXPORTERS.get("kmz"), "unknown export 'kmz'; allowed: kml, geojson, plan"),
        (lambda: TRACE_FORMATS.get("csv"), "allowed: aadm, dt"),
        (lambda: presets().get("paper-sim"), "unknown scenario 'paper-sim'"),
    ],
)
def test_every_registry_gives_the_same_one_line_error(lookup: object, needle: str) -> None:
    with pytest.raises(SkymuleError) as error:
        lookup()  # type: ignore[operator]
    assert needle in str(error.value) and "\n" not in str(error.value)


def test_registries_hold_the_components() -> None:
    assert {"greedy", "hgad", "planner", "optimal-fixed"} <= set(POLICIES)
    assert {"aadm-lte-cqi", "shannon"} <= set(BUILTIN_RATE_TABLES)
    assert {"inprocess", "process", "dask-local", "dask"} <= set(EXECUTORS)


def test_autonomous_bound_reads_the_monotone_flag() -> None:
    assert set(monotone_models()) == {
        "fspl", "free-space", "log-distance", "al-hourani", "3gpp-rma-av",
    }  # fmt: skip
    assert not PATHLOSS_MODELS.get("two-ray").monotone


def test_radio_params_table_and_flat_keys_are_the_same() -> None:
    flat = RadioSpec.model_validate({"model": "log-distance", "path_loss_exponent": 3.0})
    table = RadioSpec.model_validate({"model": "log-distance", "params": {"path_loss_exponent": 3}})
    assert flat == table and table.param("path_loss_exponent") == 3.0
    model = build_pathloss(table)
    assert isinstance(model, LogDistance) and model.exponent == 3.0
    # parameters of another model are kept (compare --sources) but do not reach this one
    other = RadioSpec.model_validate({"model": "fspl", "params": {"environment": "urban"}})
    assert other.model_params().model_dump() == {}


def test_bad_params_name_the_key_and_what_is_allowed(tmp_path: Path) -> None:
    text = presets().get("paper-sim-fixed")
    cases = [
        ("max_hover_s = 60.0", "max_hover_s = -1", "policy.params.max_hover_s = -1"),
        ('model = "fspl"', 'model = "two-ray"\nground_reflection = 3', "ground_reflection = 3"),
        ('model = "fspl"', 'model = "two-ray"\n[radio.params]\nground_refl = 1', "did you mean"),
        ('model = "fspl"', 'model = "fpsl"', "unknown radio.model 'fpsl'"),
    ]
    for old, new, needle in cases:
        path = tmp_path / "bad.toml"
        path.write_text(text.replace(old, new))
        done = run_cli("run", path)
        assert done.returncode == 2 and needle in done.stderr, (new, done.stderr)
        assert len(done.stderr.strip().splitlines()) == 1


def test_hgad_parameters_from_either_place_give_the_same_run() -> None:
    base = load_scenario("paper-sim-fixed")
    table = base.model_copy(
        update={"policy": PolicySpec(params={"hover_threshold": 0.8, "max_hover_s": 20})}
    )
    flat = base.model_copy(
        update={"policy": PolicySpec.model_validate({"hover_threshold": 0.8, "max_hover_s": 20})}
    )
    assert table.policy == flat.policy and table.policy.param("max_hover_s") == 20
    assert table.policy.max_hover_s == 20.0  # the batched engine's accessor
    policy = make_policy(table.policy)
    assert (policy.hover_threshold, policy.max_hover_s) == (0.8, 20)  # type: ignore[attr-defined]
    assert simulate(table).summary == simulate(flat).summary
    assert HGADParams().max_hover_s == 60.0
    # another policy of a comparison ignores HGAD's parameters
    assert simulate(table, "greedy").summary["policy"] == "greedy"


def _readme_block(start: str) -> str:
    readme = (ROOT / "README.md").read_text()
    for body in re.findall(r"```\w+\n(.*?)```", readme, re.S):
        if body.startswith(start):
            return str(body)
    raise AssertionError(f"README has no block starting {start!r}")


def test_readme_own_policy_example_runs_as_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "largest_buffer.py").write_text(_readme_block("# largest_buffer.py"))
    (tmp_path / "my-mission.toml").write_text(_readme_block("# my-mission.toml"))
    commands = _readme_block("skymule run my-mission.toml").splitlines()
    monkeypatch.chdir(tmp_path)  # the policy module is found in the current folder
    monkeypatch.delitem(sys.modules, "largest_buffer", raising=False)
    outputs = []
    for line in commands:
        args = line.split("#")[0].split()[1:]
        outputs.append(run_cli(*args, "--json", check=True).stdout)
    mine = json.loads(outputs[0])
    assert mine["policy"] == "largest-buffer-first"
    compared = {r["policy"] for r in json.loads(outputs[1])["runs"]}
    assert compared == {"greedy", "hgad", "largest-buffer-first"}
    # the parameters come from the file: a stricter SNR floor downloads less
    assert json.loads(outputs[2])["total_downloaded_mbit"] < mine["total_downloaded_mbit"]
    # on an autonomous mission it flies (to the largest buffer's hover point), not sits at home
    autonomous = ("run", "paper-sim-autonomous", "--policy", "largest_buffer:LargestBufferFirst")
    flown = json.loads(run_cli(*autonomous, "--json", check=True).stdout)
    assert flown["distance_m"] > 1000 and flown["total_downloaded_mbit"] > 2000
    typo = (tmp_path / "my-mission.toml").read_text().replace("min_snr_db =", "min_snr =")
    (tmp_path / "typo.toml").write_text(typo)
    done = run_cli("run", "typo.toml")
    assert done.returncode == 2 and "did you mean 'min_snr_db'?" in done.stderr


def test_a_policy_module_that_fails_to_import_says_why(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "broken_policy.py").write_text("raise RuntimeError('no licence server')\n")
    monkeypatch.chdir(tmp_path)
    done = run_cli("run", "paper-sim-fixed", "--policy", "broken_policy:Mine")
    assert done.returncode == 2
    assert "could not import module broken_policy: RuntimeError: no licence server" in done.stderr
    missing = run_cli("run", "paper-sim-fixed", "--policy", "no_such_module:Mine")
    assert "could not import module no_such_module: ModuleNotFoundError" in missing.stderr
