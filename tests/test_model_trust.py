"""A stable-baselines3 zip a file names is unpickled only with ``--trust-model`` (issue 24).

stable-baselines3 is not needed here: a stand-in ``stable_baselines3`` module whose
``PPO.load`` unpickles the zip's ``data`` entry, as the real one does, shows that a payload
would run on load, and that without the opt-in skymule never gets that far.
"""

from __future__ import annotations

import base64
import json
import os
import pickle
import sys
import types
import zipfile
from pathlib import Path
from typing import Any

import pytest

from conftest import run_cli, tiny_scenario
from skymule.errors import SkymuleError
from skymule.policies import make_policy
from skymule.scenario import PolicySpec
from skymule.trust import TRUST_ENV, is_trusted, trusting


class _Payload:
    """Unpickling this creates ``path``: the stand-in for code a shared model could run."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> tuple[Any, ...]:
        return (os.mkdir, (str(self.path),))


def evil_zip(folder: Path) -> tuple[Path, Path]:
    """A zip laid out like a stable-baselines3 save whose ``data`` carries a payload."""
    marker = folder / "payload-ran"
    blob = base64.b64encode(pickle.dumps(_Payload(marker))).decode()
    data = {"policy_class": {":type:": "<class 'abc.ABCMeta'>", ":serialized:": blob}}
    path = folder / "model.zip"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("data", json.dumps(data))
        archive.writestr("_stable_baselines3_version", "2.3.0")
    return path, marker


@pytest.fixture
def unpickling_sb3(monkeypatch: pytest.MonkeyPatch) -> None:
    """A ``stable_baselines3`` whose ``PPO.load`` unpickles ``data`` (as the real one does)."""

    class PPO:
        @staticmethod
        def load(path: str, device: str = "cpu") -> Any:
            with zipfile.ZipFile(path) as archive:
                data = json.loads(archive.read("data"))
            for value in data.values():
                pickle.loads(base64.b64decode(value[":serialized:"]))
            raise ValueError("not a PPO model")

    module = types.ModuleType("stable_baselines3")
    module.PPO = PPO  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "stable_baselines3", module)


def test_the_payload_never_runs_without_the_opt_in(tmp_path: Path, unpickling_sb3: None) -> None:
    model, marker = evil_zip(tmp_path)
    with pytest.raises(SkymuleError) as caught:
        make_policy(PolicySpec(name=f"rl:{model}"))
    message = str(caught.value)
    assert "\n" not in message
    assert "pickled Python objects" in message and f"--trust-model {model}" in message
    assert not marker.exists()
    # the stand-in really is dangerous: trusted, the payload runs (what the opt-in allows)
    with trusting([model]), pytest.raises(SkymuleError, match="not a stable-baselines3"):
        make_policy(PolicySpec(name=f"rl:{model}"))
    assert marker.exists()


def test_trust_is_for_one_file_and_one_block(tmp_path: Path) -> None:
    model, _ = evil_zip(tmp_path)
    other = tmp_path / "other.zip"
    saved = os.environ.get(TRUST_ENV)
    with trusting([tmp_path / "." / "model.zip"]):
        assert is_trusted(model) and not is_trusted(other)
    assert os.environ.get(TRUST_ENV) == saved and not is_trusted(model)


def test_refused_before_stable_baselines3_is_needed(tmp_path: Path) -> None:
    """Without the extra: the refusal, not "install stable-baselines3"; trusted, the install
    hint (the opt-in gets past the check)."""
    if "stable_baselines3" in sys.modules or _importable("stable_baselines3"):
        pytest.skip("checks the message when stable-baselines3 is not installed")
    model, marker = evil_zip(tmp_path)
    with pytest.raises(SkymuleError, match="not loaded: a stable-baselines3 zip"):
        make_policy(PolicySpec(name=f"rl:{model}"))
    with trusting([model]), pytest.raises(SkymuleError, match="needs stable-baselines3"):
        make_policy(PolicySpec(name=f"rl:{model}"))
    assert not marker.exists()


def _importable(name: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(name) is not None


def test_every_command_refuses_an_untrusted_model_in_one_line(
    tmp_path: Path, unpickling_sb3: None
) -> None:
    model, marker = evil_zip(tmp_path)
    scenario = tiny_scenario(tmp_path, f"rl:{model}")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        f'base = "{scenario.name}"\n[axes]\npolicy.name = ["greedy", "rl:{model}"]\nseed = [0]\n'
    )
    for args in (
        ("run", scenario),
        ("compare", scenario, "--policies", f"greedy,rl:{model}"),
        ("sweep", sweep, "--out", tmp_path / "sw", "--executor", "inprocess", "--quiet"),
        ("resilience", scenario, "--fault", "snr-error", "--levels", "0", "--out", tmp_path / "r",
         "--policies", f"rl:{model}", "--missions", "1"),
    ):  # fmt: skip
        result = run_cli(*args)
        assert result.returncode == 2, (args, result.stderr)
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr
        assert "--trust-model" in result.stderr
    assert not marker.exists()
    assert not (tmp_path / "sw" / "results").exists()  # refused before any mission ran


def test_an_override_never_touches_the_model_and_the_opt_in_reaches_the_loader(
    tmp_path: Path, unpickling_sb3: None
) -> None:
    model, marker = evil_zip(tmp_path)
    scenario = tiny_scenario(tmp_path, f"rl:{model}")
    assert run_cli("run", scenario, "--policy", "greedy").returncode == 0
    assert run_cli("bound", scenario).returncode == 0
    assert not marker.exists()
    trusted = run_cli("run", scenario, "--trust-model", model)
    assert trusted.returncode == 2 and "not a stable-baselines3 PPO model" in trusted.stderr
    assert marker.exists()  # the user asked for it
    assert TRUST_ENV not in os.environ or not is_trusted(model)  # for that command only
