"""What ``compare`` and ``report`` write (issue 32): only inside ``--out``, an index file last
that readers require, no temporary folders left by killed processes, rows labelled as asked,
one column name everywhere, an invalid bound drawn as invalid, and a preset's key that
replaces a plug-in's default said in one line."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import matplotlib
import pandas as pd
import pytest

from conftest import run_cli
from skymule.io import atomic
from skymule.tasks import compare as compare_task
from skymule.tasks.compare import COMPARISON_CSV, compare_policies, policy_folder, write_compare

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
WEIGHTS = ROOT / "src" / "skymule" / "data" / "learned_policy.npz"
SHORT = ("--set", "mission.duration_s=60")


def _files(folder: Path) -> set[Path]:
    return {p.relative_to(folder) for p in folder.rglob("*")}


def test_a_policy_path_cannot_write_outside_out(tmp_path: Path) -> None:
    """``learned:../../../w.npz`` named the run folder ``cmp/../../../w.npz``: its files
    landed next to ``cmp``. The folder name is now one safe component inside ``--out``."""
    work = tmp_path / "a" / "b" / "c"
    work.mkdir(parents=True)
    shutil.copy(WEIGHTS, tmp_path / "w.npz")
    before = _files(tmp_path)
    done = run_cli(
        "compare", "paper-sim-autonomous", "--policies", "greedy,learned:../../../w.npz",
        "--out", "cmp", *SHORT, cwd=work,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    new = _files(tmp_path) - before
    assert new and all(p.parts[:4] == ("a", "b", "c", "cmp") for p in new), sorted(new)
    assert (work / "cmp" / "learned:.._.._.._w.npz" / "summary.json").is_file()
    assert (work / "cmp" / "greedy" / "summary.json").is_file()


@pytest.mark.parametrize(
    ("asked", "folder"),
    [
        ("learned:../../../w.npz", "learned:.._.._.._w.npz"),
        ("..", "policy"),
        ("rl:/abs/model.zip", "rl:_abs_model.zip"),
        ("mostbits:MostBits", "mostbits:MostBits"),
    ],
)
def test_policy_folders_are_one_safe_component(asked: str, folder: str) -> None:
    assert policy_folder(asked) == folder
    assert os.sep not in folder and folder not in (".", "..")


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_report_removes_the_staging_folders_of_killed_reports(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run_cli("run", "paper-sim-fixed", *SHORT, "--out", run, check=True)
    dead = run / f".report.{_dead_pid()}.0123456789ab.tmp"
    (dead / "figures").mkdir(parents=True)
    (dead / "figures" / "half.png").write_bytes(b"\x89PNG")
    stale_file = run / f".summary.json.{_dead_pid()}.00000000abcd.tmp"
    stale_file.write_text("{")
    live = run / f".report.{os.getppid()}.fedcba987654.tmp"  # a running process's: kept
    live.mkdir()
    run_cli("report", run, "--no-pdf", check=True)
    assert not dead.exists() and not stale_file.exists()
    assert live.is_dir() and (run / "report.html").is_file()


def test_remove_stale_temporaries_keeps_other_names(tmp_path: Path) -> None:
    keep = [
        tmp_path / "report.html",
        tmp_path / ".hidden",
        tmp_path / ".x.notapid.0123456789ab.tmp",
    ]
    for path in keep:
        path.write_text("x")
    mine = tmp_path / f".y.{os.getpid()}.0123456789ab.tmp"
    mine.write_text("x")
    gone = tmp_path / f".y.{_dead_pid()}.0123456789ab.tmp"
    gone.write_text("x")
    assert atomic.remove_stale_temporaries(tmp_path) == [gone]
    assert all(p.exists() for p in [*keep, mine])


def test_a_compare_interrupted_before_its_index_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """comparison.csv is written last; a folder with run folders but without it (compare
    killed mid-write) is refused by report in one line (it was reported, exit 0)."""
    from skymule.scenario import load_scenario

    comparison = compare_policies(load_scenario("paper-sim-fixed", ["mission.duration_s=60"]),
                                  ["greedy", "hgad"])  # fmt: skip

    def killed(*args: object) -> Path:
        raise KeyboardInterrupt

    out = tmp_path / "cmp"
    with monkeypatch.context() as patch:
        patch.setattr(compare_task, "write_bound", killed)
        with pytest.raises(KeyboardInterrupt):
            write_compare(comparison, out)
    assert (out / "greedy" / "summary.json").is_file() and not (out / COMPARISON_CSV).exists()
    done = run_cli("report", out, "--no-pdf")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "incomplete compare folder" in done.stderr and COMPARISON_CSV in done.stderr
    write_compare(comparison, out)  # run again: complete, and reported
    run_cli("report", out, "--no-pdf", check=True)
    with monkeypatch.context() as patch:  # a rewrite cut short: the old index is gone first
        patch.setattr(compare_task, "write_bound", killed)
        with pytest.raises(KeyboardInterrupt):
            write_compare(comparison, out)
    assert not (out / COMPARISON_CSV).exists()


PLUGIN = textwrap.dedent(
    '''
    """Two plug-ins whose classes share one name (the issue's MostBits pair)."""
    import numpy as np
    from pydantic import BaseModel
    from skymule import Action


    class MostBits:
        name = "mostbits"

        class Params(BaseModel):
            max_hover_s: float = 40.0

        def __init__(self, params):
            self.params = params

        def reset(self, context):
            pass

        def act(self, observation):
            usable = (observation.remaining_bit > 0) & (observation.rate_bps > 0)
            if not usable.any():
                return Action(serve=None)
            return Action(serve=int(np.argmax(np.where(usable, observation.rate_bps, -1.0))))


    class MostBitsFirstSensor(MostBits):
        """Same name, other choice: the first sensor that has data and a link."""

        def act(self, observation):
            usable = (observation.remaining_bit > 0) & (observation.rate_bps > 0)
            return Action(serve=int(np.argmax(usable)) if usable.any() else None)
    '''
)


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    (tmp_path / "mostbits32.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "mostbits32", raising=False)
    return "mostbits32"


def test_policies_sharing_a_class_name_are_labelled_as_asked(tmp_path: Path, plugin: str) -> None:
    asked = [f"{plugin}:MostBits", f"{plugin}:MostBitsFirstSensor"]
    done = run_cli(
        "compare", "paper-sim-fixed", "--policies", ",".join(["greedy", *asked]),
        "--out", tmp_path / "cmp", *SHORT, "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    rows = pd.read_csv(tmp_path / "cmp" / COMPARISON_CSV)
    assert rows["policy"].tolist() == ["greedy", *asked]  # a unique name is kept as it was
    printed = [r["policy"] for r in json.loads(done.stdout)["runs"]]
    assert printed == ["greedy", *asked]
    for name in asked:
        summary = json.loads((tmp_path / "cmp" / name / "summary.json").read_text())
        assert summary["policy"] == name


def test_a_preset_key_replacing_a_plugin_default_is_one_warning(
    tmp_path: Path, plugin: str
) -> None:
    """paper-sim-fixed's [policy] is HGAD with max_hover_s = 60; MostBits' own default is
    40. compare gives it 60 (run_missions did not): now it says so, in one line."""
    done = run_cli("compare", "paper-sim-fixed", "--policies", f"greedy,{plugin}:MostBits", *SHORT)
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "warning" in line]
    assert warnings == [
        f"skymule: warning: policy.params.max_hover_s = 60.0 (written for 'hgad') replaces "
        f"'{plugin}:MostBits''s own default 40.0"
    ]
    run = run_cli("run", "paper-sim-fixed", "--policy", f"{plugin}:MostBits", *SHORT)
    assert "replaces" in run.stderr and run.returncode == 0
    # the plug-in's own table, or the same value as its default: nothing to say
    own = run_cli(
        "run", "paper-sim-fixed", "--set", f'policy.name="{plugin}:MostBits"', *SHORT
    )  # fmt: skip
    assert own.returncode == 0 and "warning" not in own.stderr, own.stderr
    same = run_cli(
        "run", "paper-sim-fixed", "--policy", f"{plugin}:MostBits",
        "--set", "policy.params.max_hover_s=40", *SHORT,
    )  # fmt: skip
    assert same.returncode == 0 and "warning" not in same.stderr, same.stderr


def test_one_per_sensor_column_name_in_every_table(tmp_path: Path) -> None:
    """comparison.csv (was ``downloaded_mbit_LW1``) and a sweep's results.parquet
    (``per_sensor_downloaded_mbit.LW1``) name a sensor's download the same way."""
    run_cli("compare", "paper-sim-fixed", "--out", tmp_path / "cmp", *SHORT, check=True)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'base = "paper-sim-fixed"\nseed = 1\n[axes]\npolicy.name = ["greedy", "hgad"]\n'
        "mission.duration_s = [60]\n"
    )
    run_cli("sweep", sweep, "--out", tmp_path / "sw", "--workers", "1", check=True)
    compared = pd.read_csv(tmp_path / "cmp" / COMPARISON_CSV).columns
    swept = pd.read_parquet(tmp_path / "sw" / "results.parquet").columns
    per_sensor = {c for c in compared if "LW1" in c}
    assert per_sensor == {"per_sensor_downloaded_mbit.LW1"}
    assert per_sensor <= set(swept)
    assert not any(c.startswith("downloaded_mbit_") for c in [*compared, *swept])


def test_an_invalid_bound_is_drawn_and_said_to_be_invalid(tmp_path: Path) -> None:
    """Strong, fast shadowing fails the grid bound's condition (bound.json says so); the
    report drew a solid "upper bound" and gaps against it. Now: red dotted, labelled
    invalid, a warning on the page and on stderr."""
    out = tmp_path / "cmp"
    run_cli(
        "compare", "paper-sim-autonomous", "--out", out, "--set", "mission.duration_s=120",
        "--set", "radio.shadowing_std_db=10", "--set", "radio.shadowing_decorrelation_m=2",
        check=True,
    )  # fmt: skip
    warnings = json.loads((out / "bound.json").read_text())["warnings"]
    assert any("condition fails" in w for w in warnings)
    done = run_cli("report", out, "--no-pdf", check=True)
    assert f"skymule: warning: {out / 'bound.json'}: the grid bound's condition fails" in (
        done.stderr
    )
    page = (out / "report.html").read_text()
    assert "The bound is not valid for this mission" in page
    assert "bound, INVALID here [Mbit]" in page and "solid: the upper bound" not in page


def test_the_bars_draw_an_invalid_bound_dotted_and_labelled(tmp_path: Path) -> None:
    import matplotlib.pyplot as plt

    from skymule.report.inputs import load_input
    from skymule.report.panels import INVALID_BOUND_LABEL, draw_policy_bars

    run_cli("compare", "paper-sim-fixed", "--out", tmp_path / "cmp", *SHORT, check=True)
    runs = load_input(tmp_path / "cmp").runs
    for valid, style, label in ((True, "-", "upper bound"), (False, ":", INVALID_BOUND_LABEL)):
        fig, ax = plt.subplots()
        draw_policy_bars(ax, runs, bound_mbit=500.0, bound_valid=valid)
        (line,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
        assert line.get_linestyle() == style
        plt.close(fig)


def test_fleet_policies_sharing_a_class_name_get_two_folders(tmp_path: Path, plugin: str) -> None:
    """A fleet compare named each run folder by the class name: the second run of two
    plug-ins sharing it overwrote the first. Each is now its own folder and row."""
    asked = [f"{plugin}:MostBits", f"{plugin}:MostBitsFirstSensor"]
    fleet = ROOT / "examples" / "fleet-lake-wheeler.toml"
    done = run_cli(
        "compare", fleet, "--policies", ",".join(asked), "--out", tmp_path / "cmp", *SHORT
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert pd.read_csv(tmp_path / "cmp" / COMPARISON_CSV)["policy"].tolist() == asked
    for name in asked:
        assert (tmp_path / "cmp" / policy_folder(name) / "summary.json").is_file()
