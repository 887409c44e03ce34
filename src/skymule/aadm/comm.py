"""A stand-in for the challenge's comm process: TCP polls on one side, agent files on the other.

As the challenge's comm script does (:mod:`~skymule.aadm.protocol` cites it), with its bytes
(:func:`reset_files`, :func:`write_reply_files`): it first resets the files (``ss.txt`` all
-99, ``dv.txt`` and ``dd.txt`` all 0, ``tn.txt`` 0, ``bc.txt`` empty), then every ``poll_s``
polls the controller with a bare ``snr_dd``, writes ``ss.txt`` (``1:38.992650,...``, the
reply's SNR text), ``dv.txt`` (``1:500.0, 2:800.0, ...``, once shared), ``dd.txt``
(downloaded) and ``tn.txt`` (``-1`` once complete), each atomically (the script writes them
in place), and names the tower the agent last wrote to ``bc.txt`` (tower 1 until the agent
has written a valid one). Use it to run a team's file-protocol agent script
against the emulated controller.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

from skymule.aadm import files, net
from skymule.aadm.controller import poll_once
from skymule.aadm.protocol import Reply
from skymule.errors import SkymuleError
from skymule.io import atomic

log = logging.getLogger("skymule.aadm.comm")


def reset_files(folder: Path, n_towers: int) -> None:
    """The comm script's start: ``bc.txt`` empty, ``tn.txt`` ``0``, ``dd.txt`` and ``dv.txt``
    ``1: 0.0, 2: 0.0, ...``, ``ss.txt`` ``1: -99, 2: -99, ...`` (no newline, as it writes)."""
    zeros = ", ".join(f"{k}: 0.0" for k in range(1, n_towers + 1))
    atomic.write_text(folder / files.CHOICE_FILE, "")
    atomic.write_text(folder / files.DONE_FILE, str(files.NOT_DONE))
    atomic.write_text(folder / files.DOWNLOADED_FILE, zeros)
    atomic.write_text(folder / files.VOLUME_FILE, zeros)
    atomic.write_text(
        folder / files.SNR_FILE, ", ".join(f"{k}: -99" for k in range(1, n_towers + 1))
    )


def _pairs_text(body: str) -> str:
    """``vol:``/``download:`` values as the comm script writes them: braces and quotes
    dropped, ``id:value`` pairs joined by ``, `` (``1:500.0, 2:800.0``); ValueError if a
    pair is not ``id:value`` (``download:None``, which the script fails on too)."""
    raw = body.replace("}", "").replace("'", "").strip("{}")
    pairs = [item.split(":") for item in raw.split(",")]
    if any(len(pair) != 2 for pair in pairs):
        raise ValueError(f"not id:value pairs: {raw[:40]!r}")
    return ", ".join(f"{key.strip()}:{value.strip()}" for key, value in pairs)


def write_reply_files(folder: Path, text: str) -> None:
    """The files the comm script writes from one reply, byte for byte: for each ``;`` part
    in order, ``snr:`` -> ``ss.txt`` (the text after ``snr:``, e.g. ``1:38.992650,...``),
    ``vol:`` -> ``dv.txt``, ``download:`` -> ``dd.txt``, ``download_complete:`` -> ``tn.txt``
    = ``-1``. A part it cannot read ends the reply's processing, as in the script."""
    for part in text.split(";"):
        if part.startswith("snr:"):
            atomic.write_text(folder / files.SNR_FILE, part.replace("snr:", ""))
        elif part.startswith(("vol:", "download:")):
            key = part.split(":")[0]
            try:
                values = _pairs_text(part.replace(f"{key}:", ""))
            except ValueError as exc:
                log.info("reply part %r: %s", part[:40], exc)
                return
            name = files.VOLUME_FILE if key == "vol" else files.DOWNLOADED_FILE
            atomic.write_text(folder / name, values)
        elif part.strip().startswith("download_complete:"):
            atomic.write_text(folder / files.DONE_FILE, str(files.DONE))


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
    reset_files(folder, n_towers)

    def choose(reply: Reply) -> int:
        write_reply_files(folder, reply.text)
        return _choice(folder, n_towers)

    polls = 0
    reached = False
    quiet = net.RateLimitedLog(log, every_s=5.0)
    while polls < max_polls and not should_stop():
        started = time.monotonic()
        try:
            reply, _ = poll_once(host, port, choose, n_towers)
            reached = True
        except ConnectionRefusedError:
            if not reached:  # no controller at all: say so (the CLI's one line)
                raise
            quiet.warning(f"poll failed: no controller listening on {host}:{port}")
            reply = None
        except (OSError, SkymuleError) as exc:  # as the challenge's script: poll again
            quiet.warning(f"poll failed: {exc}")
            reply = None
        if reply is not None and reply.kind == "error":
            raise SkymuleError(f"controller {host}:{port} refused the poll: {reply.text}")
        polls += 1
        time.sleep(max(0.0, poll_s - (time.monotonic() - started)))
    return polls


def _choice(folder: Path, n_towers: int) -> int:
    """``bc.txt`` as the comm script reads it (stripped; tower 1 while empty or unreadable)."""
    try:
        return files.read_choice_file(folder / files.CHOICE_FILE, n_towers)
    except SkymuleError as exc:
        log.info("no valid choice yet (%s); naming tower 1", exc)
        return 1
