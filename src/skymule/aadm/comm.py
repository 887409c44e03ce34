"""A stand-in for the challenge's comm process: TCP polls on one side, agent files on the other.

As the challenge's comm script does (:mod:`~skymule.aadm.protocol` cites it): it first resets
the files (``ss.txt`` all -99, ``dv.txt`` and ``dd.txt`` all 0, ``tn.txt`` 0), then every
``poll_s`` polls the controller with a bare ``snr_dd``, writes ``ss.txt`` (SNR, when the reply
has one), ``dv.txt`` (volumes, once shared), ``dd.txt`` (downloaded) and ``tn.txt`` (``-1``
once complete) atomically, and names the tower the agent last wrote to ``bc.txt`` (tower 1
until the agent has written a valid one). Use it to run a team's file-protocol agent script
against the emulated controller.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from skymule.aadm import files
from skymule.aadm.controller import poll_once
from skymule.aadm.protocol import NOT_HEARD_DB, Reply
from skymule.errors import SkymuleError

log = logging.getLogger("skymule.aadm.comm")


def run_comm(
    folder: Path,
    host: str,
    port: int,
    n_towers: int,
    *,
    poll_s: float = 1.0,
    max_polls: int = 100_000,
    should_stop: Callable[[], bool] = lambda: False,
) -> int:
    """Poll until ``should_stop()`` or ``max_polls``; returns the number of polls made."""
    folder.mkdir(parents=True, exist_ok=True)
    volumes: list[np.ndarray] = []
    files.write_tower_file(folder / files.SNR_FILE, np.full(n_towers, NOT_HEARD_DB))
    files.write_tower_file(folder / files.VOLUME_FILE, np.zeros(n_towers))
    files.write_tower_file(folder / files.DOWNLOADED_FILE, np.zeros(n_towers))
    files.write_done_file(folder / files.DONE_FILE, False)

    def choose(reply: Reply) -> int:
        if reply.snr_db is None:
            return _choice(folder, n_towers)
        files.write_tower_file(folder / files.SNR_FILE, reply.snr_db)
        if reply.kind == "vol" and reply.values is not None:
            volumes.append(reply.values)
            files.write_tower_file(folder / files.VOLUME_FILE, reply.values)
            files.write_tower_file(folder / files.DOWNLOADED_FILE, np.zeros(n_towers))
        elif reply.kind == "download" and reply.values is not None:
            files.write_tower_file(folder / files.DOWNLOADED_FILE, reply.values)
        elif reply.kind == "download_complete" and volumes:
            files.write_tower_file(folder / files.DOWNLOADED_FILE, volumes[0])
        if reply.kind == "download_complete":
            files.write_done_file(folder / files.DONE_FILE, True)
        return _choice(folder, n_towers)

    polls = 0
    while polls < max_polls and not should_stop():
        started = time.monotonic()
        try:
            reply, _ = poll_once(host, port, choose, n_towers)
        except (TimeoutError, SkymuleError) as exc:  # as the challenge's script: poll again
            log.warning("poll failed: %s", exc)
            reply = None
        if reply is not None and reply.kind == "error":
            raise SkymuleError(f"controller {host}:{port} refused the poll: {reply.text}")
        polls += 1
        time.sleep(max(0.0, poll_s - (time.monotonic() - started)))
    return polls


def _choice(folder: Path, n_towers: int) -> int:
    try:
        return files.read_choice_file(folder / files.CHOICE_FILE, n_towers)
    except SkymuleError as exc:
        log.info("no valid choice yet (%s); naming tower 1", exc)
        return 1
