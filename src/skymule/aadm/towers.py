"""skymule's radio in the place of the AADM towers, so that the challenge's own controller runs.

On the testbed the controller asks each fixed node (LW1..LW4, port 8001..8004 on the node's
address) for the UAV's SNR: it sends the bare tower id and reads ``00,<snr dB>,<previous
rate>`` (:mod:`~skymule.aadm.protocol`). :func:`serve_towers` answers the same from the
scenario's signal source at the UAV's position, which it takes from the testbed's telemetry
line (its own telemetry port; ``forward`` passes each message on to the controller's
telemetry port and returns its reply, so one sender feeds both) or, in process, from a
:class:`~skymule.aadm.vehicle.Vehicle`. A recorded trace is replayed one sample per request
to each tower.

The controller finds the towers' addresses in the testbed's experiment-environment file
(``/root/.ap-set-experiment-env.sh``): ``AP_EXPENV_SET_NODES`` lists the nodes in order, and
node k's address is ``export AP_EXPENV_EVM_<k>_XM=<ip>``. :func:`experiment_env` writes one
that puts every node on one address; the controller looks the towers up as ``LW1``..``LW4``
and the UAV as ``0`` (its ``IP_trace`` helper; :mod:`~skymule.aadm.protocol` cites it).
"""

from __future__ import annotations

import logging
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass

import numpy as np

from skymule.aadm import net, protocol
from skymule.aadm.controller import PositionSource, SignalFeed, telemetry_position
from skymule.errors import SkymuleError
from skymule.world import Mission

log = logging.getLogger("skymule.aadm.towers")

#: The testbed's experiment-environment file, read by the challenge's controller.
EXPERIMENT_ENV = "/root/.ap-set-experiment-env.sh"
#: The node name the controller gives the UAV's address.
UAV_NODE = "0"


class TowerRadio:
    """What each tower hears of the UAV (thread-safe)."""

    def __init__(self, mission: Mission, position_source: PositionSource | None = None) -> None:
        self.mission = mission
        self.feed = SignalFeed(mission)
        self.position_source = position_source
        self._position: np.ndarray | None = None
        self._requests = np.zeros(mission.n_sensors, np.int64)
        self._last_rate_bps = np.zeros(mission.n_sensors)
        self._lock = threading.Lock()
        self.owner: str | None = None  # the address whose valid telemetry came first

    def telemetry(self, text: str, peer: str = "") -> None:
        """Take the UAV's position from one telemetry line (one-line SkymuleError if bad, or
        if it comes from another address than the first valid one: the session's UAV)."""
        with self._lock:
            if self.owner is not None and peer != self.owner:
                raise SkymuleError(f"telemetry from {peer}: the session's comes from {self.owner}")
        message = protocol.parse_telemetry(text)
        with self._lock:
            self.owner = self.owner or peer
            self._position = telemetry_position(message, self.mission.frame, self._position)

    def answer(self, index: int) -> str:
        """Tower ``index``'s reply: its SNR of the UAV now and the rate of its last answer."""
        with self._lock:
            position = self._position
            if self.position_source is not None:
                position = self.position_source()[0]
            snr, _ = self.feed.snr_db(position, int(self._requests[index]))
            self._requests[index] += 1
            value = float(snr[index])
            reply = protocol.format_tower_reply(value, float(self._last_rate_bps[index]))
            self._last_rate_bps[index] = protocol.shannon_rate_bps(value)
            return reply


@dataclass(frozen=True)
class RunningTowers:
    """The towers' ports (tower 1 first) and their telemetry port (None: none)."""

    host: str
    ports: tuple[int, ...]
    telemetry_port: int | None


def _tower(radio: TowerRadio, index: int) -> Callable[[socket.socket, str], None]:
    def handle(sock: socket.socket, peer: str) -> None:
        if net.receive(sock, lambda data: "whole", first_byte_s=net.FIRST_BYTE_S) is not None:
            sock.sendall(radio.answer(index).encode())

    return handle


class Forwarder:
    """Passes telemetry on to the controller; once the controller's port stops answering (the
    testbed's controller closes it after the score line), says so once and stops trying for
    :data:`DEAD_FOR_S` seconds, answering ``None`` meanwhile."""

    def __init__(self, target: tuple[str, int], timeout_s: float = 2.0) -> None:
        self.target = target
        self.timeout_s = timeout_s
        self._dead_until = 0.0
        self._said = False
        self._lock = threading.Lock()

    def send(self, text: str) -> str:
        with self._lock:
            if time.monotonic() < self._dead_until:
                return protocol.NOTHING_NEW
        host, port = self.target
        try:
            reply = net.exchange(host, port, text, timeout_s=self.timeout_s)
        except OSError as exc:
            with self._lock:
                self._dead_until = time.monotonic() + DEAD_FOR_S
                said, self._said = self._said, True
            if not said:
                log.warning(
                    "controller telemetry %s:%d does not answer (%s); not forwarding for %g s "
                    "at a time (the testbed's controller stops listening after its score line)",
                    host,
                    port,
                    exc,
                    DEAD_FOR_S,
                )
            return protocol.NOTHING_NEW
        with self._lock:
            self._said = False
        return reply


#: Seconds the towers stop forwarding after the controller's telemetry port failed.
DEAD_FOR_S = 10.0


def _telemetry(
    radio: TowerRadio, forward: tuple[str, int] | None
) -> Callable[[socket.socket, str], None]:
    forwarder = None if forward is None else Forwarder(forward)

    def handle(sock: socket.socket, peer: str) -> None:
        data = net.receive(sock, net.text_line, first_byte_s=net.FIRST_BYTE_S)
        if data is None:
            return
        text = data.decode("utf-8", "replace")
        try:
            radio.telemetry(text, peer)
        except SkymuleError as exc:
            log.warning("refused: %s", exc)
            sock.sendall(f"Error: {exc}".encode())
            return
        reply = protocol.NOTHING_NEW if forwarder is None else forwarder.send(text)
        sock.sendall(reply.encode())

    return handle


@contextmanager
def serve_towers(
    radio: TowerRadio,
    host: str = "127.0.0.1",
    ports: Sequence[int] | None = None,
    telemetry_port: int | None = 0,
    forward: tuple[str, int] | None = None,
) -> Iterator[RunningTowers]:
    """Serve one port per tower (default: any free ports) and a telemetry port (0: any free;
    None: none) until the block ends; everything is closed on exit, also on an exception."""
    n_towers = radio.mission.n_sensors
    chosen = [0] * n_towers if ports is None else list(ports)
    if len(chosen) != n_towers:
        raise SkymuleError(f"towers: {len(chosen)} ports for the scenario's {n_towers} towers")
    with ExitStack() as stack:
        served = [
            stack.enter_context(
                net.serving(host, port, _tower(radio, k), "aadm-towers", f"tower {k + 1} port")
            ).port
            for k, port in enumerate(chosen)
        ]
        telemetry = None
        if telemetry_port is not None:
            telemetry = stack.enter_context(
                net.serving(
                    host,
                    telemetry_port,
                    _telemetry(radio, forward),
                    "aadm-towers",
                    "--telemetry-port",
                )
            ).port
        yield RunningTowers(host, tuple(served), telemetry)


def ask_tower(host: str, port: int, tower_id: int, timeout_s: float = 5.0) -> float:
    """The SNR a tower gives, asked as the challenge's controller asks (bare tower id)."""
    return protocol.parse_tower_reply(net.exchange(host, port, str(tower_id), timeout_s))


# --- the experiment-environment file ---------------------------------------------------------


def experiment_env(n_towers: int, address: str = "127.0.0.1") -> str:
    """An experiment-environment file with the UAV (node ``0``) and LW1..LWn at ``address``."""
    nodes = [UAV_NODE, *(f"LW{k}" for k in range(1, n_towers + 1))]
    lines = [
        "# written by skymule aadm towers: every AADM node at one address",
        f'export AP_EXPENV_SET_NODES="{" ".join(nodes)}"',
        *(f"export AP_EXPENV_EVM_{k}_XM={address}" for k in range(1, len(nodes) + 1)),
    ]
    return "\n".join(lines) + "\n"


def read_experiment_env(text: str, where: str) -> dict[str, str]:
    """Node name -> address, by the controller's rule: the k-th name of
    ``AP_EXPENV_SET_NODES`` has the address of ``AP_EXPENV_EVM_<k>_XM``."""
    order: list[str] | None = None
    addresses: dict[int, str] = {}
    for line in text.splitlines():
        if "AP_EXPENV_SET_NODES=" in line and order is None:
            order = re.findall(r"[A-Za-z0-9]+", line.split("=", 1)[1])
        match = re.match(r"export AP_EXPENV_EVM_(\d+)_XM=(.*)", line.strip())
        if match:
            addresses[int(match.group(1))] = match.group(2).strip()
    if order is None:
        raise SkymuleError(f"{where}: no AP_EXPENV_SET_NODES= line")
    missing = [name for k, name in enumerate(order, start=1) if k not in addresses]
    if missing:
        raise SkymuleError(f"{where}: no AP_EXPENV_EVM_<n>_XM address for node(s) {missing}")
    return {name: addresses[k] for k, name in enumerate(order, start=1)}
