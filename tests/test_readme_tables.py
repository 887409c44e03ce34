"""scripts/update_readme_tables.py: the README's measured tables come from the commands."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = runpy.run_path(str(ROOT / "scripts" / "update_readme_tables.py"))


def test_rewrite_touches_only_the_lines_between_the_markers() -> None:
    text = "intro\n<!-- table:x -->\n| a |\n|---|\n| 1 |\n<!-- /table -->\nafter | 1 |\n"
    new = SCRIPT["rewrite"](text, "x", lambda old: [*old[:2], "| 2 |"])
    assert new == text.replace("| 1 |\n<!--", "| 2 |\n<!--")
    with pytest.raises(SystemExit, match="no <!-- table:y -->"):
        SCRIPT["rewrite"](text, "y", lambda old: old)


def test_every_table_the_script_knows_is_marked_in_the_readme() -> None:
    lines = (ROOT / "README.md").read_text().split("\n")
    for name in SCRIPT["TABLES"]:
        start, end = SCRIPT["table_span"](lines, name)
        assert end > start + 2, name  # header, rule and at least one row


def test_readme_result_tables_are_what_the_commands_give_today() -> None:
    """The deterministic tables (no timings) match a fresh run: they have not drifted."""
    assert SCRIPT["main"](["--check", "--only", "presets,autonomous"]) == 0


def test_readme_planner_table_is_what_the_commands_give_today() -> None:
    """HGAD and the planner against the autonomous bound (its AADM scores once drifted)."""
    assert SCRIPT["main"](["--check", "--only", "planner"]) == 0
