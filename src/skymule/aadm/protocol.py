"""The AADM challenge's TCP bytes, as its own controller and UAV-side script exchange them.

Source: the challenge's sample controller, its UAV-side comm script and its ``IP_trace``
helper (AERPAW Autonomous Data Mule challenge, 2025; public copies in the search index under
file ids 69268802416, 68879267091 and 68989527686). Facts only; the code here is skymule's.

UAV poll (port 8005 on the testbed), one TCP connection a poll, nothing newline-terminated::

    UAV -> controller   snr_dd
    controller -> UAV   [Controller-->UAV] Cannot share now. Please wait for the UAV to
                        reach the desired altitude.;                      (before sharing)
                        vol:{'1': 500.0, '2': 800.0, ...};snr:1:12.345678,2:...   (sharing)
                        download:1:123.45,2:0.00,...;snr:...   (cumulative Mbit, 2 decimals)
                        download_complete:1;snr:...            (once, when all is downloaded)
    UAV -> controller   3                                       (the tower id, bare)
    controller -> UAV   [Controller-->UAV] Report: ts>2025-05-24 16:19:32.181307, bs>3,
                        snr>12.345678 db, rate>3.82 mbps, RECV>123.45 mbits
                        or [Controller-->UAV] Report: ts>.... No data left for download from BS3
                        or [Controller-->UAV] Please wait for the UAV to reach the desired
                        altitude.  (before sharing)   or  Invalid BS Number

SNR is given with 6 decimals; a tower never heard from is ``-99.000000`` and one whose SNR
could not be read ``0.000000`` (the controller's fallbacks). ``rate`` is what this poll
credited [Mbit per 1-s poll] (less than the CQI rate on the poll that empties a tower).

Telemetry (port 8006), one message a connection::

    sender -> controller   alt:<m>,arm:<0|1>,rtl:<0|1>,land:<0|1>,lat:<deg>,lon:<deg>
    controller -> sender   Start time not initialized.     (volumes not shared yet)
                           Download starts at <timestamp>  (once, after sharing)
                           T1: 424.00 seconds, S1:76.00, S2:100.00, Score:176.00  (once, at the end)
                           None                             (otherwise)

Towers (fixed nodes, ports 8001-8004 on their own addresses): the controller sends the bare
tower id and reads ``00,<snr dB>,<previous rate>`` (the SNR a float32, the Shannon rate of
the previous answer in bit/s); it uses the second field only (a value that is not a number
counts as 0 dB).

Every receiver here also accepts a message ending in a newline (skymule's own senders add one
where the testbed's parser strips it: telemetry values go through ``float``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import datetime

import numpy as np

from skymule.aadm.files import TIME_FORMAT
from skymule.aadm.rules import FIRST_TOWER_PORT as FIRST_TOWER_PORT
from skymule.aadm.rules import TELEMETRY_PORT as TELEMETRY_PORT
from skymule.aadm.rules import TOWERS_TELEMETRY_PORT as TOWERS_TELEMETRY_PORT
from skymule.aadm.rules import UAV_PORT as UAV_PORT
from skymule.errors import SkymuleError

REQUEST = "snr_dd"
NOT_HEARD_DB = -99.0
#: SNR the testbed shows for a tower whose reading failed (and uses for its rate).
UNREADABLE_SHOWN_DB = 0.0
PREFIX = "[Controller-->UAV]"
WAIT_REPLY = f"{PREFIX} Cannot share now. Please wait for the UAV to reach the desired altitude.;"
WAIT_REPORT = f"{PREFIX} Please wait for the UAV to reach the desired altitude."
INVALID_TOWER = "Invalid BS Number"
NOT_STARTED = "Start time not initialized."
NOTHING_NEW = "None"
#: The testbed's answer to every poll once the score is out (its controller is "off").
OFF_REPLY = f"{PREFIX} The system is currently off;"
KINDS = ("wait", "vol", "download", "download_complete", "off", "error")

#: Telemetry values the controllers here take [m, deg]: a UAV of the challenge flies below
#: 120 m; the altitude may read a little below 0 on the ground (barometer drift).
ALTITUDE_RANGE_M = (-5.0, 200.0)
LATITUDE_RANGE_DEG = (-90.0, 90.0)
LONGITUDE_RANGE_DEG = (-180.0, 180.0)
_RANGES = {"alt": ALTITUDE_RANGE_M, "lat": LATITUDE_RANGE_DEG, "lon": LONGITUDE_RANGE_DEG}

_REPORT_RE = re.compile(r"bs>(\d+), snr>(\S+) db, rate>(\S+) mbps, RECV>(\S+) mbits")
_NO_DATA_RE = re.compile(r"No data left for download from BS(\d+)")


def stamp(when: datetime) -> str:
    return when.strftime(TIME_FORMAT)


# --- controller -> UAV ----------------------------------------------------------------------


def shown_snr(snr_db: np.ndarray) -> np.ndarray:
    """The SNR the testbed reports: -99 for a tower not heard, 0 for an unreadable one."""
    snr = np.asarray(snr_db, float)
    return np.where(np.isnan(snr), UNREADABLE_SHOWN_DB, np.maximum(snr, NOT_HEARD_DB))


def format_snr(snr_db: np.ndarray) -> str:
    return "snr:" + ",".join(f"{i + 1}:{v:.6f}" for i, v in enumerate(shown_snr(snr_db)))


def format_volumes(volumes_mbit: np.ndarray) -> str:
    """``vol:{'1': 500.0, ...}``: the controller sends its volume dict as Python prints it."""
    items = ", ".join(f"'{i + 1}': {float(v)!r}" for i, v in enumerate(volumes_mbit))
    return "vol:{" + items + "}"


def format_downloads(received_mbit: np.ndarray) -> str:
    return "download:" + ",".join(f"{i + 1}:{float(v):.2f}" for i, v in enumerate(received_mbit))


def format_report(when: datetime, tower: int, snr_db: float, rate_mbit: float, recv: float) -> str:
    shown = float(shown_snr(np.array([snr_db]))[0])
    return (
        f"{PREFIX} Report: ts>{stamp(when)}, bs>{tower}, snr>{shown:.6f} db, "
        f"rate>{rate_mbit:.2f} mbps, RECV>{recv:.2f} mbits"
    )


def format_no_data_left(when: datetime, tower: int) -> str:
    return f"{PREFIX} Report: ts>{stamp(when)}. No data left for download from BS{tower}"


def format_score(t1_s: float, s1: float, s2: float, score: float, *, window_closed: bool) -> str:
    """The score line; the testbed prints t1 unrounded when the window closed."""
    t1 = f"{t1_s}" if window_closed else f"{t1_s:.2f}"
    return f"T1: {t1} seconds, S1:{s1:.2f}, S2:{s2:.2f}, Score:{score:.2f}"


@dataclass(frozen=True)
class Reply:
    """A parsed controller reply to ``snr_dd``.

    Attributes:
        kind: ``wait``, ``vol``, ``download``, ``download_complete`` or ``error``.
        values: ``vol``: volumes [Mbit]; ``download``: cumulative Mbit per tower (2 decimals);
            else None.
        snr_db: (N,) SNR per tower [dB] as shown (-99: not heard), or None.
        text: the whole reply.
    """

    kind: str
    values: np.ndarray | None
    snr_db: np.ndarray | None
    text: str = ""


def _pairs(text: str) -> np.ndarray:
    # the comm script's reading: drop braces and quotes, then "id: value" pairs
    cleaned = text.replace("{", "").replace("}", "").replace("'", "")
    values: dict[int, float] = {}
    for pair in cleaned.split(","):
        key, _, value = pair.partition(":")
        try:
            values[int(key)] = float(value)
        except ValueError:
            bad = pair.strip()[:30]
            raise SkymuleError(f"controller reply: {bad!r} is not 'id:value'") from None
    if sorted(values) != list(range(1, len(values) + 1)):
        raise SkymuleError(f"controller reply: tower ids {sorted(values)} are not 1..N")
    return np.array([values[k] for k in sorted(values)])


def parse_reply(text: str) -> Reply:
    """Parse a reply to ``snr_dd`` as the challenge's comm script splits it (on ``;``)."""
    body = text.strip()
    if body.startswith(PREFIX) and "Cannot share now" in body:
        return Reply("wait", None, None, body)
    if body == OFF_REPLY:
        return Reply("off", None, None, body)
    kind, values, snr = "", None, None
    for part in body.split(";"):
        part = part.strip()
        if part.startswith("snr:"):
            snr = _pairs(part[4:])
        elif part.startswith("download_complete:"):
            kind = "download_complete"
        elif part.startswith(("vol:", "download:")):
            kind, _, rest = part.partition(":")
            values = None if rest.strip() == "None" else _pairs(rest)
    if not kind or snr is None:
        return Reply("error", None, None, body)
    return Reply(kind, values, snr, body)


def reply_complete(data: bytes, n_towers: int) -> bool:
    """Whether ``data`` holds a whole reply to ``snr_dd`` (the testbed ends none with a
    newline: a wait text ends in ``;``, the others in an SNR list of N six-decimal values)."""
    text = data.decode("utf-8", "replace").strip()
    if text.endswith(";") or text.endswith("\n"):
        return True
    _, sep, snr = text.rpartition("snr:")
    if not sep:
        return False
    values = snr.split(",")
    return len(values) >= n_towers and re.fullmatch(r"\d+:-?\d+\.\d{6}", values[-1]) is not None


@dataclass(frozen=True)
class Report:
    """A parsed report: the tower named and, when served, what this poll credited."""

    tower: int | None
    served: bool
    rate_mbit: float = 0.0
    received_mbit: float = math.nan


def parse_report(text: str) -> Report:
    match = _REPORT_RE.search(text)
    if match is not None:
        return Report(int(match.group(1)), True, float(match.group(3)), float(match.group(4)))
    empty = _NO_DATA_RE.search(text)
    return Report(int(empty.group(1)) if empty else None, False)


# --- telemetry --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Telemetry:
    """One telemetry message (None: the field was not sent)."""

    alt_m: float | None = None
    armed: bool | None = None
    rtl: bool | None = None
    land: bool | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None


def format_telemetry(alt_m: float, armed: bool, lat_deg: float, lon_deg: float) -> str:
    # full precision: the controller's position is the UAV's, to the float
    return (
        f"alt:{float(alt_m)!r},arm:{int(armed)},rtl:0,land:0,"
        f"lat:{float(lat_deg)!r},lon:{float(lon_deg)!r}"
    )


def parse_telemetry(text: str) -> Telemetry:
    """Parse ``alt:..,arm:..,rtl:..,land:..,lat:..,lon:..`` (any order; unknown keys are
    ignored as the controller does); one-line SkymuleError for a value that is not a number
    or out of range (:data:`ALTITUDE_RANGE_M`, valid latitude and longitude)."""
    fields: dict[str, float | bool | None] = {}
    for part in text.strip().split(","):
        key, _, value = part.strip().partition(":")
        if key in ("arm", "rtl", "land"):
            if value.strip() not in ("0", "1"):
                raise SkymuleError(f"telemetry field {key}:{value[:20]!r}: expected 0 or 1")
            fields[key] = value.strip() == "1"
        elif key in ("alt", "lat", "lon"):
            try:
                number = float(value)
            except ValueError:
                number = math.nan
            if not math.isfinite(number):
                raise SkymuleError(f"telemetry field {key}:{value[:20]!r} is not a number")
            low, high = _RANGES[key]
            if not low <= number <= high:
                raise SkymuleError(
                    f"telemetry field {key}:{value.strip()[:20]}: allowed {low:g} to {high:g}"
                )
            fields[key] = number
    return Telemetry(
        alt_m=_float(fields.get("alt")),
        armed=_flag(fields.get("arm")),
        rtl=_flag(fields.get("rtl")),
        land=_flag(fields.get("land")),
        lat_deg=_float(fields.get("lat")),
        lon_deg=_float(fields.get("lon")),
    )


def testbed_telemetry_problems(text: str) -> list[str]:
    """What the testbed's controller would misread in a telemetry line it accepts: it splits
    on ``,`` and compares ``arm:`` to the bare ``1`` / ``0`` (``arm:1\n`` or ``arm: 1`` is
    neither, so it never sees the UAV arm or disarm, and never ends the session)."""
    problems = []
    for part in text.split(","):
        if part.startswith("arm:") and part[4:] not in ("0", "1"):
            problems.append(
                f"{part[:20]!r}: the testbed compares arm to the bare '0' / '1' and would "
                "not see the UAV arm or disarm"
            )
        elif part.strip().startswith("arm:") and not part.startswith("arm:"):
            problems.append(f"{part[:20]!r}: the testbed would not see this arm field")
    return problems


def _float(value: float | bool | None) -> float | None:
    return None if value is None else float(value)


def _flag(value: float | bool | None) -> bool | None:
    return None if value is None else bool(value)


# --- towers -----------------------------------------------------------------------------------


def format_tower_reply(snr_db: float, previous_rate_bps: float) -> str:
    """``00,<snr>,<previous rate>`` as the fixed nodes send it: the SNR as a float32 printed
    by Python (``12.345678``), the Shannon rate of the previous answer in bit/s as
    ``str(float)``. An unreadable SNR is an empty field (the controller then counts 0 dB), a
    tower not heard -99."""
    snr = "" if math.isnan(snr_db) else str(np.float32(max(float(snr_db), NOT_HEARD_DB)))
    return f"00,{snr},{float(previous_rate_bps)!r}"


def shannon_rate_bps(snr_db: float, bandwidth_hz: float = 1.4e6) -> float:
    """B log2(1 + SNR) [bit/s], the rate the fixed nodes report (0 for an unreadable SNR)."""
    if math.isnan(snr_db):
        return 0.0
    return float(bandwidth_hz * math.log2(1.0 + 10.0 ** (max(snr_db, NOT_HEARD_DB) / 10.0)))


def parse_tower_reply(text: str) -> float:
    """The SNR the controller takes from a tower's reply (0 dB when it is not a number)."""
    values = text.split(",")
    if len(values) < 2:
        raise SkymuleError(f"tower reply {text[:40]!r} is not '00,<snr>,<rate>'")
    try:
        return float(values[1].strip())
    except ValueError:
        return UNREADABLE_SHOWN_DB
