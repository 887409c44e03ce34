"""The README is a README: short, its set-up commands are CI's, and its Python runs as written."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 300


def python_blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


def test_readme_python_blocks_run_and_the_batched_form_in_the_docs_too() -> None:
    """The README's blocks in order, then docs/policies.md's (the batched form of the
    README's own policy, which it continues), in one namespace as a reader runs them."""
    blocks = python_blocks(README)
    assert blocks, "the README should show a Python quick start"
    namespace: dict[str, object] = {}
    for page, block in [(README, b) for b in blocks] + [
        (ROOT / "docs" / "policies.md", b) for b in python_blocks(ROOT / "docs" / "policies.md")
    ]:
        exec(compile(block, str(page), "exec"), namespace)
    result = namespace["result"]
    plugin = namespace["LargestBufferFirst"]
    policy = plugin(plugin.Params(min_snr_db=3))  # type: ignore[attr-defined,operator]
    assert policy.name == "largest-buffer-first" and policy.params.min_snr_db == 3
    batched = namespace["batched"]  # the batched form, run beside the per-mission one
    assert float(batched.downloaded_bit.sum()) > 0  # type: ignore[attr-defined]
    assert namespace["LargestBufferFirstBatched"].batched is True  # type: ignore[attr-defined]
    comparison = namespace["comparison"]
    gaps = [round(r["gap_to_bound_mbit"], 1) for r in comparison.rows()]  # type: ignore[attr-defined]
    assert gaps == [562.4, 243.6]
    assert result.summary["policy"] == "greedy"  # type: ignore[attr-defined]


def test_readme_states_the_two_setup_commands() -> None:
    text = README.read_text()
    assert "pip install -e '.[test,dask,browser,fast]'" in text
    assert "python -m pytest -q" in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert "pip install -q -e '.[test,dask,browser,fast]'" in ci and "python -m pytest -q" in ci
    # the default run leaves the slow tests out (pyproject's addopts); CI runs them too, and
    # the README says how
    steps = [line.strip() for line in ci.splitlines()]
    assert steps.index("python -m pytest -q -m slow") > steps.index("python -m pytest -q")
    assert "python -m pytest -q -m slow" in text


def test_readme_is_short_and_links_every_doc() -> None:
    """At most 300 lines; every page of docs/ is linked from it (the rest lives there)."""
    text = README.read_text()
    assert len(text.splitlines()) <= MAX_LINES
    unlinked = [
        p.name for p in sorted((ROOT / "docs").glob("*.md")) if f"docs/{p.name}" not in text
    ]
    assert not unlinked, f"README.md does not link {unlinked}"
    assert text.count("<!-- table:") == 1, "one result table"
