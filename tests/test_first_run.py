"""A first sweep without surprises: the executor is chosen by the work (a small sweep does
not pay for starting worker processes), and the one-off numba compile is announced."""

from __future__ import annotations

import io
import sys
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from conftest import SMALL_SWEEP, run_cli, write
from skymule.experiments.sweep import load_sweep
from skymule.experiments.workload import choose_executor, estimated_seconds

ROOT = Path(__file__).resolve().parents[1]


def _sweep(tmp_path: Path, policies: str, seeds: int, base: str = "paper-sim-fixed") -> Path:
    text = f'base = "{base}"\nseed = 1\n[axes]\npolicy.name = [{policies}]\n'
    return write(tmp_path, text + f"seed = {{ range = [0, {seeds}] }}\n", f"s{seeds}.toml")


def test_the_readme_sweep_runs_in_process_and_a_large_one_in_a_pool(tmp_path: Path) -> None:
    readme = load_sweep(ROOT / "examples" / "sweep-paper.toml")  # 1,000 missions
    assert len(readme) == 1000 and choose_executor(readme, workers=2) == "inprocess"
    large = load_sweep(_sweep(tmp_path, '"greedy", "hgad"', 50_000))  # 100,000 missions
    assert choose_executor(large, workers=2) == "process"
    assert estimated_seconds(large) == pytest.approx(100 * estimated_seconds(readme))
    assert choose_executor(large, workers=1) == "inprocess"  # one core: nothing to share


def test_slow_policies_and_long_missions_count_for_more(tmp_path: Path) -> None:
    fast = load_sweep(_sweep(tmp_path, '"greedy", "hgad"', 50))
    planner = load_sweep(_sweep(tmp_path, '"planner"', 100, "paper-sim-autonomous"))
    assert choose_executor(fast, workers=2) == "inprocess"
    assert choose_executor(planner, workers=2) == "process"  # 100 missions one at a time
    mission = fast.base.mission.model_copy(update={"duration_s": 5000.0})
    ten_times = replace(fast, base=fast.base.model_copy(update={"mission": mission}))
    assert estimated_seconds(ten_times) == pytest.approx(10 * estimated_seconds(fast))


def test_the_sweep_command_says_which_executor_it_chose(tmp_path: Path) -> None:
    sweep = write(tmp_path, SMALL_SWEEP.format(n=2))
    done = run_cli("sweep", sweep, "--out", tmp_path / "out", "--quiet", check=True)
    assert "(inprocess, chosen by estimated work)" in done.stdout
    bad = run_cli("sweep", sweep, "--out", tmp_path / "bad", "--executor", "proces")
    assert bad.returncode == 2
    assert "allowed: auto, inprocess, process" in bad.stderr
    assert "did you mean 'process'?" in bad.stderr
    assert not (tmp_path / "bad").exists()


def test_a_long_first_compile_is_announced_once_even_on_a_pipe(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """numba's compile event (a cache miss) of a skymule kernel that lasts longer than
    COMPILE_NOTE_AFTER_S prints one line on stderr, piped or not, once; a quick one and
    other packages' kernels say nothing."""
    numba = pytest.importorskip("numba", reason="the compiled engine is the `fast` extra")
    from skymule.sim import compiled
    from skymule.sim.compiled import FIRST_COMPILE_NOTE, note_first_compile

    note_first_compile()  # what compiled.jit does before it compiles anything
    # as in a process that has not said it yet (an earlier test's compile may have)
    monkeypatch.setattr(compiled, "_COMPILE_NOTE_SAID", threading.Event())

    def kernel(x: float) -> float:
        return x + 1.0

    kernel.__module__ = "skymule.sim.kernels"  # as if it were one of ours
    other = numba.njit(cache=False)(lambda x: x * 2.0)
    piped = io.StringIO()  # not a terminal
    monkeypatch.setattr(sys, "stderr", piped)
    monkeypatch.setattr(compiled, "COMPILE_NOTE_AFTER_S", 60.0)
    assert numba.njit(cache=False)(kernel)(1.0) == 2.0
    assert piped.getvalue() == ""  # a quick compile: nothing to explain

    monkeypatch.setattr(compiled, "COMPILE_NOTE_AFTER_S", 0.0)  # every compile is "long"
    assert other(1.0) == 2.0  # not ours: says nothing
    assert piped.getvalue() == ""
    first = numba.njit(cache=False)(kernel)
    assert first(1.0) == 2.0 and first(1) == 2.0  # two compiles (two signatures)
    assert piped.getvalue().splitlines() == [FIRST_COMPILE_NOTE]


def _report_launched(queue: Any) -> None:
    from skymule.sim.compiled import _launched_here

    queue.put(_launched_here())


def test_only_the_process_the_user_started_announces_a_compile_on_a_pipe() -> None:
    """A pool's worker that compiles says nothing on a piped stderr (N workers, one log)."""
    import multiprocessing

    from skymule.sim.compiled import _launched_here

    assert _launched_here()
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    worker = context.Process(target=_report_launched, args=(queue,))
    worker.start()
    try:
        assert queue.get(timeout=120) is False
    finally:
        worker.join(timeout=60)
