"""``skymule aadm ...``: the controller emulator, the agent, a comm stand-in, a loopback flight.

Mounted in :mod:`skymule.cli` as ``app.add_typer(aadm_app, name="aadm")``; user mistakes
raise :class:`~skymule.errors.SkymuleError` (one line, exit 2 through ``skymule.cli.main``).
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from skymule.aadm.rules import (
    AADM_POLL_S,
    AADM_WINDOW_S,
    FIRST_TOWER_PORT,
    TELEMETRY_PORT,
    TOWERS_TELEMETRY_PORT,
    UAV_PORT,
)
from skymule.errors import SkymuleError
from skymule.trust import TRUST_HELP, trust_option

#: Seconds a running session may go without a poll before the controller calls it lost.
AGENT_TIMEOUT_S = 30.0
#: Failed polls the agent tries again (:data:`skymule.aadm.agent.POLL_RETRIES`).
POLL_RETRIES = 12

if TYPE_CHECKING:
    from skymule.aadm.agent import AadmAgent
    from skymule.aadm.vehicle import Vehicle

aadm_app = typer.Typer(
    no_args_is_help=True,
    help=(
        "AADM challenge: emulated controller and towers, policy agent, comm stand-in, "
        "loopback flight."
    ),
)

ScenarioArg = Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")]
HostOpt = Annotated[str, typer.Option("--host", help="Controller address.")]
TrustOption = Annotated[
    list[Path] | None, typer.Option("--trust-model", help=TRUST_HELP, callback=trust_option)
]


def _say(text: str) -> None:
    print(text, flush=True)


@aadm_app.command()
def controller(
    scenario: ScenarioArg,
    host: HostOpt = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="UAV poll port (0: any free port).")] = (
        UAV_PORT
    ),
    telemetry_port: Annotated[
        int, typer.Option("--telemetry-port", help="Telemetry port (0: any free port).")
    ] = TELEMETRY_PORT,
    poll_s: Annotated[
        float, typer.Option("--poll-s", help="Seconds each poll stands for (AADM: 1).")
    ] = AADM_POLL_S,
    window_s: Annotated[float, typer.Option("--window-s", help="Download window [s].")] = (
        AADM_WINDOW_S
    ),
    log: Annotated[Path | None, typer.Option("--log", help="Download log to write.")] = None,
    volumes: Annotated[
        Path | None, typer.Option("--volumes", help="AADM volume file (default: buffers).")
    ] = None,
    exit_on_disarm: Annotated[
        bool,
        typer.Option("--exit-on-disarm", help="Exit once the UAV reports itself disarmed."),
    ] = False,
    agent_timeout: Annotated[
        float,
        typer.Option("--agent-timeout", help="Seconds without a poll before the flight is lost."),
    ] = AGENT_TIMEOUT_S,
    clock: Annotated[
        str,
        typer.Option(
            "--clock",
            help="wall: t1 and the window on the wall clock, as the testbed (polls at most "
            "once a second); poll: one poll = --poll-s seconds (accelerated runs).",
        ),
    ] = "wall",
    dialect: Annotated[
        str,
        typer.Option(
            "--dialect",
            help="testbed: answer as the real controller, warn about what fails there; "
            "lenient: strip whitespace, refuse requests other than snr_dd.",
        ),
    ] = "testbed",
    speed: Annotated[
        float,
        typer.Option("--speed", help="Run the wall clock this many times faster (tests)."),
    ] = 1.0,
) -> None:
    """Serve the AADM controller's bytes with SNR from the scenario's signal source."""
    from skymule.aadm.controller import ControllerCore, serve_controller
    from skymule.aadm.files import read_volume_file
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    if poll_s <= 0 or window_s <= 0 or agent_timeout <= 0 or speed <= 0:
        raise SkymuleError(
            f"--poll-s {poll_s:g} / --window-s {window_s:g} / --agent-timeout "
            f"{agent_timeout:g} / --speed {speed:g}: each must be > 0"
        )
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s", stream=sys.stderr)
    mission = build_mission(load_scenario(scenario))
    shared = None if volumes is None else read_volume_file(volumes, mission.n_sensors)
    core = ControllerCore(
        mission,
        shared,
        poll_s=poll_s,
        window_s=window_s,
        log_path=log,
        clock=clock,
        dialect=dialect,
        speed=speed,
    )
    lost: float | None = None
    with _until_stopped() as stopped, serve_controller(core, host, port, telemetry_port) as server:
        _say(f"listening on {server.host}:{server.port} (UAV polls)")
        _say(f"listening on {server.host}:{server.telemetry_port} (telemetry)")
        _say(f"clock: {clock}, dialect: {dialect}")
        while not stopped.wait(0.1):
            if exit_on_disarm and core.disarmed:
                break
            idle = core.idle_s()
            if idle is not None and idle > agent_timeout:
                lost = idle
                core.stop("UAV lost")
                break
    parts = core.score()
    summary = (
        f"downloaded {core.received_mbit().sum():.1f} Mbit in {core.served_polls} polls; "
        f"t1 {parts['aadm_t1_s']:g} s; score {parts['aadm_score']:.1f}"
    )
    if lost is not None:
        _say(f"no poll from the UAV for {lost:.0f} s: the flight was cut off")
        _say(f"{summary} (INCOMPLETE: the UAV was lost)")
        raise typer.Exit(1)
    _say(summary)


@contextmanager
def _until_stopped() -> Iterator[threading.Event]:
    """An event set by SIGTERM or Ctrl-C, so that either ends the session like the other."""
    stopped = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stopped.set())
    try:
        yield stopped
    except KeyboardInterrupt:
        stopped.set()
    finally:
        signal.signal(signal.SIGTERM, previous)


def _make_vehicle(kind: str, agent: AadmAgent, address: str) -> Vehicle:
    from skymule.aadm.loopback import kinematic_vehicle
    from skymule.aadm.vehicle import MavsdkVehicle

    if kind == "kinematic":
        return kinematic_vehicle(agent)
    if kind == "mavsdk":
        return MavsdkVehicle(address, agent.mission.frame)
    raise SkymuleError(f"--vehicle {kind!r} is not allowed; allowed: kinematic, mavsdk")


@aadm_app.command()
def agent(
    scenario: ScenarioArg,
    policy: Annotated[str, typer.Option("--policy", help="Policy name or module:Class.")],
    host: HostOpt = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="Controller UAV poll port.")] = UAV_PORT,
    telemetry_port: Annotated[
        int, typer.Option("--telemetry-port", help="Where the vehicle's telemetry goes.")
    ] = TELEMETRY_PORT,
    files_dir: Annotated[
        Path | None,
        typer.Option("--files", help="Use the agent<->comm files in DIR instead of TCP."),
    ] = None,
    vehicle: Annotated[str, typer.Option("--vehicle", help="kinematic or mavsdk.")] = "kinematic",
    mavsdk_address: Annotated[
        str, typer.Option("--mavsdk-address", help="MAVSDK system address.")
    ] = "udpin://0.0.0.0:14540",
    poll_s: Annotated[
        float | None,
        typer.Option(
            "--poll-s",
            help="Wall seconds between polls (default: 1 with --files or mavsdk, as the comm "
            "process; else 0: as fast as the controller answers; each is a 1-s slot).",
        ),
    ] = None,
    send_telemetry: Annotated[
        bool,
        typer.Option(
            "--telemetry/--no-telemetry",
            help="With --files: send the vehicle's telemetry to --telemetry-port each poll.",
        ),
    ] = True,
    altitude: Annotated[
        float | None,
        typer.Option("--altitude", help="Take-off altitude [m] (default: the scenario's)."),
    ] = None,
    retries: Annotated[
        int, typer.Option("--retries", help="Failed polls tried again before returning home.")
    ] = POLL_RETRIES,
    trust_model: TrustOption = None,
) -> None:
    """Run a skymule policy as the UAV-side agent (the challenge's TCP bytes, or its files)."""
    from skymule.aadm.agent import AadmAgent, fly_tcp, run_file_agent
    from skymule.aadm.loopback import takeoff_altitude_m
    from skymule.policies import make_policy
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    if poll_s is not None and poll_s < 0:
        raise SkymuleError(f"--poll-s {poll_s:g}: must be >= 0")
    if retries < 0:
        raise SkymuleError(f"--retries {retries}: must be >= 0")
    spec = load_scenario(scenario, policies=[policy]).with_policy(policy)
    mission = build_mission(spec)
    the_agent = AadmAgent(mission, make_policy(spec.policy))
    craft = _make_vehicle(vehicle, the_agent, mavsdk_address)
    # the file protocol: the comm process polls once a second; a faster agent would fly its
    # mission on stale files (the controller then cut it off)
    fast = vehicle == "kinematic" and files_dir is None
    pace = poll_s if poll_s is not None else (0.0 if fast else 1.0)
    climb = takeoff_altitude_m(spec, mission) if altitude is None else altitude
    try:
        if files_dir is not None:
            if not files_dir.is_dir():
                raise SkymuleError(f"--files {files_dir}: no such folder")
            record = run_file_agent(
                the_agent,
                craft,
                files_dir,
                pace_s=pace,
                altitude_m=climb,
                telemetry=(host, telemetry_port) if send_telemetry else None,
            )
            if record.score_line:
                _say(f"controller: {record.score_line}")
        else:
            record = fly_tcp(
                the_agent,
                craft,
                host,
                port,
                telemetry_port,
                pace_s=pace,
                altitude_m=climb,
                retries=retries,
            )
            if record.score_line:
                _say(f"controller: {record.score_line}")
    finally:
        close = getattr(craft, "close", None)
        if callable(close):
            close()
    _say(
        f"{record.polls} polls; landed {record.end_distance_to(the_agent.home_xy()):.1f} m "
        "from the launch point"
    )


@aadm_app.command()
def comm(
    files_dir: Annotated[Path, typer.Option("--files", help="Agent working folder.")],
    towers: Annotated[int, typer.Option("--towers", help="Number of towers.")] = 4,
    port: Annotated[int, typer.Option("--port", help="Controller UAV poll port.")] = UAV_PORT,
    host: HostOpt = "127.0.0.1",
    poll_s: Annotated[float, typer.Option("--poll-s", help="Seconds between polls.")] = 1.0,
    max_polls: Annotated[int, typer.Option("--max-polls", help="Stop after N polls.")] = 100_000,
) -> None:
    """Stand in for the challenge's comm process: bare snr_dd polls <-> ss/dv/dd/tn/bc files."""
    from skymule.aadm.comm import run_comm

    if towers < 1:
        raise SkymuleError(f"--towers {towers}: must be >= 1")
    try:
        polls = run_comm(files_dir, host, port, towers, poll_s=poll_s, max_polls=max_polls)
    except ConnectionRefusedError:
        raise SkymuleError(f"--port {port}: no controller listening on {host}") from None
    _say(f"{polls} polls")


@aadm_app.command()
def towers(
    scenario: ScenarioArg,
    host: HostOpt = "127.0.0.1",
    first_port: Annotated[
        int,
        typer.Option("--first-port", help="Tower 1's port; tower k on the k-th after (0: any)."),
    ] = FIRST_TOWER_PORT,
    telemetry_port: Annotated[
        int, typer.Option("--telemetry-port", help="Telemetry port (0: any free port).")
    ] = TOWERS_TELEMETRY_PORT,
    forward: Annotated[
        str | None,
        typer.Option("--forward", help="Pass telemetry on to the controller's HOST:PORT."),
    ] = f"127.0.0.1:{TELEMETRY_PORT}",
    write_env: Annotated[
        Path | None,
        typer.Option("--write-env", help="Write an experiment-environment file here."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Let --write-env replace an existing file.")
    ] = False,
) -> None:
    """Answer as the AADM towers (00,<snr>,<rate>) so the challenge's own controller runs."""
    from skymule.aadm.towers import TowerRadio, experiment_env, serve_towers
    from skymule.io import atomic
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    target = None if not forward else _host_port(forward)
    mission = build_mission(load_scenario(scenario))
    env_text = None if write_env is None else experiment_env(mission.n_sensors, host)
    if write_env is not None and write_env.exists() and not force:
        try:
            same = write_env.read_text(encoding="utf-8") == env_text
        except (OSError, UnicodeDecodeError):
            same = False
        if not same:
            raise SkymuleError(
                f"--write-env {write_env}: the file exists (on the testbed it names the real "
                "nodes); pass --force to replace it, or give another path"
            )
    n_towers = mission.n_sensors
    ports = [0 if first_port == 0 else first_port + k for k in range(n_towers)]
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s", stream=sys.stderr)
    with (
        _until_stopped() as stopped,
        serve_towers(TowerRadio(mission), host, ports, telemetry_port, target) as served,
    ):
        for name, port in zip(mission.sensor_names, served.ports, strict=True):
            _say(f"listening on {host}:{port} (tower {name})")
        _say(f"listening on {host}:{served.telemetry_port} (telemetry)")
        if write_env is not None and env_text is not None:
            atomic.write_text(write_env, env_text)
            _say(f"wrote {write_env}")
        stopped.wait()


@aadm_app.command()
def vehicle(
    mavlink: Annotated[
        str,
        typer.Option(
            "--mavlink",
            help="Where the MAVSDK script listens: udp://[HOST]:PORT (as PX4 SITL's 14540).",
        ),
    ] = "udp://:14540",
    scenario: Annotated[
        str | None,
        typer.Option("--scenario", help="Scenario whose origin is home (default: AADM launch)."),
    ] = None,
    speed_mps: Annotated[float, typer.Option("--speed-mps", help="Cruise speed [m/s].")] = 10.0,
    time_scale: Annotated[
        float, typer.Option("--time-scale", help="Run the vehicle's clock this much faster.")
    ] = 1.0,
) -> None:
    """A kinematic MAVLink test vehicle (NOT PX4 or ArduPilot) for MAVSDK scripts and tests."""
    from skymule.aadm.mavlink_vehicle import MavlinkTestVehicle, parse_mavlink_address
    from skymule.geo import LocalFrame

    host, port = parse_mavlink_address(mavlink)
    if speed_mps <= 0 or time_scale <= 0:
        raise SkymuleError(
            f"--speed-mps {speed_mps:g} / --time-scale {time_scale:g}: each must be > 0"
        )
    if scenario is None:
        frame = LocalFrame(35.7274824, -78.6962749)  # the AADM launch point
    else:
        from skymule.scenario import load_scenario
        from skymule.world import build_mission

        frame = build_mission(load_scenario(scenario)).frame
    craft = MavlinkTestVehicle(frame, port, host=host, speed_mps=speed_mps, time_scale=time_scale)
    try:
        with _until_stopped() as stopped:
            _say(
                f"MAVLink test vehicle (kinematic, not PX4 or ArduPilot) sending to {host}:{port}"
                f" from {frame.origin_lat_deg:.7f}, {frame.origin_lon_deg:.7f}; Ctrl-C to stop"
            )
            stopped.wait()
    finally:
        craft.close()


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise SkymuleError(f"--forward {text!r}: expected HOST:PORT, like 127.0.0.1:8006")
    return host, int(port)


@aadm_app.command()
def fly(
    scenario: ScenarioArg,
    policy: Annotated[
        str | None, typer.Option("--policy", help="Policy (default: the scenario's).")
    ] = None,
    poll_s: Annotated[
        float, typer.Option("--poll-s", help="Wall seconds between polls (0: flat out).")
    ] = 0.01,
    log: Annotated[Path | None, typer.Option("--log", help="Download log to write.")] = None,
    trust_model: TrustOption = None,
) -> None:
    """Offline AADM flight on loopback (controller + agent + kinematic vehicle) vs skymule run."""
    from skymule.aadm.loopback import first_difference, fly_loopback
    from skymule.aadm.score import describe_cadence
    from skymule.scenario import load_scenario

    if poll_s < 0:
        raise SkymuleError(f"--poll-s {poll_s:g}: must be >= 0")
    spec = load_scenario(scenario, policies=None if policy is None else [policy])
    if policy is None:
        from skymule.cli.missions import announce_imports

        announce_imports([spec.policy.name], scenario)
    result = fly_loopback(spec, policy, poll_s=poll_s, log_path=log)
    _say(
        f"{result.policy}: {result.climb_slots} s of climbing, then {result.polls} polls; "
        f"volumes shared at poll {result.share_poll}"
    )
    _say(f"{'':14}{'flight':>12}{'skymule run':>14}{'difference':>12}")
    for index, name in enumerate(result.sensor_names):
        flight, engine = result.flight_mbit[index], result.engine_mbit[index]
        _say(f"{name + ' [Mbit]':14}{flight:12.1f}{engine:14.1f}{flight - engine:12.1f}")
    total_f, total_e = result.flight_mbit.sum(), result.engine_mbit.sum()
    _say(f"{'total [Mbit]':14}{total_f:12.1f}{total_e:14.1f}{total_f - total_e:12.1f}")
    for key, label in (("aadm_t1_s", "t1 [s]"), ("aadm_score", "AADM score")):
        flight_v, engine_v = float(result.flight_score[key]), float(result.engine_score[key])
        _say(f"{label:14}{flight_v:12.1f}{engine_v:14.1f}{flight_v - engine_v:12.1f}")
    flight_p, engine_p = result.flight_prediction, result.engine_prediction
    cadence = describe_cadence(
        float(flight_p["aadm_poll_interval_s"]), float(flight_p["aadm_poll_jitter_s"])
    )
    _say(f"on the testbed's clock ({cadence}, [aadm] poll_interval_s):")
    for key, label in (("aadm_t1_s", "  t1 [s]"), ("aadm_score", "  AADM score")):
        flight_v, engine_v = float(flight_p[key]), float(engine_p[key])
        _say(f"{label:14}{flight_v:12.1f}{engine_v:14.1f}{flight_v - engine_v:12.1f}")
    if abs(result.engine_mission_mbit - total_e) > 1e-6:
        _say(
            f"(skymule run downloads {result.engine_mission_mbit:.1f} Mbit over its whole "
            "mission; the columns count the controller's window)"
        )
    parted = first_difference(result)
    if parted is not None:
        _say(parted)
    _say(f"landed {result.landed_distance_m:.1f} m from the launch point")
    if log is not None:
        _say(f"wrote {log}")
