"""The test suite as the README runs it: how many tests, how many passed, and its wall time.

Run: python benchmarks/bench_suite.py [--json PATH]   (~3 min on 2 cores)
(SKYMULE_BENCH_TINY=1: one small test file instead of the suite; not a measurement)

It runs ``python -m pytest -q`` from the repository root in a fresh process and counts the
tests from pytest's JUnit XML report (``--junitxml``), not from its printed summary.
``--json benchmarks/results/suite.json``: the suite table of docs/speed.md.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from _results import json_option, table, write
from _sizes import tiny

ROOT = Path(__file__).resolve().parents[1]
TINY_TESTS = ["tests/test_public_api.py", "-n", "0"]


def counts(report: Path) -> dict[str, int]:
    """Tests, failures (errors included) and skips of a JUnit XML report."""
    suites = ET.parse(report).getroot()
    found = {"tests": 0, "failed": 0, "skipped": 0}
    for suite in suites.iter("testsuite"):
        found["tests"] += int(suite.get("tests", 0))
        found["failed"] += int(suite.get("failures", 0)) + int(suite.get("errors", 0))
        found["skipped"] += int(suite.get("skipped", 0))
    return found


def main(json_path: Path | None) -> None:
    """Run the suite, print and save its counts and wall time."""
    with tempfile.TemporaryDirectory() as scratch:
        report = Path(scratch) / "junit.xml"
        command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
        start = time.perf_counter()
        done = subprocess.run(
            [*command, f"--junitxml={report}", *(TINY_TESTS if tiny() else [])],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
        seconds = time.perf_counter() - start
        if not report.exists():
            raise SystemExit(f"pytest wrote no report (exit {done.returncode}):\n{done.stderr}")
        found = counts(report)
    passed = found["tests"] - found["failed"] - found["skipped"]
    print(
        f"{found['tests']} tests: {passed} passed, {found['skipped']} skipped, "
        f"{found['failed']} failed, {seconds:.1f} s wall (exit {done.returncode})"
    )
    row = [found["tests"], passed, found["skipped"], found["failed"], f"{seconds:.0f}"]
    columns = ["tests", "passed", "skipped", "failed", "wall time [s]", "command"]
    write(json_path, {"suite": table(columns, [[*row, "`python -m pytest -q`"]])})


if __name__ == "__main__":
    main(json_option())
