"""The agent: any policy as the UAV side, over TCP (loopback flight) and over the files."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from conftest import SKYMULE, cli_env, preset_mission, run_cli, start_cli, two_towers
from skymule.aadm import files
from skymule.aadm.agent import AadmAgent
from skymule.aadm.comm import run_comm
from skymule.aadm.controller import ControllerCore, serve_controller
from skymule.aadm.loopback import fly_loopback
from skymule.policies import Greedy
from skymule.scenario import load_scenario
from skymule.world import build_mission


@pytest.fixture
def small(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(two_towers("aadm-small", 60, (60, 40)))
    return path


@pytest.fixture(autouse=True)
def _no_server_left_behind() -> Iterator[None]:
    yield
    assert not [t for t in threading.enumerate() if t.name == "aadm-controller"]


@pytest.mark.parametrize("preset", ["paper-sim-autonomous", "aadm-default"])
def test_loopback_flight_of_hgad_matches_skymule_run(preset: str) -> None:
    # autonomous (HGAD steers) and fixed path (aadm-default: 600 s, cut by the 500-s window)
    scenario = load_scenario(preset)
    result = fly_loopback(scenario, "hgad", poll_s=0.0)
    # the agent climbs to the mission altitude at 2.5 m/s before its first poll, which gets
    # the volumes: slot 0 is at home at altitude, as the engine's
    altitude = scenario.trajectory.altitude_m if preset == "paper-sim-autonomous" else 25.0
    assert result.climb_slots == int(np.ceil(altitude / 2.5)) and result.share_poll == 0
    # one poll = one slot, in lock step: the controller credits what the engine downloads
    np.testing.assert_allclose(result.flight_mbit, result.engine_mbit, atol=1e-6)
    assert result.flight_score == pytest.approx(result.engine_score)
    assert result.landed_distance_m <= 5.0  # the testbed's landing rule


README_PLUGIN = """
import numpy as np
from skymule import Action


class LargestBufferFirst:
    name = "largest-buffer-first"

    def __init__(self, params=None):
        self.margin_bit = 50e6

    def reset(self, context):
        self.current = None
        self.hover_points_m = context.hover_points_m

    def act(self, observation):
        left = observation.remaining_bit
        goto = None
        if self.hover_points_m is not None and left.any():
            goto = tuple(self.hover_points_m[int(np.argmax(left))])
        usable = (left > 0) & (observation.rate_bps > 0) & (observation.snr_db >= 0.0)
        if not usable.any():
            return Action(serve=None, goto_m=goto)
        best = int(np.argmax(np.where(usable, left, -1.0)))
        keep = self.current is not None and usable[self.current]
        if keep and left[best] - left[self.current] < self.margin_bit:
            best = self.current
        self.current = best
        return Action(serve=best, goto_m=goto)
"""


def test_a_plugin_that_flies_off_at_once_matches_skymule_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the README's LargestBufferFirst heads for a tower from slot 0: shared while still
    # climbing, it flew 2 slots behind the engine (+55.1 Mbit on LW3, -42.3 on LW4)
    from skymule.aadm.loopback import first_difference

    (tmp_path / "largest_buffer_t.py").write_text(README_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    name = "largest_buffer_t:LargestBufferFirst"
    result = fly_loopback(load_scenario("paper-sim-autonomous", policies=[name]), name)
    assert first_difference(result) is None
    n = len(result.flight_per_poll_bit)
    assert n == 500  # the window: a poll a second
    np.testing.assert_allclose(
        result.flight_per_poll_bit, result.engine_per_slot_bit[:n], atol=1e-6
    )
    np.testing.assert_allclose(result.flight_mbit, result.engine_mbit, atol=1e-6)
    assert result.flight_score == pytest.approx(result.engine_score)


def test_plain_step_entry_point() -> None:
    mission = preset_mission("paper-sim-autonomous")
    agent = AadmAgent(mission, Greedy())
    here = np.array([0.0, 0.0, 25.0])
    step = agent.step(np.array([20.0, -99.0, 5.0, np.nan]), np.zeros(4), here)
    assert step.tower_id == 1 and step.serve == 0  # Greedy: best SNR with data
    assert agent.slot == 1 and step.goto_m is not None
    # a tower whose data is all downloaded is skipped; NaN (unreadable) counts as 0 dB
    step = agent.step(np.array([20.0, -99.0, -5.0, np.nan]), np.array([500.0, 0, 0, 0]), here)
    assert step.tower_id == 4


AGENT_SCRIPT = """
import sys, time, os
folder = sys.argv[1]
def read(name):
    try:
        with open(os.path.join(folder, name)) as f:
            return dict((int(k), float(v)) for k, v in
                        (p.split(':') for p in f.read().strip().split(',') if p.strip()))
    except (OSError, ValueError):
        return None
deadline = time.time() + 20
while time.time() < deadline:
    try:
        if open(os.path.join(folder, 'tn.txt')).read().strip() == '-1':
            break
    except OSError:
        pass
    snr, vol, got = read('ss.txt'), read('dv.txt'), read('dd.txt')
    if snr:
        left = {k: vol[k] - (got or {}).get(k, 0) for k in vol} if vol else {k: 1 for k in snr}
        best = max((k for k in snr if left.get(k, 0) > 0), key=lambda k: snr[k], default=1)
        with open(os.path.join(folder, 'bc.tmp'), 'w') as f:
            f.write(str(best))
        os.replace(os.path.join(folder, 'bc.tmp'), os.path.join(folder, 'bc.txt'))
    time.sleep(0.02)
"""


def test_plain_script_agent_through_the_files(small: Path, tmp_path: Path) -> None:
    # the UAV hovers between LW1 and LW3 at 30 m; its position reaches the emulator in-process
    mission = build_mission(load_scenario(str(small)))
    where = np.array([150.0, -150.0, 30.0])
    core = ControllerCore(
        mission, log_path=tmp_path / "dl.csv", position_source=lambda: (where, True)
    )
    folder = tmp_path / "agent"
    folder.mkdir()
    script = tmp_path / "agent.py"
    script.write_text(AGENT_SCRIPT)
    stop = threading.Event()
    process = subprocess.Popen([sys.executable, str(script), str(folder)])
    try:
        with serve_controller(core) as server:
            comm = threading.Thread(
                target=run_comm,
                args=(folder, server.host, server.port, 2),
                kwargs={"poll_s": 0.03, "max_polls": 2000, "should_stop": stop.is_set},
            )
            comm.start()
            try:
                process.wait(timeout=25)
            finally:
                stop.set()
                comm.join(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert files.read_done_file(folder / "tn.txt")
    np.testing.assert_allclose(core.received_mbit(), [60.0, 40.0])
    # dd.txt holds the last download: reply (the comm script does not write it on
    # download_complete), so it may stop short of the volumes
    assert np.all(files.read_tower_file(folder / "dd.txt", 2) <= [60.0, 40.0])
    log = files.read_download_log(tmp_path / "dl.csv")
    assert log.cumulative_mbit[-1].tolist() == [60.0, 40.0]
    # the script's choices reached the controller: both towers served
    assert (np.diff(log.cumulative_mbit, axis=0, prepend=0) > 0).any(axis=0).all()


def test_skymule_agent_through_the_files(small: Path, tmp_path: Path) -> None:
    from skymule.aadm.agent import run_file_agent
    from skymule.aadm.loopback import kinematic_vehicle
    from skymule.policies import make_policy

    scenario = load_scenario(str(small))
    mission = build_mission(scenario)
    agent = AadmAgent(mission, make_policy(scenario.policy))
    vehicle = kinematic_vehicle(agent)
    core = ControllerCore(mission, position_source=lambda: (vehicle.position_m(), vehicle.armed))
    folder = tmp_path / "agent"
    stop = threading.Event()
    with serve_controller(core) as server:
        comm = threading.Thread(
            target=run_comm,
            args=(folder, server.host, server.port, 2),
            kwargs={"poll_s": 0.01, "max_polls": 3000, "should_stop": stop.is_set},
        )
        comm.start()
        try:
            record = run_file_agent(agent, vehicle, folder, pace_s=0.01, max_polls=3000)
        finally:
            stop.set()
            comm.join(timeout=10)
    assert core.received_mbit().sum() > 0
    assert record.end_distance_to(agent.home_xy()) <= 5.0 and not vehicle.armed


def test_controller_and_agent_as_separate_processes(small: Path, tmp_path: Path) -> None:
    controller = start_cli(
        "aadm",
        "controller",
        str(small),
        *("--port", "0", "--telemetry-port", "0", "--exit-on-disarm", "--log", "dl.csv"),
        *("--clock", "poll"),
        cwd=tmp_path,
    )
    try:
        assert controller.stdout is not None
        polls, telemetry = (controller.stdout.readline() for _ in range(2))
        match = re.match(r"listening on 127\.0\.0\.1:(\d+) \(UAV polls\)", polls)
        told = re.match(r"listening on 127\.0\.0\.1:(\d+) \(telemetry\)", telemetry)
        assert match and told, polls + telemetry
        done = subprocess.run(
            [
                *SKYMULE,
                "aadm",
                "agent",
                str(small),
                *("--policy", "hgad", "--port", match.group(1)),
                *("--telemetry-port", told.group(1)),
            ],
            cwd=tmp_path,
            env=cli_env(),
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 0, done.stderr
        assert "landed 0.0 m from the launch point" in done.stdout
        assert "controller: T1: " in done.stdout  # the score line the telemetry got back
        out, _ = controller.communicate(timeout=30)
    finally:
        if controller.poll() is None:
            controller.kill()
            controller.communicate()
    assert controller.returncode == 0
    assert "downloaded 100.0 Mbit" in out
    assert files.read_download_log(tmp_path / "dl.csv").cumulative_mbit[-1].tolist() == [60, 40]


FIXED_SMALL = two_towers(
    "aadm-small-fixed",
    80,
    (150, 120),
    trajectory="""[trajectory]
mode = "fixed"
speed_mps = 10.0
waypoints = [[0, 0, 30], [300, -300, 30], [0, -300, 30]]
""",
    policy="optimal-fixed",
)


@pytest.mark.parametrize(
    "policy", ["greedy", "hgad", "hgad-robust", "planner", "planner-robust", "optimal-fixed"]
)
def test_two_process_flight_equals_aadm_fly(policy: str, tmp_path: Path) -> None:
    # the agent command, with its defaults, against a controller in another thread: the same
    # polls, downloads and score as `aadm fly`. Before the agent took the scenario's altitude
    # it climbed to 25 m where `aadm fly` flew at 30 m, and the planner split at poll 19.
    path = tmp_path / "scenario.toml"
    text = FIXED_SMALL if policy == "optimal-fixed" else two_towers("aadm-small", 60, (300, 250))
    path.write_text(text)
    scenario = load_scenario(str(path))
    fly = fly_loopback(scenario, policy, poll_s=0.0)
    core = ControllerCore(build_mission(scenario))
    with serve_controller(core) as server:
        done = run_cli(
            *("aadm", "agent", str(path), "--policy", policy, "--port", str(server.port)),
            *("--telemetry-port", str(server.telemetry_port)),
        )
    assert done.returncode == 0, done.stderr
    fly_polls = fly.flight_per_poll_bit
    assert core.served_polls == len(fly_polls) > 0, done.stderr
    assert core.per_poll_bit == fly_polls, done.stderr  # poll by poll, to the bit
    assert core.score() == fly.flight_score


def _lost_after(core: ControllerCore, polls: int) -> None:
    """The controller stops answering (its connection closes) after ``polls`` polls."""
    answer = core.request

    def request(text: str, peer: str = "", round_start: float | None = None) -> tuple[str, object]:
        if core.served_polls >= polls:
            raise OSError("controller gone")
        return answer(text, peer, round_start)

    core.request = request  # type: ignore[method-assign,assignment]


def test_agent_retries_then_returns_to_launch(small: Path) -> None:
    from skymule.aadm.agent import fly_tcp
    from skymule.aadm.loopback import kinematic_vehicle
    from skymule.errors import SkymuleError
    from skymule.policies import make_policy

    scenario = load_scenario(str(small))
    mission = build_mission(scenario)
    agent = AadmAgent(mission, make_policy(scenario.policy))
    vehicle = kinematic_vehicle(agent)
    core = ControllerCore(mission)
    _lost_after(core, 8)
    with (
        serve_controller(core) as server,
        pytest.raises(SkymuleError, match=r"gave up after 2 retries, returned to launch"),
    ):
        fly_tcp(
            agent,
            vehicle,
            server.host,
            server.port,
            server.telemetry_port,
            pace_s=0.0,
            altitude_m=30.0,
            retries=2,
            retry_wait_s=0.0,
        )
    assert not vehicle.armed  # landed, not left hovering
    assert np.hypot(*vehicle.position_m()[:2]) <= 0.5 and core.served_polls == 8


def test_a_report_lost_after_the_controller_counted_the_poll(small: Path) -> None:
    # the controller credits poll 12, then the connection breaks before the report: the agent
    # tries again naming the same tower (its policy is not asked twice for one slot) and
    # takes the controller's totals from the next reply
    from skymule.aadm.agent import fly_tcp
    from skymule.aadm.loopback import kinematic_vehicle
    from skymule.policies import make_policy

    scenario = load_scenario(str(small))
    mission = build_mission(scenario)
    agent = AadmAgent(mission, make_policy(scenario.policy))
    core = ControllerCore(mission)
    account = core.choose

    def choose(text: str, snapshot: object) -> str:
        report = account(text, snapshot)  # type: ignore[arg-type]
        if core.served_polls == 12 and not lost:
            lost.append(report)
            raise OSError("link lost before the report")
        return report

    lost: list[str] = []
    core.choose = choose  # type: ignore[method-assign,assignment]
    with serve_controller(core) as server:
        address = (server.host, server.port, server.telemetry_port)
        record = fly_tcp(agent, kinematic_vehicle(agent), *address, pace_s=0.0, retry_wait_s=0.0)
    assert lost and record.share_poll is not None
    np.testing.assert_allclose(core.received_mbit(), [60.0, 40.0])
    # one decision a slot: the poll tried again did not ask the policy (or the pilot) again
    assert len(record.towers) == record.polls


def test_a_restarted_agent_rejoins_the_session(small: Path) -> None:
    from skymule.aadm.agent import fly_tcp
    from skymule.aadm.loopback import kinematic_vehicle
    from skymule.policies import make_policy

    scenario = load_scenario(str(small))
    mission = build_mission(scenario)
    core = ControllerCore(mission)
    with serve_controller(core) as server:
        address = (server.host, server.port, server.telemetry_port)
        first = AadmAgent(mission, make_policy(scenario.policy))
        fly_tcp(first, kinematic_vehicle(first), *address, pace_s=0.0, max_polls=15)  # killed
        before = core.served_polls
        second = AadmAgent(mission, make_policy(scenario.policy))
        record = fly_tcp(second, kinematic_vehicle(second), *address, pace_s=0.0)
    assert before > 0 and record.rejoined and record.share_poll is not None
    np.testing.assert_allclose(core.received_mbit(), [60.0, 40.0])  # finished by the second
    assert core.disarmed and record.score_line is not None


def test_cli_fly_prints_the_comparison(small: Path) -> None:
    done = run_cli("aadm", "fly", str(small), "--poll-s", "0")
    assert done.returncode == 0, done.stderr
    assert re.search(r"total \[Mbit\]\s+100\.0\s+100\.0\s+0\.0", done.stdout), done.stdout
    assert "AADM score" in done.stdout
    # the prediction at the testbed's cadence, saying which cadence it assumes
    assert "on the testbed's clock (1.031 s a poll, [aadm] poll_interval_s):" in done.stdout
    nominal = re.search(r"^t1 \[s\]\s+(\S+)", done.stdout, re.M)
    stretched = re.search(r"^  t1 \[s\]\s+(\S+)", done.stdout, re.M)
    assert nominal and stretched
    assert float(stretched.group(1)) == pytest.approx(1.031 * float(nominal.group(1)), abs=0.06)


@pytest.mark.parametrize(
    ("args", "problem"),
    [
        (["aadm", "fly", "no-such-preset"], "no-such-preset"),
        (["aadm", "fly", "{small}", "--policy", "nope"], "unknown policy 'nope'"),
        (["aadm", "controller", "{small}", "--volumes", "{vol}"], "3 volume line(s) for 2 towers"),
        (
            [
                *("aadm", "agent", "{small}", "--policy", "hgad", "--retries", "0"),
                *("--port", "{port}", "--telemetry-port", "{port}"),
            ],
            "no controller listening; gave up after 0 retries, returned to launch",
        ),
        (["aadm", "agent", "{small}", "--policy", "hgad", "--vehicle", "mavsdk"], "skymule[fly]"),
        (
            ["aadm", "agent", "{small}", "--policy", "hgad", "--vehicle", "boat"],
            "kinematic, mavsdk",
        ),
        (["aadm", "agent", "{small}", "--policy", "hgad", "--files", "nowhere"], "no such folder"),
        (["aadm", "controller", "{small}", "--clock", "sundial"], "allowed: wall, poll"),
        (["aadm", "controller", "{small}", "--dialect", "loose"], "allowed: testbed, lenient"),
        (["aadm", "controller", "{small}", "--speed", "0"], "--speed 0"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(
    small: Path, tmp_path: Path, args: list[str], problem: str
) -> None:
    if "mavsdk" in args and importlib.util.find_spec("mavsdk_grpc") is not None:
        pytest.skip("the fly extra is installed: tests/test_aadm_mavlink.py flies --vehicle mavsdk")
    (tmp_path / "vol.txt").write_text("10\n30\n90\n")
    with __import__("socket").socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    filled = [a.format(small=small, vol=tmp_path / "vol.txt", port=port) for a in args]
    done = run_cli(*filled, cwd=tmp_path)
    assert done.returncode == 2, done.stdout + done.stderr
    assert problem in done.stderr
    assert "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
