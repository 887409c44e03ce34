"""A ``module:Class`` a file names is imported only when that policy runs (issue 24).

Each test writes a module with a unique name that leaves a marker file when imported, names
it in a scenario, and checks which commands import it: none that do not run it (an override,
``bound``, ``compare`` of other policies, loading or checking the file, a sweep of other
policies), and the one that runs it says so on stderr in one line.
"""

from __future__ import annotations

import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from conftest import run_cli, tiny_scenario
from skymule.errors import SkymuleError
from skymule.experiments.sweep import load_sweep
from skymule.scenario import load_scenario

POLICY_SOURCE = '''
from pathlib import Path

from pydantic import BaseModel, ConfigDict

from skymule.policies.base import Action

Path(__file__).with_suffix(".imported").touch()


class Quiet:
    """Serves nothing; one parameter."""

    name = "quiet"

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        patience: int = 1

    def __init__(self, params):
        self.params = params

    def reset(self, context):
        pass

    def act(self, observation):
        return Action(serve=None)
'''


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[str, Path]:
    """(module name, marker file) of a fresh plug-in module in ``tmp_path``, on sys.path."""
    module = f"sharedmod_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{module}.py").write_text(POLICY_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield module, tmp_path / f"{module}.imported"
    sys.modules.pop(module, None)


def test_commands_that_do_not_run_the_plugin_never_import_it(
    tmp_path: Path, plugin: tuple[str, Path]
) -> None:
    module, marker = plugin
    scenario = tiny_scenario(tmp_path, f"{module}:Quiet", "[policy.params]\npatience = 3\n")
    sweep = tmp_path / "sweep.toml"  # the base holds the plug-in's parameter: kept, unused
    sweep.write_text('base = "shared.toml"\n[axes]\npolicy.name = ["greedy", "hgad"]\n')
    load_scenario(scenario)
    load_sweep(sweep)
    for args in (
        ("run", scenario, "--policy", "greedy"),
        ("bound", scenario),
        ("compare", scenario, "--policies", "greedy,hgad"),
        ("sweep", sweep, "--out", tmp_path / "sw", "--executor", "inprocess", "--quiet"),
    ):
        result = run_cli(*args)
        assert result.returncode == 0, (args, result.stderr)
        assert module not in result.stderr
    assert not marker.exists() and module not in sys.modules


def test_the_run_that_uses_it_says_which_module_it_imports(
    tmp_path: Path, plugin: tuple[str, Path]
) -> None:
    module, marker = plugin
    scenario = tiny_scenario(tmp_path, f"{module}:Quiet")
    result = run_cli("run", scenario)
    assert result.returncode == 0, result.stderr
    notice = [line for line in result.stderr.splitlines() if module in line]
    assert notice == [f"skymule: importing module {module} for policy '{module}:Quiet' "
                      f"(named in {scenario})"]  # fmt: skip
    assert marker.exists()
    # named on the command line: what runs is what the user typed, no notice
    typed = run_cli("run", "paper-sim-fixed", "--policy", f"{module}:Quiet")
    assert typed.returncode == 0 and module not in typed.stderr


def test_a_sweep_of_the_plugin_announces_it_once(tmp_path: Path, plugin: tuple[str, Path]) -> None:
    module, marker = plugin
    tiny_scenario(tmp_path, "greedy")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        f'base = "shared.toml"\n[axes]\npolicy.name = ["greedy", "{module}:Quiet"]\nseed = [0, 1]\n'
    )
    result = run_cli("sweep", sweep, "--out", tmp_path / "sw", "--executor", "inprocess")
    assert result.returncode == 0, result.stderr
    assert result.stderr.count(f"importing module {module}") == 1
    assert marker.exists()


def test_plugin_parameters_are_checked_when_it_is_made(
    tmp_path: Path, plugin: tuple[str, Path]
) -> None:
    module, marker = plugin
    scenario = tiny_scenario(tmp_path, f"{module}:Quiet", "[policy.params]\npatiense = 3\n")
    load_scenario(scenario)  # checking the file imports nothing, so cannot know the key
    assert not marker.exists()
    result = run_cli("run", scenario)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1] == (
        f"skymule: error: policy.params.patiense: unknown parameter of policy "
        f"'{module}:Quiet'; its parameters: patience; did you mean 'patience'?"
    )


def test_a_malformed_import_path_is_refused_without_importing() -> None:
    for name in ("os.path:", "a b:C", "x:y:z", ":Class"):
        with pytest.raises(SkymuleError, match=r"an import path is 'package\.module:Class'"):
            load_scenario("paper-sim-fixed", [f'policy.name="{name}"'])


def test_this_s_prints_no_zen_unless_it_runs(tmp_path: Path) -> None:
    """The audit's case, in a fresh interpreter: ``this`` prints the Zen of Python on import."""
    scenario = tiny_scenario(tmp_path, "this:s")
    code = "from skymule.cli import main; main()"
    done = subprocess.run(
        [sys.executable, "-c", code, "run", str(scenario), "--policy", "greedy"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "Beautiful is better than ugly" not in done.stdout + done.stderr
