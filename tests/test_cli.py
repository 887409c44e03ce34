"""The command line as a user drives it: files written, tables printed, mistakes reported."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from conftest import CliResult, run_cli
from skymule.scenario import load_scenario

SKYMULE = str(Path(sys.executable).with_name("skymule"))


def skymule(*args: str, cwd: Path | None = None) -> CliResult:
    return run_cli(*args, cwd=cwd)


def test_run_writes_summary_and_slots(tmp_path: Path) -> None:
    """Through the installed entry point in its own process (other CLI tests run in-process)."""
    out = tmp_path / "run"
    done = subprocess.run(
        [SKYMULE, "run", "paper-sim-fixed", "--out", str(out), "--policy", "greedy"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "LW4" in done.stdout and "greedy" in done.stdout
    summary = json.loads((out / "summary.json").read_text())
    for key in (
        "scenario",
        "policy",
        "mission_time_s",
        "slots",
        "total_downloaded_mbit",
        "per_sensor_downloaded_mbit",
        "per_sensor_buffer_mbit",
        "completion",
        "handovers",
        "hover_time_s",
        "distance_m",
    ):
        assert key in summary
    assert summary["policy"] == "greedy" and summary["slots"] == 500
    slots = pd.read_csv(out / "slots.csv", keep_default_na=False)
    names = ["LW1", "LW2", "LW3", "LW4"]
    expected = [
        "t_s",
        "x_m",
        "y_m",
        "z_m",
        "lat",
        "lon",
        "served",
        *[f"snr_db_{n}" for n in names],
        *[f"remaining_mbit_{n}" for n in names],
        "rate_mbps",
        "downloaded_mbit",
        "hovering",
    ]
    assert all(column in slots.columns for column in expected)
    assert len(slots) == 500
    assert slots["downloaded_mbit"].sum() == pytest.approx(summary["total_downloaded_mbit"])
    assert set(slots["served"]) <= {"", *names}
    # lat/lon at the edge agree with the launch point for the first slot (path starts there)
    assert slots["lat"][0] == pytest.approx(35.7274824, abs=1e-6)
    # the saved scenario reloads to the same mission
    saved = json.loads((out / "scenario.json").read_text())
    assert saved["name"] == "paper-sim-fixed" and saved["policy"]["name"] == "greedy"


def test_compare_and_plot(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    done = skymule("compare", "paper-sim-fixed", "--policies", "greedy,hgad", "--out", str(out))
    assert done.returncode == 0, done.stderr
    table = pd.read_csv(out / "comparison.csv")
    assert table["policy"].tolist() == ["greedy", "hgad"]
    for policy in ("greedy", "hgad"):
        one = json.loads((out / policy / "summary.json").read_text())
        row = table.set_index("policy").loc[policy]
        assert row["total_downloaded_mbit"] == pytest.approx(one["total_downloaded_mbit"])
    # plotting works from the files alone, in a copied folder
    copied = tmp_path / "elsewhere"
    (out / "hgad").rename(copied)
    done = skymule("plot", str(copied))
    assert done.returncode == 0, done.stderr
    for name in ("download.png", "snr_cdf.png"):
        assert (copied / name).stat().st_size > 10_000


def test_scenarios_lists_presets() -> None:
    done = skymule("scenarios")
    assert done.returncode == 0
    assert "paper-sim-fixed" in done.stdout and "aadm-default" in done.stdout


def test_in_process_runs_capture_tables_and_usage_errors() -> None:
    """run_cli (conftest) sees what a piped `skymule` prints: rich tables, click's usage."""
    done = skymule("scenarios")
    assert done.returncode == 0 and done.stderr == ""
    assert "paper-sim-fixed" in done.stdout and "\x1b[" not in done.stdout  # no colour codes
    done = skymule("run", "paper-sim-fixed", "--bogus")
    assert done.returncode == 2 and done.stdout == ""
    assert "No such option" in done.stderr and "--bogus" in done.stderr


def test_presets_match_the_paper_and_aadm() -> None:
    paper = load_scenario("paper-sim-fixed")
    assert [s.buffer_mbit for s in paper.sensors] == [500, 800, 700, 1000]
    assert paper.mission.duration_s == 500 and paper.radio.model == "fspl"
    assert paper.trajectory.speed_mps == 10.0
    assert {w[2] for w in paper.trajectory.waypoints} == {30}  # type: ignore[union-attr]
    aadm = load_scenario("aadm-default")
    assert [s.buffer_mbit for s in aadm.sensors] == [1000] * 4
    assert aadm.radio.rate_table == "aadm-lte-cqi"


BASE = """
name = "bad"
[mission]
duration_s = 20
[site]
geofence = "lake-wheeler"
[[sensors]]
name = "LW1"
x_m = 27.0
y_m = -3.0
buffer_mbit = 100
[trajectory]
waypoints = [[0, 0, 30], [-100, 100, 30]]
"""


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        (("[trajectory]", '[policy]\nname = "psychic"\n[trajectory]'), "unknown policy 'psychic'"),
        (("[trajectory]", '[radio]\nrate_table = "lte-magic"\n[trajectory]'), "rate_table"),
        (("buffer_mbit = 100", "buffer_mbit = -5"), "sensors[0].buffer_mbit = -5"),
        (("[[0, 0, 30], [-100, 100, 30]]", "[[0, 0, 30]]"), "at least 2"),
        (("[[0, 0, 30], [-100, 100, 30]]", "[[0, 0, 30], [2000, 0, 30]]"), "outside the geofence"),
        (("buffer_mbit = 100", "buffer_mbit = 100\nbufer = 3"), "unknown field 'sensors[0].bufer'"),
        (("duration_s = 20", 'duration_s = "long"'), "mission.duration_s"),
        (("[site]", "[site]\nspeed = 1\n"), "unknown field 'site.speed'"),
        (("duration_s = 20", "duration_s = inf"), "mission.duration_s = inf: Input should be a"),
    ],
)
def test_bad_scenarios_get_one_line_and_exit_2(
    tmp_path: Path, edit: tuple[str, str], needle: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(BASE.replace(*edit))
    done = skymule("run", str(path))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert needle in lines[0]
    assert "Traceback" not in done.stderr


def _trace_scenario(tmp_path: Path, trace_text: str) -> Path:
    (tmp_path / "flight.csv").write_text(trace_text)
    path = tmp_path / "t.toml"
    path.write_text(
        '[[sensors]]\nname = "LW1"\nbuffer_mbit = 10\n'
        '[[sensors]]\nname = "LW2"\nbuffer_mbit = 10\n'
        '[signal]\nsource = "trace"\ntrace = "flight.csv"\n'
    )
    return path


@pytest.mark.parametrize(
    ("trace", "needle"),
    [
        ("Time,LW1,X,Y,Height\n0,10,0,0,30\n1,12,5,0,30\n", "LW2"),
        ("", "flight.csv"),
        ("Time,LW1,LW2,X,Y,Height\n", "flight.csv"),
        ("Time,LW1,LW2,X,Y,Height\n0,10,abc,0,0,30\n", "abc"),
    ],
    ids=["missing-column", "empty", "header-only", "non-numeric"],
)
def test_bad_traces_get_one_line_and_exit_2(tmp_path: Path, trace: str, needle: str) -> None:
    done = skymule("run", str(_trace_scenario(tmp_path, trace)))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], done.stderr


def test_bad_flags_and_folders_exit_2(tmp_path: Path) -> None:
    assert skymule("run", "paper-sim-fixed", "--bogus").returncode == 2
    done = skymule("compare", "paper-sim-fixed", "--policies", "greedy,oracle")
    assert done.returncode == 2 and "oracle" in done.stderr
    done = skymule("plot", str(tmp_path))
    assert done.returncode == 2 and "not a run folder" in done.stderr
    done = skymule("run", "no-such-preset")
    assert done.returncode == 2 and "paper-sim-fixed" in done.stderr


def test_unwritable_output_folder_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    done = skymule("run", "paper-sim-fixed", "--out", str(blocker / "run"))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and str(blocker) in lines[0], done.stderr


def test_damaged_run_folder_is_one_line(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert skymule("run", "paper-sim-fixed", "--out", str(out)).returncode == 0
    slots = pd.read_csv(out / "slots.csv", keep_default_na=False)
    slots.drop(columns=["served"]).to_csv(out / "slots.csv", index=False)
    for command in (("plot", str(out)), ("report", str(out)), ("export", str(out), "--kml")):
        done = skymule(*command)
        assert done.returncode == 2, command
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and "missing column(s) served" in lines[0], done.stderr


def test_damaged_comparison_table_is_one_line(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    assert skymule("compare", "paper-sim-fixed", "--out", str(out)).returncode == 0
    (out / "comparison.csv").write_bytes(b"\x00\xff\xfe not a table")
    done = skymule("report", str(out), "--no-pdf")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "comparison.csv: cannot read" in lines[0], done.stderr
