"""The local Dask executor opens no well-known port: it runs with 8787 held by someone else."""

from __future__ import annotations

import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from skymule.experiments.executors import open_executor
from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import load_sweep

#: Worker processes and Dask clusters: in the default run, skipped by ``-m 'not slow'``.
pytestmark = pytest.mark.slow

SWEEP = """
base = "paper-sim-fixed"
seed = 3
mode = "product"
[axes]
"mission.duration_s" = [120]
policy.name = ["greedy", "hgad"]
seed = { range = [0, 3] }
"""


@pytest.fixture
def port_8787_held() -> Iterator[socket.socket]:
    """Hold TCP port 8787 (Dask's dashboard default) for the test; skip if it cannot be bound."""
    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        try:
            holder.bind(("", 8787))
        except OSError as exc:
            pytest.skip(f"cannot bind port 8787 to hold it: {exc}")
        holder.listen(1)
        yield holder
    finally:
        holder.close()


def _square(x: int) -> int:
    return x * x


@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_dask_local_runs_while_port_8787_is_taken(
    port_8787_held: socket.socket, tmp_path: Path
) -> None:
    pytest.importorskip("distributed")
    with open_executor("dask-local", workers=1) as executor:
        assert [f.result() for f in [executor.submit(_square, i) for i in range(4)]] == [
            0,
            1,
            4,
            9,
        ]
    (tmp_path / "sweep.toml").write_text(SWEEP)
    spec = load_sweep(tmp_path / "sweep.toml")
    tables = {
        name: run_sweep(spec, tmp_path / name, executor=name, workers=1, progress=False).results
        for name in ("inprocess", "dask-local")
    }
    assert len(tables["inprocess"]) == 6
    pd.testing.assert_frame_equal(tables["inprocess"], tables["dask-local"])


WARMED = """
import sys
from skymule.experiments.executors import open_executor

def loaded(name):
    return name in sys.modules

if __name__ == "__main__":
    with open_executor("process", 1, warm=("skymule.sim.fixed",)) as pool:
        print(pool.submit(loaded, "skymule.sim.fixed").result(), flush=True)
    with open_executor("process", 1) as pool:
        print(pool.submit(loaded, "skymule.sim.fixed").result(), flush=True)
"""


def test_process_workers_import_the_warm_modules_as_they_start(tmp_path: Path) -> None:
    """A sweep's workers import its engine on start-up (while the plan is made), not on the
    first chunk; without ``warm`` they import nothing extra."""
    script = tmp_path / "warmed.py"
    script.write_text(WARMED)
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, check=True
    )
    assert done.stdout.split() == ["True", "False"]
