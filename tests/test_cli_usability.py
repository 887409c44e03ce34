"""What every CLI has: --version, python -m, --json, --set, presets shown, did-you-mean,
output folders that are never silently mixed, Ctrl-C that says how to resume."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import SMALL_SWEEP, run_cli
from skymule.scenario import presets

ROOT = Path(__file__).parents[1]


def one_line_error(done: object, *needles: str) -> None:
    assert done.returncode == 2, done
    stderr = done.stderr
    assert len(stderr.strip().splitlines()) == 1, stderr
    for needle in needles:
        assert needle in stderr, stderr


def test_python_m_and_version() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    done = subprocess.run(
        [sys.executable, "-m", "skymule", "--version"],
        capture_output=True, text=True, env=env, timeout=120, check=True,
    )  # fmt: skip
    assert re.fullmatch(r"skymule \S+\n", done.stdout)
    helped = subprocess.run(
        [sys.executable, "-m", "skymule", "--help"],
        capture_output=True, text=True, env=env, timeout=120, check=True,
    )  # fmt: skip
    for command in ("run", "compare", "bound", "sweep", "--install-completion"):
        assert command in helped.stdout


def test_json_summaries_are_machine_readable() -> None:
    run = json.loads(run_cli("run", "paper-sim-fixed", "--json", check=True).stdout)
    assert run["policy"] == "hgad" and run["total_downloaded_mbit"] == pytest.approx(2756.434)
    compared = json.loads(
        run_cli("compare", "paper-sim-fixed", "--policies", "greedy,hgad", "--json").stdout
    )
    by_policy = {row["policy"]: row for row in compared["runs"]}
    assert by_policy["greedy"]["gap_to_bound_mbit"] == pytest.approx(562.402, abs=1e-3)
    assert compared["bounds"]["scenario"]["upper_bound_mbit"] == pytest.approx(3000.0)


def test_set_overrides_dotted_keys_with_file_validation() -> None:
    base = json.loads(run_cli("run", "paper-sim-fixed", "--json", check=True).stdout)
    assert base["per_sensor_buffer_mbit"]["LW3"] == 700
    changed = run_cli(
        "run", "paper-sim-fixed", "--json",
        "--set", "sensors[2].buffer_mbit=100", "--set", "policy.name=greedy",
        check=True,
    )  # fmt: skip
    summary = json.loads(changed.stdout)
    assert summary["per_sensor_buffer_mbit"]["LW3"] == 100 and summary["policy"] == "greedy"
    # the preset has the older flat max_hover_s; a params override still wins
    capped = run_cli(
        "run", "paper-sim-fixed", "--json", "--set", "policy.params.max_hover_s=1", check=True
    )
    assert json.loads(capped.stdout)["hover_time_s"] < base["hover_time_s"]
    one_line_error(
        run_cli("run", "paper-sim-fixed", "--set", "sensors[2].buffer_mbit=-5"),
        "sensors[2].buffer_mbit = -5",
    )
    one_line_error(run_cli("bound", "paper-sim-fixed", "--set", "sensors[9].buffer_mbit=1"), "[9]")
    one_line_error(run_cli("compare", "paper-sim-fixed", "--set", "seed"), "key=value")


def test_misspelt_keys_presets_and_policies_get_did_you_mean(tmp_path: Path) -> None:
    # a misspelt required key: name the unknown key and the right one, not only "required"
    one_line_error(
        run_cli(
            "run", "paper-sim-fixed",
            "--set", "sensors[1].bufer_mbit=5", "--set", "sensors[1].buffer_mbit=",
        ),
        "'sensors[1].bufer_mbit'", "did you mean 'buffer_mbit'?",
    )  # fmt: skip
    text = presets().get("paper-sim-fixed").replace("buffer_mbit = 800", "bufer_mbit = 800")
    (tmp_path / "typo.toml").write_text(text)
    one_line_error(run_cli("run", tmp_path / "typo.toml"), "did you mean 'buffer_mbit'?")
    one_line_error(run_cli("run", "paper-sim-fixd"), "did you mean 'paper-sim-fixed'?")
    one_line_error(
        run_cli("compare", "paper-sim-fixed", "--policies", "greedy,hgda"),
        "unknown policy 'hgda'", "did you mean 'hgad'?",
    )  # fmt: skip
    one_line_error(
        run_cli("run", "paper-sim-fixed", "--set", "policy.params.max_hover=3"),
        "policy.params.max_hover", "did you mean 'max_hover_s'?",
    )  # fmt: skip
    one_line_error(run_cli("sweep", "x.toml", "--out", tmp_path, "--executor", "proces"))


def test_scenarios_show_prints_the_preset_with_comments() -> None:
    shown = run_cli("scenarios", "--show", "paper-sim-fixed", check=True).stdout
    assert shown == presets().get("paper-sim-fixed")
    assert shown.startswith("#") and "lawnmower" in shown
    one_line_error(run_cli("scenarios", "--show", "aadm"), "did you mean 'aadm-default'?")


def test_output_folders_are_not_overwritten_or_mixed(tmp_path: Path) -> None:
    out = tmp_path / "hgad"
    run_cli("run", "paper-sim-fixed", "--out", out, check=True)
    run_cli("run", "paper-sim-fixed", "--out", out, check=True)  # the same run again is fine
    one_line_error(
        run_cli("run", "paper-sim-fixed", "--out", out, "--policy", "greedy"),
        "policy 'hgad'", "--force",
    )  # fmt: skip
    assert json.loads((out / "summary.json").read_text())["policy"] == "hgad"
    run_cli("run", "paper-sim-fixed", "--out", out, "--policy", "greedy", "--force", check=True)
    assert json.loads((out / "summary.json").read_text())["policy"] == "greedy"

    cmp = tmp_path / "cmp"
    run_cli("compare", "paper-sim-fixed", "--out", cmp, check=True)
    one_line_error(run_cli("run", "paper-sim-fixed", "--out", cmp), "a comparison")
    one_line_error(run_cli("compare", "aadm-default", "--out", cmp), "'paper-sim-fixed'")
    run_cli("bound", "paper-sim-fixed", "--out", cmp, check=True)  # its own bound.json
    one_line_error(run_cli("bound", "paper-sim-fixed", "--out", out), "a run")
    other = tmp_path / "notes"
    other.mkdir()
    (other / "thesis.txt").write_text("mine")
    one_line_error(run_cli("compare", "paper-sim-fixed", "--out", other), "other files")
    assert (other / "thesis.txt").read_text() == "mine"


def test_a_source_comparison_and_a_policy_comparison_never_share_a_folder(
    tmp_path: Path,
) -> None:
    mix = tmp_path / "mix"
    sources = ("--sources", "fspl,two-ray", "--policies", "greedy")
    run_cli("compare", "paper-sim-fixed", *sources, "--out", mix, check=True)
    run_cli("compare", "paper-sim-fixed", *sources, "--out", mix, check=True)  # the same again
    (mix / "notes.txt").write_text("mine")
    refused = run_cli("compare", "paper-sim-fixed", "--policies", "greedy", "--out", mix)
    # each name once, though comparison.csv has a row per source and policy
    one_line_error(refused, "holds a comparison of greedy under sources fspl, two-ray on")
    one_line_error(run_cli("bound", "paper-sim-fixed", "--out", mix), "under sources")
    assert not (mix / "bound.json").exists()
    one_line_error(run_cli("compare", "paper-sim-fixed", "--sources", "fspl", "--out", mix))

    # --force replaces the comparison: nothing of the source comparison is left behind
    run_cli("compare", "paper-sim-fixed", "--policies", "greedy,hgad", "--out", mix, "--force")
    left = sorted(p.name for p in mix.iterdir())
    assert left == ["bound.json", "comparison.csv", "greedy", "hgad", "notes.txt"]
    # a comparison of a subset of the policies would leave the others' folders: refused
    one_line_error(run_cli("compare", "paper-sim-fixed", "--policies", "hgad", "--out", mix))
    run_cli("compare", "paper-sim-fixed", "--policies", "hgad,greedy", "--out", mix, check=True)


def test_plot_points_a_sweep_folder_to_report_and_draws_a_source_comparison(
    tmp_path: Path,
) -> None:
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SMALL_SWEEP.format(n=1))
    swept = tmp_path / "swept"
    run_cli("sweep", sweep, "--out", swept, "--executor", "inprocess", "--quiet", check=True)
    one_line_error(run_cli("plot", swept), f"`skymule report {swept}`")
    sources = tmp_path / "sources"
    run_cli(
        "compare", "paper-sim-fixed", "--sources", "fspl,two-ray", "--policies", "greedy",
        "--out", sources, check=True,
    )  # fmt: skip
    drawn = run_cli("plot", sources, check=True).stdout
    for source in ("fspl", "two-ray"):
        assert f"{sources / source / 'greedy' / 'download.png'}" in drawn
        assert (sources / source / "greedy" / "download.png").stat().st_size > 1000


def test_report_without_pdf_leaves_no_stale_pdfs(tmp_path: Path) -> None:
    out = tmp_path / "run"
    run_cli("run", "paper-sim-fixed", "--out", out, check=True)
    (out / "figures").mkdir()
    stale = out / "figures" / "old.pdf"
    stale.write_bytes(b"%PDF-1.4 stale")
    done = run_cli("report", out, "--no-pdf", check=True)
    assert not list((out / "figures").glob("*.pdf"))
    assert ".pdf" not in done.stdout
    assert ".pdf" not in (out / "report.html").read_text()


SWEEP = """base = "paper-sim-fixed"
seed = 1
[axes]
policy.name = ["greedy", "hgad"]
seed = {{ range = [0, {n}] }}
"""


def test_sweep_folder_remembers_its_sweep_file(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP.format(n=2))
    out = tmp_path / "sw"
    args = ("--out", out, "--executor", "inprocess", "--quiet")
    run_cli("sweep", sweep, *args, check=True)
    again = run_cli("sweep", sweep, *args, check=True)
    assert "ran 0 of 4" in again.stdout  # resumed: nothing left to run
    sweep.write_text(SWEEP.format(n=3))
    one_line_error(run_cli("sweep", sweep, *args), "holds the sweep")
    one_line_error(run_cli("sweep", sweep, *args, "--set", "mission.duration_s=100"))
    run_cli("sweep", sweep, *args, "--force", check=True)
    one_line_error(run_cli("run", "paper-sim-fixed", "--out", out), "a sweep")


def test_ctrl_c_on_a_sweep_says_what_was_kept_and_how_to_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import skymule.experiments.run as sweep_run

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_run, "run_sweep", interrupted)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP.format(n=2))
    done = run_cli("sweep", sweep, "--out", tmp_path / "sw", "--workers", "2")
    assert done.returncode == 130
    assert "kept 0 of 4 missions" in done.stderr
    assert f"Resume with: skymule sweep {sweep} --out {tmp_path / 'sw'}" in done.stderr
    assert "--workers 2" in done.stderr


def test_analyze_says_which_buffers_it_assumed(tmp_path: Path) -> None:
    log = ROOT / "tests" / "fixtures" / "aadm_merged_small.csv"
    done = run_cli("analyze", log, "--out", tmp_path / "a", "--no-pdf", check=True)
    assert "assumed 1000 Mbit per tower" in done.stdout
    given = run_cli(
        "analyze", log, "--out", tmp_path / "b", "--no-pdf", "--buffers", "50", check=True
    )
    assert "assumed" not in given.stdout
