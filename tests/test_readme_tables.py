"""scripts/render_tables.py: every table of README.md and docs/ is its benchmark's saved JSON."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
RENDER = runpy.run_path(str(ROOT / "scripts" / "render_tables.py"))
MAX_LINES = 300


def saved(name: str) -> dict[str, dict[str, object]]:
    tables: dict[str, dict[str, object]] = json.loads((RESULTS / name).read_text())["tables"]
    return tables


def test_every_page_shows_the_saved_tables() -> None:
    """``render_tables.py --check``: no table of README.md or docs/*.md differs from
    benchmarks/results/*.json (a hand edit or a stale page fails here)."""
    assert RENDER["main"](["--check"]) == 0


def test_every_marker_names_a_saved_table() -> None:
    tables = RENDER["load_tables"](RESULTS)
    markers = [
        line
        for page in RENDER["pages"](ROOT)
        for line in page.read_text().splitlines()
        if line.startswith("<!-- table:")
    ]
    assert len(markers) >= 12 and "<!-- table:sim2real -->" in markers
    for line in markers:
        assert all(n in tables for n in line[len("<!-- table:") : -4].split("+")), line


def test_the_renderer_is_short_and_reads_no_printed_output() -> None:
    source = (ROOT / "scripts" / "render_tables.py").read_text()
    assert len(source.splitlines()) <= MAX_LINES
    assert "import re\n" not in source and "subprocess" not in source


def test_render_replaces_only_the_lines_between_the_markers(tmp_path: Path) -> None:
    """Text outside the markers is kept; ``A+B`` renders A's rows then B's, notes after."""
    tables = {
        "a": {"columns": ["x", "n"], "rows": [["one", "1"]], "note": "A's note."},
        "b": {"columns": ["x", "n"], "rows": [["two", "-2.5"]]},
    }
    text = "intro\n<!-- table:a+b -->\nold\n<!-- /table:a+b -->\nafter | 1 |\n"
    new = RENDER["render"](text, tables, "page.md")
    assert new == (
        "intro\n<!-- table:a+b -->\n| x | n |\n|---|---:|\n| one | 1 |\n| two | -2.5 |\n\n"
        "A's note.\n<!-- /table:a+b -->\nafter | 1 |\n"
    )
    assert RENDER["render"](new, tables, "page.md") == new  # rendering is idempotent


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("<!-- table:nope -->\n<!-- /table:nope -->\n", "no table 'nope'"),
        ("<!-- table:a -->\nrow\n", "has no <!-- /table:a -->"),
    ],
)
def test_render_names_what_is_wrong(text: str, message: str) -> None:
    tables = {"a": {"columns": ["x"], "rows": [["1"]]}}
    with pytest.raises(RENDER["TableError"], match=message):
        RENDER["render"](text, tables, "page.md")


def test_check_reports_drift_and_a_bad_results_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "results").mkdir()
    page = tmp_path / "README.md"
    page.write_text("<!-- table:t -->\n| x |\n|---|\n| 1 |\n<!-- /table:t -->\n")
    results = tmp_path / "results" / "t.json"
    results.write_text(json.dumps({"tables": {"t": {"columns": ["x"], "rows": [["2"]]}}}))
    args = ["--root", str(tmp_path), "--results", str(tmp_path / "results")]
    assert RENDER["main"]([*args, "--check"]) == 1
    assert "README.md: <!-- table:t -->" in capsys.readouterr().out
    assert "| 1 |" in page.read_text()  # --check writes nothing
    assert RENDER["main"](args) == 0 and "| 2 |" in page.read_text()
    assert RENDER["main"]([*args, "--check"]) == 0
    results.write_text(json.dumps({"tables": {"t": {"columns": ["x"], "rows": [["1", "2"]]}}}))
    assert RENDER["main"](args) == 2
    assert "t.json: table 't' row 0 has 2 cells, not 1" in capsys.readouterr().err


def test_the_deterministic_tables_are_what_skymule_gives_today(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The results tables without timings (presets, autonomous, Table II, sources, bounds,
    planner), recomputed by benchmarks/bench_presets.py, equal the saved ones cell for cell."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    monkeypatch.delenv("SKYMULE_BENCH_TINY", raising=False)
    bench = runpy.run_path(str(ROOT / "benchmarks" / "bench_presets.py"))
    saved_tables = saved("presets.json")
    for name in bench["DETERMINISTIC"]:
        assert bench["TABLES"][name]() == saved_tables[name], name


def test_results_writer_merges_rows_of_other_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``_results.write(merge_on=2)`` (bench_sweep.py's scale mode): a run's rows replace rows
    with the same size and executor, the others are kept, in order of size."""
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    sys.modules.pop("_results", None)
    import _results

    path = tmp_path / "scale.json"
    columns = ["missions", "executor", "s"]
    _results.write(path, {"s": _results.table(columns, [["1,000", "a", "1"], ["20", "a", "2"]])})
    _results.write(path, {"s": _results.table(columns, [["1,000", "a", "3"]])}, merge_on=2)
    rows = json.loads(path.read_text())["tables"]["s"]["rows"]
    assert rows == [["20", "a", "2"], ["1,000", "a", "3"]]
    argv = ["bench", "--x", "--json", "out.json", "1"]
    assert _results.json_option(argv) == Path("out.json") and argv == ["bench", "--x", "1"]
