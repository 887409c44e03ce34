"""docs/aadm.md's file-protocol recipe, run as written: three processes (controller, comm
stand-in, file agent), with free ports instead of 8005/8006 and the clock run 10x faster
(``--speed 10`` on the controller, ``--poll-s 0.1`` on both UAV-side processes: the same
1 poll per testbed second as the defaults)."""

from __future__ import annotations

import re
import signal
import subprocess
from pathlib import Path

from conftest import SKYMULE, cli_env, start_cli, two_towers
from skymule.aadm import files

SCENARIO = two_towers("aadm-recipe", 60, (15, 10))


def _start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    return start_cli("aadm", *args, cwd=cwd)


def _stop(process: subprocess.Popen[str]) -> tuple[str, str]:
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
    try:
        return process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def test_the_docs_file_recipe_runs_as_written(tmp_path: Path) -> None:
    (tmp_path / "recipe.toml").write_text(SCENARIO)
    controller = _start(
        [
            *("controller", "recipe.toml", "--exit-on-disarm"),
            *("--port", "0", "--telemetry-port", "0", "--speed", "10"),
        ],
        tmp_path,
    )
    comm = agent = None
    try:
        assert controller.stdout is not None
        lines = [controller.stdout.readline() for _ in range(2)]
        ports = [re.search(r":(\d+) \(", line) for line in lines]
        assert all(ports), lines
        poll_port, telemetry_port = (m.group(1) for m in ports if m)
        comm = _start(
            ["comm", "--files", "agent_dir", "--port", poll_port, "--poll-s", "0.1"], tmp_path
        )
        agent = subprocess.run(
            [
                *SKYMULE,
                "aadm",
                *("agent", "recipe.toml", "--policy", "hgad", "--files", "agent_dir"),
                *("--port", poll_port, "--telemetry-port", telemetry_port, "--poll-s", "0.1"),
            ],
            cwd=tmp_path,
            env=cli_env(),
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert agent.returncode == 0, agent.stderr
        out, err = controller.communicate(timeout=30)  # --exit-on-disarm: the UAV landed
    finally:
        if comm is not None:
            _stop(comm)
        _stop(controller)
    assert controller.returncode == 0, err
    landed = re.search(r"landed (\S+) m from the launch point", agent.stdout)
    assert landed and float(landed.group(1)) <= 0.5, agent.stdout
    score = re.search(r"controller: T1: (\S+) seconds, S1:\S+, S2:100\.00", agent.stdout)
    assert score, agent.stdout
    assert "downloaded 25.0 Mbit" in out, out
    assert "(INCOMPLETE" not in out
    assert files.read_done_file(tmp_path / "agent_dir" / "tn.txt")
