"""``skymule aadm ...``: the controller emulator, the agent, a comm stand-in, a loopback flight.

Mounted in :mod:`skymule.cli` as ``app.add_typer(aadm_app, name="aadm")``; user mistakes
raise :class:`~skymule.errors.SkymuleError` (one line, exit 2 through ``skymule.cli.main``).
"""

from __future__ import annotations

import logging
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from skymule.aadm.score import AADM_POLL_S, AADM_WINDOW_S
from skymule.errors import SkymuleError

if TYPE_CHECKING:
    from skymule.aadm.agent import AadmAgent
    from skymule.aadm.vehicle import Vehicle

aadm_app = typer.Typer(
    no_args_is_help=True,
    help="AADM challenge: emulated controller, policy agent, comm stand-in, loopback flight.",
)

ScenarioArg = Annotated[str, typer.Argument(help="Scenario TOML path or preset name.")]
HostOpt = Annotated[str, typer.Option("--host", help="Controller address.")]


def _say(text: str) -> None:
    print(text, flush=True)


@aadm_app.command()
def controller(
    scenario: ScenarioArg,
    host: HostOpt = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="TCP port (0: any free port).")] = 0,
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
) -> None:
    """Serve the AADM controller protocol with SNR from the scenario's signal source."""
    from skymule.aadm.controller import ControllerCore, serve_controller
    from skymule.aadm.files import read_volume_file
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    if poll_s <= 0 or window_s <= 0:
        raise SkymuleError(f"--poll-s {poll_s:g} / --window-s {window_s:g}: both must be > 0")
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s", stream=sys.stderr)
    mission = build_mission(load_scenario(scenario))
    shared = None if volumes is None else read_volume_file(volumes, mission.n_sensors)
    core = ControllerCore(mission, shared, poll_s=poll_s, window_s=window_s, log_path=log)
    stopped = threading.Event()
    try:
        with serve_controller(core, host, port) as server:
            _say(f"listening on {server.host}:{server.port}")
            while not stopped.wait(0.2):
                if exit_on_disarm and core.disarmed:
                    break
    finally:
        parts = core.score()
        _say(
            f"downloaded {core.received_mbit().sum():.1f} Mbit in {core.served_polls} polls; "
            f"t1 {parts['aadm_t1_s']:g} s; score {parts['aadm_score']:.1f}"
        )


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
    port: Annotated[int, typer.Option("--port", help="Controller TCP port.")] = 8005,
    files_dir: Annotated[
        Path | None,
        typer.Option("--files", help="Use the agent<->comm files in DIR instead of TCP."),
    ] = None,
    vehicle: Annotated[str, typer.Option("--vehicle", help="kinematic or mavsdk.")] = "kinematic",
    mavsdk_address: Annotated[
        str, typer.Option("--mavsdk-address", help="MAVSDK system address.")
    ] = "udp://:14540",
    poll_s: Annotated[
        float, typer.Option("--poll-s", help="Wall seconds between polls (each is a 1-s slot).")
    ] = 1.0,
    altitude: Annotated[float, typer.Option("--altitude", help="Take-off altitude [m].")] = 25.0,
) -> None:
    """Run a skymule policy as the UAV-side agent (TCP comm protocol or the file protocol)."""
    from skymule.aadm.agent import AadmAgent, fly_tcp, run_file_agent
    from skymule.policies import make_policy
    from skymule.scenario import load_scenario
    from skymule.world import build_mission

    if poll_s < 0:
        raise SkymuleError(f"--poll-s {poll_s:g}: must be >= 0")
    spec = load_scenario(scenario).with_policy(policy)
    the_agent = AadmAgent(build_mission(spec), make_policy(spec.policy))
    craft = _make_vehicle(vehicle, the_agent, mavsdk_address)
    if files_dir is not None:
        if not files_dir.is_dir():
            raise SkymuleError(f"--files {files_dir}: no such folder")
        record = run_file_agent(
            the_agent,
            craft,
            files_dir,
            pace_s=poll_s,
            altitude_m=altitude,
        )
    else:
        try:
            record = fly_tcp(
                the_agent,
                craft,
                host,
                port,
                pace_s=poll_s,
                altitude_m=altitude,
            )
        except ConnectionRefusedError:
            raise SkymuleError(f"--port {port}: no controller listening on {host}") from None
    _say(
        f"{record.polls} polls; landed {record.end_distance_to(the_agent.home_xy()):.1f} m "
        "from the launch point"
    )


@aadm_app.command()
def comm(
    files_dir: Annotated[Path, typer.Option("--files", help="Agent working folder.")],
    port: Annotated[int, typer.Option("--port", help="Controller TCP port.")],
    host: HostOpt = "127.0.0.1",
    poll_s: Annotated[float, typer.Option("--poll-s", help="Seconds between polls.")] = 1.0,
    max_polls: Annotated[int, typer.Option("--max-polls", help="Stop after N polls.")] = 100_000,
) -> None:
    """Stand in for the challenge's comm process: plain snr_dd polls <-> ss/dv/dd/tn/bc files."""
    from skymule.aadm.comm import run_comm

    try:
        polls = run_comm(files_dir, host, port, poll_s=poll_s, max_polls=max_polls)
    except ConnectionRefusedError:
        raise SkymuleError(f"--port {port}: no controller listening on {host}") from None
    _say(f"{polls} polls")


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
) -> None:
    """Offline AADM flight on loopback (controller + agent + kinematic vehicle) vs skymule run."""
    from skymule.aadm.loopback import fly_loopback
    from skymule.scenario import load_scenario

    if poll_s < 0:
        raise SkymuleError(f"--poll-s {poll_s:g}: must be >= 0")
    result = fly_loopback(load_scenario(scenario), policy, poll_s=poll_s, log_path=log)
    _say(f"{result.policy}: {result.polls} polls, volumes shared at poll {result.share_poll}")
    _say(f"{'':14}{'flight':>12}{'skymule run':>14}{'difference':>12}")
    for index, name in enumerate(result.sensor_names):
        flight, engine = result.flight_mbit[index], result.engine_mbit[index]
        _say(f"{name + ' [Mbit]':14}{flight:12.1f}{engine:14.1f}{flight - engine:12.1f}")
    total_f, total_e = result.flight_mbit.sum(), result.engine_mbit.sum()
    _say(f"{'total [Mbit]':14}{total_f:12.1f}{total_e:14.1f}{total_f - total_e:12.1f}")
    for key, label in (("aadm_t1_s", "t1 [s]"), ("aadm_score", "AADM score")):
        flight_v, engine_v = float(result.flight_score[key]), float(result.engine_score[key])
        _say(f"{label:14}{flight_v:12.1f}{engine_v:14.1f}{flight_v - engine_v:12.1f}")
    if abs(result.engine_mission_mbit - total_e) > 1e-6:
        _say(
            f"(skymule run downloads {result.engine_mission_mbit:.1f} Mbit over its whole "
            "mission; the columns count the controller's window)"
        )
    _say(f"landed {result.landed_distance_m:.1f} m from the launch point")
    if log is not None:
        _say(f"wrote {log}")
