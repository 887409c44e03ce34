"""Shared test helpers: the ``skymule`` command line run inside the test process.

Starting a fresh interpreter per CLI call costs ~1.2 s (imports), so most CLI tests call
:func:`run_cli` instead: ``skymule.cli.main(args)`` with stdout/stderr redirected into
strings and ``SystemExit`` turned into a return code. The result has the attributes of
:class:`subprocess.CompletedProcess` (``returncode``, ``stdout``, ``stderr``), so a test
reads the same either way. Tests where the process boundary is the point (the installed
entry point, SIGKILL and resume, ``PYTHONPATH``) keep :func:`subprocess.run`.

Unlike a subprocess, an unexpected exception (a bug: what the real CLI prints as a
traceback and exit 1) propagates out of :func:`run_cli` and fails the test with its own
traceback; warnings follow pytest's ``filterwarnings = error``.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

if TYPE_CHECKING:
    from skymule.world import Mission


@functools.cache
def preset_mission(name: str) -> Mission:
    """The built Mission of preset ``name``, built once per test process. A Mission is
    immutable (read-only arrays, frozen fields), so every test may share it."""
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    return build_mission(load_scenario(name))


@pytest.fixture(scope="session")
def mission() -> Callable[[str], Mission]:
    """A factory: ``mission("paper-sim-autonomous")`` is that preset's built Mission."""
    return preset_mission


@pytest.fixture(scope="session")
def base_mission() -> Mission:
    """The paper's fixed-trajectory mission (``paper-sim-fixed``), shared."""
    return preset_mission("paper-sim-fixed")


@dataclass(frozen=True)
class CliResult:
    """One finished in-process ``skymule`` call (the fields of ``CompletedProcess``)."""

    args: list[str]
    returncode: int
    stdout: str
    stderr: str

    def check_returncode(self) -> None:
        """Raise ``CalledProcessError`` on a non-zero status, like ``CompletedProcess``."""
        if self.returncode:
            raise subprocess.CalledProcessError(
                self.returncode, ["skymule", *self.args], self.stdout, self.stderr
            )


@contextlib.contextmanager
def _environ(env: Mapping[str, str] | None) -> Iterator[None]:
    """Set ``env`` in ``os.environ`` for the duration, then put the old values back."""
    saved = {key: os.environ.get(key) for key in env or {}}
    os.environ.update(env or {})
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@contextlib.contextmanager
def _argv0(name: str) -> Iterator[None]:
    """Click names the program from ``sys.argv[0]`` in usage lines: say ``skymule``."""
    saved = sys.argv[:]
    sys.argv[:] = [name]
    try:
        yield
    finally:
        sys.argv[:] = saved


def run_cli(
    *args: str | Path,
    cwd: str | Path | None = None,
    env: Mapping[str, str] | None = None,
    check: bool = False,
) -> CliResult:
    """Run ``skymule <args>`` in this process and return its status and output.

    ``cwd`` runs it from that folder; ``env`` sets environment variables for the call (for
    an import path use ``monkeypatch.syspath_prepend`` in the test: ``PYTHONPATH`` is only
    read at interpreter start); ``check`` raises ``CalledProcessError`` on a non-zero
    status, as ``subprocess.run(check=True)`` does.
    """
    from rich.console import Console

    from skymule import cli
    from skymule.cli import output

    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    console = output.console
    code: int = 0
    with contextlib.ExitStack() as stack:
        if cwd is not None:
            stack.enter_context(contextlib.chdir(cwd))
        stack.enter_context(_environ(env))
        stack.enter_context(_argv0("skymule"))
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        if console.color_system is not None:
            # imported with a terminal on stdout (pytest -s): colour and width were fixed
            # then; build the console a piped `skymule` builds, as cli.py does
            output.console = Console(width=None if sys.stdout.isatty() else 120)
            stack.callback(setattr, output, "console", console)
        # rich resolves sys.stdout when it prints (no file= given): it writes to `out`
        assert output.console.file is out
        try:
            cli.main(argv)
        except SystemExit as exc:
            if exc.code is None or isinstance(exc.code, int):
                code = exc.code or 0
            else:  # sys.exit("message"): Python prints it and exits 1
                print(exc.code, file=sys.stderr)
                code = 1
    result = CliResult(argv, code, out.getvalue(), err.getvalue())
    if check:
        result.check_returncode()
    return result


SMALL_SWEEP = """
base = "paper-sim-fixed"
seed = 3
[axes]
policy.name = ["greedy", "hgad"]
seed = {{ range = [0, {n}] }}
"sensors[*].buffer_mbit" = {{ dist = "uniform", low = 50, high = 600 }}
"mission.duration_s" = [120, 200]
"""
"""A small sweep template (``.format(n=seeds)``): 2 policies x n seeds x 2 durations."""


SKYMULE = [sys.executable, "-c", "from skymule.cli import main; main()"]
"""``skymule`` as a process of its own, from this checkout's ``src`` (see :func:`cli_env`)."""


def cli_env() -> dict[str, str]:
    """This environment with ``PYTHONPATH`` at this checkout's ``src``: a process started
    from a test runs the code under test, installed or not."""
    return {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}


def start_cli(*args: str | Path, cwd: Path | None = None) -> subprocess.Popen[str]:
    """``skymule <args>`` started as a process (servers, Ctrl-C, several processes), its
    output piped as text; the caller stops it."""
    return subprocess.Popen(
        [*SKYMULE, *(str(a) for a in args)],
        cwd=cwd,
        env=cli_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def lawnmower(n: int) -> np.ndarray:
    """(n, 3) a lawnmower flight in time order [m]: six east-west legs from north to south,
    so the first 40% of the samples cover the north legs only."""
    per_leg = n // 6
    legs = [
        np.column_stack(
            [
                np.linspace(-300, 300, per_leg)[:: -1 if i % 2 else 1],
                np.full(per_leg, 250 - 100 * i),
                np.full(per_leg, 30),
            ]
        )
        for i in range(6)
    ]
    return np.vstack(legs)


def write(tmp_path: Path, text: str, name: str = "sweep.toml") -> Path:
    """``text`` saved as ``tmp_path / name``; the path."""
    path = tmp_path / name
    path.write_text(text)
    return path


def tiny_scenario(folder: Path, policy: str, params: str = "", name: str = "shared") -> Path:
    """``folder/<name>.toml``: one sensor, a 100-m fixed path, 20 s, under ``policy`` with the
    TOML lines ``params`` after its ``[policy]`` table (a file someone shared)."""
    path = folder / f"{name}.toml"
    path.write_text(
        f'name = "{name}"\n[mission]\nduration_s = 20\n'
        '[[sensors]]\nname = "A"\nx_m = 50.0\ny_m = 0.0\nbuffer_mbit = 5\n'
        "[trajectory]\nwaypoints = [[0, 0, 30], [100, 0, 30]]\n"
        f"[policy]\nname = {json.dumps(policy)}\n{params}"
    )
    return path


AUTONOMOUS_TRAJECTORY = """[trajectory]
mode = "autonomous"
altitude_m = 30.0
max_speed_mps = 10.0
"""


def two_towers(
    name: str,
    duration_s: float,
    buffers_mbit: tuple[float, float],
    trajectory: str = AUTONOMOUS_TRAJECTORY,
    policy: str = "hgad",
) -> str:
    """A small Lake Wheeler scenario (TOML) with two of its towers, LW1 and LW3: the AADM
    tests' mission, short enough to fly over loopback in seconds."""
    lw1, lw3 = buffers_mbit
    return f"""name = "{name}"
[mission]
duration_s = {duration_s}
[site]
origin = {{ lat = 35.7274824, lon = -78.6962749 }}
geofence = "lake-wheeler"
[[sensors]]
name = "LW1"
lat = 35.727451
lon = -78.695974
height_m = 10.0
buffer_mbit = {lw1}
[[sensors]]
name = "LW3"
lat = 35.724933
lon = -78.691912
height_m = -0.23
buffer_mbit = {lw3}
{trajectory}[policy]
name = "{policy}"
"""
