"""Ctrl-C on a sweep is one line and the resume command, on every executor (issue 24).

A terminal's Ctrl-C goes to the whole foreground process group: the sweep process and every
worker it started. Each test starts a real sweep in a session of its own and signals that
group once the first part is stored, as a terminal would. ``dask-local`` printed 50-80 lines
of worker tracebacks (KeyboardInterrupt, CommClosedError) before the resume line; ``inprocess``
is covered in-process by ``test_cli_usability``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Signals to child processes: in the default run, skipped by ``-m 'not slow'``.
pytestmark = pytest.mark.slow

SWEEP = """
base = "paper-sim-autonomous"
seed = 1
[axes]
policy.name = ["greedy", "hgad"]
seed = { range = [0, 200] }
"""


@contextlib.contextmanager
def _group(args: list[str], cwd: Path) -> Iterator[subprocess.Popen[str]]:
    """A process in a session of its own; the whole group is killed however the test ends."""
    process = subprocess.Popen(
        args,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        yield process
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.communicate()


@pytest.mark.parametrize("executor", ["process", "dask-local"])
def test_ctrl_c_prints_one_line_and_the_resume_command(tmp_path: Path, executor: str) -> None:
    if executor.startswith("dask"):
        pytest.importorskip("distributed", reason="the dask executors need skymule[dask]")
    (tmp_path / "sweep.toml").write_text(SWEEP)
    out = tmp_path / "out"
    args = ["sweep", "sweep.toml", "--out", str(out), "--executor", executor, "--workers", "2"]
    # SIGINT as a terminal gives it (a test runner's worker may have it ignored, and an
    # ignored signal is inherited)
    start = "import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
    command = [sys.executable, "-c", start + "from skymule.cli import main; main()", *args]
    with _group([*command, "--chunk-size", "20"], tmp_path) as sweep:
        deadline = time.monotonic() + 240  # a loaded machine starts a cluster slowly
        while not list((out / "results").glob("part-*.parquet")):
            assert sweep.poll() is None and time.monotonic() < deadline, "no part was stored"
            time.sleep(0.1)
        os.killpg(sweep.pid, signal.SIGINT)
        _, stderr = sweep.communicate(timeout=120)
    assert sweep.returncode == 130
    [line] = stderr.strip().splitlines()
    assert line.startswith("skymule: interrupted; kept ")
    assert f"Resume with: skymule sweep sweep.toml --out {out} --executor {executor}" in line
