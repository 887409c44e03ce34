"""Every value of the run, compare, bound and fit-radiomap tables reads in full at 60 and 80
columns and when piped: the values come from the same command's --json output."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rich.console import Console

from conftest import run_cli
from skymule.cli import output
from skymule.cli.tables import cells, fmt, fmt_mean_ci
from skymule.io.traces import write_dt_export
from skymule.tasks.radiomaps import RadioMapFit

WIDTHS = (60, 80, None)  # None: piped (plain text)


@pytest.fixture(params=WIDTHS, ids=lambda w: f"{w}-columns" if w else "piped")
def width(request: pytest.FixtureRequest) -> Iterator[int | None]:
    """Print tables to a terminal of that width (None: the piped console tests use)."""
    if request.param is None:
        yield None
        return
    saved = output.console
    # no file: rich writes to sys.stdout at print time, which run_cli captures
    output.console = Console(width=request.param, force_terminal=True, color_system=None)
    try:
        yield request.param
    finally:
        output.console = saved


def assert_intact(text: str, values: list[Any], width: int | None) -> None:
    """Every value appears whole: numbers as a token, text with its line folds removed."""
    tokens = set(text.split())
    squeezed = "".join(text.split())
    for value in values:
        if value is None or isinstance(value, dict | list):
            continue
        shown = fmt(value)
        if isinstance(value, int | float) and not isinstance(value, bool):
            # a column shows all its numbers with the same decimals: a whole 3000.0 next to
            # 2756.4 reads "3000.0"; never fewer decimals than the value needs
            forms = {fmt(value, places) for places in (1, 3)} | {shown}
            assert forms & tokens, f"{shown} missing or cut at width {width}:\n{text}"
        else:
            assert "".join(shown.split()) in squeezed, f"{shown!r} cut at width {width}:\n{text}"
    if width is not None:  # tables fit; a "wrote PATH" line is never folded (test below)
        table_lines = [line for line in text.splitlines() if not line.startswith("wrote ")]
        assert max(len(line) for line in table_lines) <= width, text


def test_run_table(width: int | None) -> None:
    summary = json.loads(run_cli("run", "paper-sim-fixed", "--json", check=True).stdout)
    text = run_cli("run", "paper-sim-fixed", check=True).stdout
    values = [summary[k] for k in ("total_downloaded_mbit", "completion", "handovers")]
    values += [summary[k] for k in ("hover_time_s", "distance_m", "energy_kj", "aadm_score")]
    values += list(summary["per_sensor_downloaded_mbit"].values())
    values += list(summary["per_sensor_buffer_mbit"].values())
    assert_intact(text, values, width)


def test_compare_table(width: int | None) -> None:
    args = ("compare", "paper-sim-fixed", "--policies", "greedy,hgad")
    data = json.loads(run_cli(*args, "--json", check=True).stdout)
    text = run_cli(*args, check=True).stdout
    columns = ("policy", "total_downloaded_mbit", "completion", "handovers", "hover_time_s")
    columns += ("distance_m", "energy_kj", "aadm_score", "gap_to_bound_mbit", "gap_to_bound_frac")
    values = [row[c] for row in data["runs"] for c in columns]
    values.append(data["bounds"]["scenario"]["upper_bound_mbit"])
    assert "562.4" in [fmt(v) for v in values]  # the gap the issue saw cut to "562"
    assert_intact(text, values, width)


def test_bound_table(width: int | None) -> None:
    record = json.loads(run_cli("bound", "paper-sim-fixed", "--json", check=True).stdout)
    text = run_cli("bound", "paper-sim-fixed", check=True).stdout
    assert record["upper_bound_mbit"] == pytest.approx(3000.0)
    shown = {k: v for k, v in record.items() if k != "warnings"}  # those go to stderr
    values = [v for k, v in shown.items() if k != "solve_time_s"]  # timing differs per run
    assert_intact(text, [*values, *shown], width)


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A digital-twin export over two towers: log-distance SNR + 1 dB noise, 300 samples."""
    rng = np.random.default_rng(5)
    x = np.tile(np.linspace(-300.0, 300.0, 60), 5)
    y = np.repeat(np.linspace(-200.0, 200.0, 5), 60)
    z = np.full(x.size, 30.0)
    towers = np.array([[0.0, 100.0], [200.0, -100.0]])
    d = np.hypot(x[:, None] - towers[None, :, 0], y[:, None] - towers[None, :, 1]) + 20.0
    snr = np.array([70.0, 66.0]) - 25.0 * np.log10(d) + rng.standard_normal(d.shape)
    path = tmp_path_factory.mktemp("flight") / "flight.csv"
    write_dt_export(path, np.arange(x.size, dtype=float), snr, ["LW1", "LW2"], x, y, z)
    return path


@pytest.fixture(scope="module")
def flight_fit(flight: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The fit's JSON record, once (it does not depend on the terminal width)."""
    out = tmp_path_factory.mktemp("fit") / "map.json"
    return json.loads(run_cli("fit-radiomap", flight, "--out", out, "--json", check=True).stdout)


def test_fit_radiomap_table(
    width: int | None, flight: Path, flight_fit: dict[str, Any], tmp_path: Path
) -> None:
    fit = flight_fit
    text = run_cli("fit-radiomap", flight, "--out", tmp_path / "map.json", check=True).stdout
    values = [row[c] for row in fit["sensors"] for c in RadioMapFit.COLUMNS]
    assert any(k.startswith("cv_rmse") for k in fit["sensors"][0])
    assert_intact(text, values, width)


def test_written_paths_are_never_folded(tmp_path: Path, width: int | None) -> None:
    """A 'wrote PATH' line keeps a long path on one line at any width, so it can be copied
    or piped whole (rich folds long words at the terminal width by default)."""
    out = tmp_path / ("a-folder-name-long-enough-to-pass-any-terminal-width-" * 2) / "run"
    done = run_cli(
        "run", "paper-sim-fixed", "--set", "mission.duration_s=20", "--out", out, check=True
    )
    assert f"wrote {out}/summary.json" in done.stdout


def test_a_column_shows_its_numbers_alike() -> None:
    """Counts without decimals (not ``4.000``); one quantity with one number of decimals
    (hover ``0`` and ``155``, not ``0.000`` next to ``155.0``); ``mean ± CI`` alike."""
    table = run_cli("compare", "paper-sim-fixed", "--policies", "greedy,hgad", check=True)
    lines = table.stdout.splitlines()
    header = lines[1].split()
    rows = {line.split()[0]: line.split() for line in lines[3:5]}
    hover = header.index("hover")  # "hover s": the words before it are one column each
    assert [rows[p][hover] for p in ("greedy", "hgad")] == ["0", "155"]
    assert cells([{"n": 4.0}, {"n": 7.0}], ["n"]) == [["4"], ["7"]]
    assert cells([{"x": 0.0}, {"x": 155.5}], ["x"]) == [["0.0"], ["155.5"]]
    assert cells([{"x": 0.8125}, {"x": 1.0}], ["x"]) == [["0.812"], ["1.000"]]
    assert fmt_mean_ci(134.7, 2.838) == "134.7 ± 2.8"
    assert fmt_mean_ci(0.849, 0.0101) == "0.849 ± 0.010"
    assert fmt_mean_ci(0.0, 0.0) == "0 ± 0"
