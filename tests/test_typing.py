"""Types and lint are CI steps of their own (``.ci/run``), before the tests: not inside pytest."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ci_checks_lint_and_types_before_the_tests() -> None:
    steps = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    tests = steps.index("python -m pytest -q")
    assert steps.index("ruff check src tests benchmarks scripts") < tests
    assert steps.index("mypy") < tests
    # mypy's own configuration names what it checks (the package, strictly typed)
    assert 'files = ["src/skymule"]' in (ROOT / "pyproject.toml").read_text()
