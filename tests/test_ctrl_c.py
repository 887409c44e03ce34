"""Ctrl-C or SIGTERM on a sweep is one line and the resume command, on every executor
(issues 24 and 32).

A terminal's Ctrl-C goes to the whole foreground process group: the sweep process and every
worker it started. Each test starts a real sweep in a session of its own and signals that
group once the first part is stored, as a terminal would. ``dask-local`` printed 50-80 lines
of worker tracebacks (KeyboardInterrupt, CommClosedError) before the resume line, then, in
about 1 run in 6, a tornado ``Exception in callback`` or a worker's failed heartbeat; a
second Ctrl-C during the close broke the close off; SIGTERM ended with status -15, no resume
line and leaked semaphores. ``inprocess`` is covered in-process by ``test_cli_usability``.
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
def _group(
    args: list[str], cwd: Path, env: dict[str, str] | None = None
) -> Iterator[subprocess.Popen[str]]:
    """A process in a session of its own; the whole group is killed however the test ends."""
    process = subprocess.Popen(
        args,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env=env,
    )
    try:
        yield process
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.communicate()


def _signal_group(pid: int, how: str) -> None:
    """``ctrl-c``: one SIGINT to the group, as a terminal sends it; ``ctrl-c-twice``: a second
    one 0.3 s later (an impatient user); ``sigterm``: ``kill`` or a batch system's limit."""
    if how == "sigterm":
        os.killpg(pid, signal.SIGTERM)
        return
    os.killpg(pid, signal.SIGINT)
    if how == "ctrl-c-twice":
        time.sleep(0.3)
        os.killpg(pid, signal.SIGINT)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("executor", "how"),
    [
        ("process", "ctrl-c"),
        # a fresh clone's first sweep: the workers compile (numba's LLVM callbacks printed
        # "Exception ignored ... KeyboardInterrupt" when a worker took the Ctrl-C itself)
        ("process", "ctrl-c-compiling"),
        ("process", "sigterm"),
        ("dask-local", "ctrl-c"),
        ("dask-local", "ctrl-c-twice"),
        ("dask-local", "sigterm"),
    ],
)
def test_ctrl_c_prints_one_line_and_the_resume_command(
    tmp_path: Path, executor: str, how: str
) -> None:
    if executor.startswith("dask"):
        pytest.importorskip("distributed", reason="the dask executors need skymule[dask]")
    (tmp_path / "sweep.toml").write_text(SWEEP)
    out = tmp_path / "out"
    args = ["sweep", "sweep.toml", "--out", str(out), "--executor", executor, "--workers", "2"]
    # SIGINT as a terminal gives it (a test runner's worker may have it ignored, and an
    # ignored signal is inherited)
    start = "import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
    command = [sys.executable, "-c", start + "from skymule.cli import main; main()", *args]
    env = None
    if how.endswith("-compiling"):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
        how = how.removesuffix("-compiling")
    with _group([*command, "--chunk-size", "20"], tmp_path, env) as sweep:
        deadline = time.monotonic() + 240  # a loaded machine starts a cluster slowly
        while not list((out / "results").glob("part-*.parquet")):
            if sweep.poll() is not None:
                pytest.fail(f"the sweep ended before a part was stored: {sweep.communicate()}")
            assert time.monotonic() < deadline, "no part was stored"
            time.sleep(0.1)
        _signal_group(sweep.pid, how)
        _, stderr = sweep.communicate(timeout=120)
    assert sweep.returncode == (143 if how == "sigterm" else 130), stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    [line] = lines
    assert line.startswith("skymule: interrupted; kept ")
    assert f"Resume with: skymule sweep sweep.toml --out {out} --executor {executor}" in line
