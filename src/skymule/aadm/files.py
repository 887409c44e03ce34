"""The AADM challenge's own files: volumes, the controller's download log, agent<->comm files.

* **Volume file**: one Mbit value a line, tower 1 first (``10``, ``30``, ``90``, ``270``).
* **Download log** (the controller's, one row a poll): CSV ``time,dl_lw1,...,dl_lwN`` with the
  cumulative Mbit received per tower and ``time`` like ``2025-05-24 16:19:32.181307``.
* **Agent <-> comm files** in the agent's working folder: ``ss.txt`` (SNR dB), ``dv.txt``
  (volumes Mbit) and ``dd.txt`` (downloaded Mbit), each ``1: -99, 2: -99, 3: -99, 4: -99``;
  ``tn.txt`` is ``0``, or ``-1`` once the download is complete; ``bc.txt`` holds the chosen
  tower id. Every write is atomic (a temporary file in the same folder, then ``os.replace``)
  so that the other process never reads half a file.

Every malformed file is one :class:`~skymule.errors.SkymuleError` line naming the file.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.io.traces import read_volumes

#: ``time`` column format of the controller's download log.
TIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"

#: Agent <-> comm file names.
SNR_FILE = "ss.txt"
VOLUME_FILE = "dv.txt"
DOWNLOADED_FILE = "dd.txt"
DONE_FILE = "tn.txt"
CHOICE_FILE = "bc.txt"

#: ``tn.txt`` values.
NOT_DONE = 0
DONE = -1

_PAIR_RE = re.compile(r"^\s*(\d+)\s*:\s*(\S+)\s*$")


# ---------------------------------------------------------------------------
# Volume files
# ---------------------------------------------------------------------------


def read_volume_file(path: Path, n_towers: int | None = None) -> np.ndarray:
    """(N,) volumes [Mbit], tower 1 first; with ``n_towers``, exactly that many lines."""
    values = read_volumes(path)
    if n_towers is not None and len(values) != n_towers:
        raise SkymuleError(
            f"{path}: {len(values)} volume line(s) for {n_towers} towers; give one Mbit value "
            "a line, tower 1 first"
        )
    return values


def write_volume_file(path: Path, volumes_mbit: np.ndarray) -> None:
    atomic.write_text(path, "".join(f"{float(v):g}\n" for v in volumes_mbit))


# ---------------------------------------------------------------------------
# The controller's download log
# ---------------------------------------------------------------------------


def download_log_header(n_towers: int) -> list[str]:
    return ["time", *(f"dl_lw{i + 1}" for i in range(n_towers))]


def is_aadm_download_log(path: Path) -> bool:
    """Whether ``path``'s header is the controller's ``time,dl_lw1,...`` (not time,tower,mbit)."""
    try:
        with path.open(encoding="utf-8-sig") as handle:
            first = handle.readline()
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read download log ({exc.strerror})") from None
    header = [c.strip().lower() for c in first.split(",")]
    return len(header) >= 2 and header[0] == "time" and header[1].startswith("dl_")


@dataclass(frozen=True)
class AadmDownloadLog:
    """A controller download log.

    Attributes:
        time_s: (K,) seconds since the first row (the poll the volumes were shared at).
        start: timestamp of the first row.
        cumulative_mbit: (K, N) running total received per tower [Mbit].
        towers: (N,) column names (``dl_lw1`` ...).
    """

    time_s: np.ndarray
    start: datetime
    cumulative_mbit: np.ndarray
    towers: tuple[str, ...]

    def per_slot_mbit(self, slot_s: float = 1.0) -> np.ndarray:
        """(T, N) Mbit received in each slot since the first row (rows binned by time)."""
        steps = np.diff(self.cumulative_mbit, axis=0, prepend=0.0)
        slots = np.floor(self.time_s / slot_s + 1e-9).astype(int)
        out = np.zeros((int(slots[-1]) + 1 if len(slots) else 0, self.cumulative_mbit.shape[1]))
        np.add.at(out, slots, steps)
        return out


def read_download_log(path: Path) -> AadmDownloadLog:
    """Parse a controller download log (one-line error naming the file, row and column)."""
    try:
        with path.open(encoding="utf-8-sig", newline="") as handle:
            rows = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read download log ({exc.strerror})") from None
    if not rows:
        raise SkymuleError(f"{path}: empty download log (expected a time,dl_lw1,... header)")
    header = [c.strip().lower() for c in rows[0]]
    if header[0] != "time" or len(header) < 2 or not all(c.startswith("dl_") for c in header[1:]):
        raise SkymuleError(
            f"{path}: header {','.join(rows[0])!r} is not the controller's time,dl_lw1,dl_lw2,..."
        )
    if len(rows) < 2:
        raise SkymuleError(f"{path}: the download log has a header and no rows")
    stamps: list[datetime] = []
    totals = np.empty((len(rows) - 1, len(header) - 1))
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise SkymuleError(
                f"{path}: row {number} has {len(row)} cells; the header has {len(header)}"
            )
        try:
            stamps.append(datetime.strptime(row[0].strip(), TIME_FORMAT))
        except ValueError:
            raise SkymuleError(
                f"{path}: row {number}, column time: {row[0]!r} is not like "
                "'2025-05-24 16:19:32.181307'"
            ) from None
        for column, cell in enumerate(row[1:]):
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not math.isfinite(value) or value < 0:
                raise SkymuleError(
                    f"{path}: row {number}, column {header[column + 1]}: {cell!r} is not a "
                    "non-negative number of Mbit"
                )
            totals[number - 2, column] = value
    time_s = np.array([(s - stamps[0]).total_seconds() for s in stamps])
    if np.any(np.diff(time_s) < 0):
        raise SkymuleError(
            f"{path}: column time goes backwards (row {int(np.argmax(np.diff(time_s) < 0)) + 3})"
        )
    if np.any(np.diff(totals, axis=0) < -1e-9):
        bad = int(np.argmax(np.any(np.diff(totals, axis=0) < -1e-9, axis=1))) + 3
        raise SkymuleError(f"{path}: row {bad}: a cumulative total went down (totals only grow)")
    return AadmDownloadLog(time_s, stamps[0], totals, tuple(header[1:]))


class DownloadLogWriter:
    """Appends one row a poll to a controller download log, flushed at every row."""

    def __init__(self, path: Path, n_towers: int) -> None:
        self.path = path
        self._handle = path.open("w", encoding="utf-8", newline="")
        self._writer = csv.writer(self._handle)
        self._writer.writerow(download_log_header(n_towers))
        self._handle.flush()

    def write(self, when: datetime, cumulative_mbit: np.ndarray) -> None:
        self._writer.writerow([when.strftime(TIME_FORMAT), *(f"{v:.6f}" for v in cumulative_mbit)])
        self._handle.flush()

    def close(self) -> None:
        self._handle.close()


# ---------------------------------------------------------------------------
# Agent <-> comm files
# ---------------------------------------------------------------------------


def format_tower_values(values: np.ndarray) -> str:
    """``1: -99, 2: 12.5, ...`` (tower ids from 1)."""
    return ", ".join(f"{i + 1}: {float(v):g}" for i, v in enumerate(values))


def parse_tower_values(text: str, where: str, n_towers: int | None = None) -> np.ndarray:
    """(N,) values of ``1: a, 2: b, ...``, in tower-id order (ids 1..N, each once).

    A value that is not a number (e.g. ``nan`` or ``-``) is NaN: the controller could not
    read it.
    """
    pairs = [p for p in text.strip().split(",") if p.strip()]
    found: dict[int, float] = {}
    for pair in pairs:
        match = _PAIR_RE.match(pair)
        if match is None:
            raise SkymuleError(f"{where}: {pair.strip()!r} is not 'tower_id: value'")
        try:
            value = float(match.group(2))
        except ValueError:
            value = math.nan
        found[int(match.group(1))] = value
    expected = n_towers if n_towers is not None else len(found)
    if not found or sorted(found) != list(range(1, expected + 1)):
        raise SkymuleError(
            f"{where}: towers {sorted(found)}; expected ids 1..{expected} each once, "
            "like '1: -99, 2: -99, 3: -99, 4: -99'"
        )
    return np.array([found[i] for i in range(1, expected + 1)], float)


def read_tower_file(path: Path, n_towers: int | None = None) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read ({exc.strerror})") from None
    return parse_tower_values(text, str(path), n_towers)


def write_tower_file(path: Path, values: np.ndarray) -> None:
    atomic.write_text(path, format_tower_values(values) + "\n")


def read_done_file(path: Path) -> bool:
    """``tn.txt``: True once the controller reported the download complete (``-1``)."""
    try:
        text = path.read_text(encoding="utf-8").strip()
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read ({exc.strerror})") from None
    if text not in (str(NOT_DONE), str(DONE)):
        raise SkymuleError(f"{path}: {text!r}; expected 0 or -1 (download complete)")
    return text == str(DONE)


def write_done_file(path: Path, done: bool) -> None:
    atomic.write_text(path, f"{DONE if done else NOT_DONE}\n")


def parse_tower_id(text: str, n_towers: int, where: str) -> int:
    """A tower id ``1``..``n_towers`` (one-line error otherwise)."""
    cell = text.strip()
    if not cell.isdigit() or not 1 <= int(cell) <= n_towers:
        raise SkymuleError(f"{where}: tower id {cell!r} is not allowed; allowed: 1..{n_towers}")
    return int(cell)


def read_choice_file(path: Path, n_towers: int) -> int:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read ({exc.strerror})") from None
    return parse_tower_id(text, n_towers, str(path))


def write_choice_file(path: Path, tower_id: int) -> None:
    atomic.write_text(path, f"{int(tower_id)}\n")
