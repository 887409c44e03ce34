"""The UAV <-> controller TCP protocol (one connection a poll), as text.

Per poll the UAV's comm process connects (the challenge uses port 8005) and::

    UAV -> controller   snr_dd[;pos:X,Y,Z][;armed:0|1]
    controller -> UAV   wait:<why>;snr:1:<dB>,2:<dB>,...          (below 24 m: cannot share)
                        vol:1:<Mbit>,2:<Mbit>,...;snr:...          (first poll above 24 m)
                        download:1:<Mbit>,2:<Mbit>,...;snr:...     (cumulative, later polls)
                        download_complete:1;snr:...                (everything downloaded)
    UAV -> controller   <tower id 1..N>
    controller -> UAV   report:<one line>   or   error:<one line>

``pos`` and ``armed`` are skymule's extension (optional; a plain ``snr_dd`` from the
challenge's comm process works): the UAV's position in the scenario's local frame [m]
(x east, y north, z above the launch point) and whether it is armed, so that the emulator
can compute the SNR where the UAV is and stop serving on disarm. A tower not heard from
reports -99 dB. Every line ends with ``\\n``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skymule.aadm.files import parse_tower_values
from skymule.errors import SkymuleError

REQUEST = "snr_dd"
NOT_HEARD_DB = -99.0
KINDS = ("wait", "vol", "download", "download_complete", "error")


@dataclass(frozen=True)
class Request:
    """A parsed ``snr_dd`` request (position [m] and armed state when the UAV sent them)."""

    position_m: np.ndarray | None = None
    armed: bool | None = None


def format_request(position_m: np.ndarray | None = None, armed: bool | None = None) -> str:
    parts = [REQUEST]
    if position_m is not None:
        parts.append("pos:" + ",".join(f"{float(v):.3f}" for v in position_m))
    if armed is not None:
        parts.append(f"armed:{int(armed)}")
    return ";".join(parts)


def parse_request(line: str) -> Request:
    """Parse ``snr_dd[;pos:x,y,z][;armed:0|1]`` (one-line SkymuleError otherwise)."""
    fields = [f.strip() for f in line.strip().split(";")]
    if not fields or fields[0] != REQUEST:
        raise SkymuleError(f"request {line.strip()[:60]!r} is not allowed; expected {REQUEST!r}")
    position: np.ndarray | None = None
    armed: bool | None = None
    for field in fields[1:]:
        key, _, value = field.partition(":")
        if key == "pos":
            try:
                numbers = [float(v) for v in value.split(",")]
            except ValueError:
                numbers = []
            if len(numbers) != 3 or not all(math.isfinite(v) for v in numbers):
                raise SkymuleError(
                    f"request field pos:{value[:40]!r}: expected pos:x,y,z in metres"
                )
            position = np.array(numbers)
        elif key == "armed" and value in ("0", "1"):
            armed = value == "1"
        else:
            raise SkymuleError(
                f"request field {field[:40]!r} is not allowed; allowed: pos:x,y,z and armed:0|1"
            )
    return Request(position, armed)


def format_values(values: np.ndarray) -> str:
    # full float precision: a rounded total can flip a policy's "data left after this slot"
    return ",".join(f"{i + 1}:{float(v)!r}" for i, v in enumerate(values))


def format_snr(snr_db: np.ndarray) -> str:
    shown = np.where(np.isfinite(snr_db), snr_db, NOT_HEARD_DB)
    # full precision too: a rounded SNR can cross a CQI threshold the controller did not
    return "snr:" + ",".join(f"{i + 1}:{float(v)!r}" for i, v in enumerate(shown))


@dataclass(frozen=True)
class Reply:
    """A parsed controller reply to ``snr_dd``.

    Attributes:
        kind: ``wait``, ``vol``, ``download``, ``download_complete`` or ``error``.
        values: ``vol``: volumes [Mbit]; ``download``: cumulative Mbit per tower; else None.
        snr_db: (N,) SNR per tower [dB] (-99: not heard), or None for ``error``.
        text: the ``wait``/``error`` message.
    """

    kind: str
    values: np.ndarray | None
    snr_db: np.ndarray | None
    text: str = ""


def parse_reply(line: str) -> Reply:
    """Parse a controller reply (one-line SkymuleError if it is not one)."""
    text = line.strip()
    kind, _, rest = text.partition(":")
    if kind == "error":
        return Reply("error", None, None, rest)
    head, sep, snr_part = rest.rpartition(";snr:")
    if kind not in KINDS or not sep:
        raise SkymuleError(f"controller reply {text[:60]!r} is not <kind>:...;snr:1:<dB>,...")
    snr = parse_tower_values(snr_part, "controller reply snr")
    if kind in ("vol", "download"):
        values = parse_tower_values(head, f"controller reply {kind}", len(snr))
        return Reply(kind, values, snr)
    return Reply(kind, None, snr, head)
