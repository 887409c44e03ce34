"""A plug-in's parameter is tuned next to a built-in (issue 25, item 1).

``[policy.params]`` and ``--set policy.params.KEY`` go to the compared policies that declare
the key; a key none of them declares is one line with a "did you mean"; a swept parameter is
its own column in ``summary.csv`` and has its own figure in the sweep report.
"""

from __future__ import annotations

import json
import sys
import uuid
from pathlib import Path

import pandas as pd
import pytest

from conftest import run_cli

SOURCE = '''
import numpy as np
from pydantic import BaseModel, ConfigDict

from skymule.policies.base import Action


class Soonest:
    """Serves the fastest sensor, but only at min_rate_mbps or more."""

    name = "soonest"

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        min_rate_mbps: float = 0.0

    def __init__(self, params):
        self.floor_bps = params.min_rate_mbps * 1e6

    def reset(self, context):
        pass

    def act(self, observation):
        usable = (observation.remaining_bit > 0) & (observation.rate_bps >= self.floor_bps)
        usable &= observation.rate_bps > 0
        if not usable.any():
            return Action(serve=None)
        return Action(serve=int(np.argmax(np.where(usable, observation.rate_bps, -1.0))))
'''


@pytest.fixture
def soonest(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """The plug-in's policy name (a module of its own in ``tmp_path``, on sys.path)."""
    module = f"soonest_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{module}.py").write_text(SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield f"{module}:Soonest"
    sys.modules.pop(module, None)


def _six(folder: Path, policy: str = "hgad", params: str = "") -> Path:
    path = folder / "six.toml"
    path.write_text(
        'name = "six"\n[mission]\nduration_s = 120\n'
        + "".join(
            f'[[sensors]]\nname = "S{i}"\nx_m = {150.0 * i}\ny_m = 400.0\nbuffer_mbit = 300\n'
            for i in range(6)
        )
        + "[trajectory]\nwaypoints = [[0, 0, 30], [800, 0, 30]]\n"
        + f'[policy]\nname = "{policy}"\n{params}'
    )
    return path


def _params(run_dir: Path) -> dict[str, object]:
    return json.loads((run_dir / "scenario.json").read_text())["policy"]["params"]


def test_compare_gives_the_parameter_to_the_policy_that_has_it(
    tmp_path: Path, soonest: str
) -> None:
    six = _six(tmp_path)
    names = f"hgad,{soonest}"
    done = run_cli("compare", six, "--policies", names, "--out", tmp_path / "tuned",
                   "--set", "policy.params.min_rate_mbps=6")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert _params(tmp_path / "tuned" / soonest) == {"min_rate_mbps": 6}
    assert "min_rate_mbps" not in _params(tmp_path / "tuned" / "hgad")
    plain = run_cli("compare", six, "--policies", names, "--out", tmp_path / "plain")
    assert plain.returncode == 0, plain.stderr
    tuned = pd.read_csv(tmp_path / "tuned" / "comparison.csv").set_index("policy")
    untuned = pd.read_csv(tmp_path / "plain" / "comparison.csv").set_index("policy")
    assert (
        tuned.loc["hgad", "total_downloaded_mbit"] == untuned.loc["hgad", "total_downloaded_mbit"]
    )
    # 6 Mbit/s is a real floor: the plug-in downloads less than without it
    assert tuned.loc["soonest", "total_downloaded_mbit"] < untuned.loc["soonest", "total_downloaded_mbit"]  # fmt: skip  # noqa: E501


def test_a_key_no_compared_policy_knows_is_one_line_with_a_suggestion(
    tmp_path: Path, soonest: str
) -> None:
    six = _six(tmp_path)
    done = run_cli("compare", six, "--policies", f"hgad,{soonest}",
                   "--set", "policy.params.min_rate_mpbs=2")  # fmt: skip
    assert done.returncode == 2
    [line] = done.stderr.strip().splitlines()
    assert "policy.params.min_rate_mpbs: unknown parameter of policies 'hgad'" in line
    assert line.endswith("did you mean 'min_rate_mbps'?")
    # without the plug-in, no compared policy has it
    alone = run_cli("run", six, "--policy", "hgad", "--set", "policy.params.min_rate_mbps=2")
    assert alone.returncode == 2 and "min_rate_mbps: unknown parameter" in alone.stderr


def test_a_file_holding_a_plugin_parameter_runs_under_a_builtin(
    tmp_path: Path, soonest: str
) -> None:
    six = _six(tmp_path, soonest, "[policy.params]\nmin_rate_mbps = 1.5\n")
    done = run_cli("run", six, "--policy", "hgad", "--out", tmp_path / "run")
    assert done.returncode == 0, done.stderr
    assert _params(tmp_path / "run") == {}
    assert soonest.partition(":")[0] not in sys.modules  # not run, not imported


def test_a_swept_plugin_parameter_is_a_column_and_a_figure(tmp_path: Path, soonest: str) -> None:
    _six(tmp_path, soonest, "[policy.params]\nmin_rate_mbps = 1.0\n")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        f'base = "six.toml"\n[axes]\npolicy.name = ["hgad", "{soonest}"]\n'
        '"policy.params.min_rate_mbps" = [0.0, 6.0]\nseed = [0, 1]\n'
    )
    out = tmp_path / "sw"
    done = run_cli("sweep", sweep, "--out", out, "--executor", "inprocess", "--quiet")
    assert done.returncode == 0, done.stderr
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary.columns[:3]) == ["policy", "policy.params.min_rate_mbps", "missions"]
    assert summary["missions"].tolist() == [2, 2, 2, 2]
    by = summary.set_index(["policy", "policy.params.min_rate_mbps"])["total_downloaded_mbit_mean"]
    assert by[("soonest", 6.0)] < by[("soonest", 0.0)]  # the value reached the plug-in
    assert by[("hgad", 6.0)] == by[("hgad", 0.0)]  # and not hgad
    assert run_cli("report", out, "--no-pdf").returncode == 0
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "No swept numeric parameter" not in page
    assert "vs min rate mbps" in page
    assert "sweep-parameter-1" in page
