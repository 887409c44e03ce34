"""The sweep result store: a locked folder, Parquet parts written atomically, resume, merging.

Layout of a sweep folder ``DIR``::

    DIR/sweep.json                       which sweep file it holds (sha256) and the id scheme
    DIR/.lock                            while a sweep runs: its pid, host and start time
    DIR/results/part-*.parquet ...       one part per finished chunk (unique tmp + os.replace)
    DIR/results.parquet                  every mission of the sweep exactly once
    DIR/summary.csv                      per policy: missions, mean and 95% CI per metric

A part is either complete or absent: each writer writes a temporary file under a name no other
writer uses and renames it into place, so the mission ids in the parts are exactly the missions
done. A part that cannot be read (a damaged disk, a stray file) is set aside as
``*.parquet.damaged`` on resume and its missions run again.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
import uuid
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.metrics.summary import HEADLINE_METRICS

PARTS = "results"
RESULTS = "results.parquet"
SUMMARY = "summary.csv"
METADATA = "sweep.json"
LOCK = ".lock"
SUMMARY_METRICS = HEADLINE_METRICS
ID_SCHEME = 2
"""Version of the mission-id scheme (1: sha256 of each resolved scenario's JSON, no sweep.json;
2: sha256 of the sweep identity plus the mission's axis values)."""


def part_paths(out: Path) -> list[Path]:
    return sorted((out / PARTS).glob("part-*.parquet"))


# --- one sweep per folder: the lock and the sweep file it belongs to ----------------------


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


@dataclass(frozen=True)
class Holder:
    """Who holds a folder's lock."""

    pid: int
    host: str
    started: str

    def stale(self) -> bool:
        """A lock left by a dead process on this host (another host's pid cannot be checked)."""
        return self.host == socket.gethostname() and not _pid_alive(self.pid)


def _read_holder(path: Path) -> Holder | None:
    try:
        data = json.loads(path.read_text())
        return Holder(int(data["pid"]), str(data["host"]), str(data["started"]))
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError):
        return Holder(-1, "?", "?")  # half-written or foreign: treated as held, never stolen


@contextlib.contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock while the block runs; a second sweep on it gets one clear line."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SkymuleError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    path = out / LOCK
    me = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    for _ in range(3):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            holder = _read_holder(path)
            if holder is None:
                continue  # released meanwhile
            if not holder.stale():
                raise SkymuleError(
                    f"--out {out}: another sweep is using this folder (pid {holder.pid} on "
                    f"{holder.host}, started {holder.started}); wait for it, or delete "
                    f"{path} if that process is gone"
                ) from None
            # a dead process's lock: move it aside (only one contender's rename succeeds)
            with contextlib.suppress(FileNotFoundError):
                os.rename(path, path.with_name(f"{LOCK}.stale-{uuid.uuid4().hex}"))
            for stale in out.glob(f"{LOCK}.stale-*"):
                stale.unlink(missing_ok=True)
            continue
        except OSError as exc:
            raise SkymuleError(f"--out {out}: cannot write {path} ({exc.strerror})") from None
        with os.fdopen(fd, "w") as handle:
            json.dump(me, handle)
        break
    else:
        raise SkymuleError(f"--out {out}: cannot take the lock {path}; try again")
    try:
        yield
    finally:
        holder = _read_holder(path)
        if holder is not None and holder.pid == me["pid"] and holder.host == me["host"]:
            path.unlink(missing_ok=True)


def claim(out: Path, digest: str, source: str) -> None:
    """Tie ``out`` to one sweep file (by ``digest``); refuse another file or older ids."""
    meta = out / METADATA
    if meta.exists():
        try:
            data = json.loads(meta.read_text())
            held, scheme, held_source = data["sweep_sha256"], data["id_scheme"], data["source"]
        except (OSError, ValueError, KeyError, TypeError):
            raise SkymuleError(f"--out {out}: {meta} is damaged; use a new --out folder") from None
        if held != digest:
            raise SkymuleError(
                f"--out {out} holds the sweep {held_source} (sha256 {held[:12]}), not "
                f"{source} (sha256 {digest[:12]}); use another --out folder "
                "(or --force to start over)"
            )
        if scheme != ID_SCHEME:
            raise SkymuleError(f"--out {out}: mission ids v{scheme}, need v{ID_SCHEME}")
        return
    if part_paths(out):
        raise SkymuleError(
            f"--out {out} was written by an older skymule (mission ids v1, no {METADATA}) and "
            "cannot be resumed; use a new --out folder"
        )
    record = {"sweep_sha256": digest, "id_scheme": ID_SCHEME, "source": source}
    atomic.write_text(meta, json.dumps(record, indent=1) + "\n")


# --- parts -----------------------------------------------------------------------------


def _atomic_parquet(table: pa.Table | pd.DataFrame, path: Path) -> None:
    # synced before the rename: a resume trusts that a part in place is complete on disk
    with atomic.atomic_path(path, sync=True) as tmp:
        if isinstance(table, pd.DataFrame):
            table.to_parquet(tmp, index=False)
        else:
            pq.write_table(table, tmp)


def write_part(out: Path, frame: pd.DataFrame) -> Path:
    """Store one finished chunk as a new part (atomically, under a name no writer reuses)."""
    folder = out / PARTS
    folder.mkdir(parents=True, exist_ok=True)
    first = int(frame["mission_index"].iloc[0]) if len(frame) else 0
    path = folder / f"part-{first:012d}-{uuid.uuid4().hex[:12]}.parquet"
    _atomic_parquet(frame, path)
    return path


@dataclass(frozen=True)
class Done:
    """Missions already stored in a folder's parts, and the parts that could not be read."""

    ids: set[str]
    damaged: tuple[Path, ...]


def done_ids(out: Path) -> set[str]:
    """Mission ids already stored in ``out``'s readable parts."""
    return scan(out).ids


def scan(out: Path, *, set_aside: bool = False) -> Done:
    """Ids in ``out``'s parts; unreadable parts are listed (and renamed with ``set_aside``)."""
    ids: set[str] = set()
    damaged = []
    for path in part_paths(out):
        try:
            column = pq.read_table(path, columns=["mission_id"]).column(0)
        except (OSError, pa.ArrowException, KeyError):
            damaged.append(path)
            if set_aside:
                os.replace(path, path.with_name(path.name + ".damaged"))
            continue
        ids.update(column.to_pylist())
    return Done(ids, tuple(damaged))


def consolidate(out: Path, ids: Iterable[str]) -> pd.DataFrame:
    """``results.parquet``: the sweep's missions (``ids``) exactly once, in sweep order.

    Linear in the rows: the parts are joined first and filtered by one
    ``pyarrow.compute.is_in`` (which builds its hash set of the wanted ids on every call: once
    per part made 100,000-mission sweeps spend seconds rebuilding it).
    """
    tables = [pq.read_table(path) for path in part_paths(out)]
    if not tables:
        frame = pd.DataFrame()
    else:
        table = pa.concat_tables(tables, promote_options="permissive")
        wanted = pa.array(list(ids), pa.string())
        frame = table.filter(pc.is_in(table["mission_id"], value_set=wanted)).to_pandas()
        frame = frame.drop_duplicates("mission_id").sort_values("mission_index")
        frame = frame.reset_index(drop=True)
    _atomic_parquet(frame, out / RESULTS)
    return frame


def ci95_half_width(values: np.ndarray) -> float:
    """Half-width of the 95% confidence interval of the mean (Student t; NaN for n < 2)."""
    from scipy.special import stdtrit  # the t quantile scipy.stats.t.ppf uses; a light import

    values = values[np.isfinite(values)]
    if values.size < 2:
        return float("nan")
    return float(stdtrit(values.size - 1, 0.975) * values.std(ddof=1) / np.sqrt(values.size))


def summary_table(results: pd.DataFrame, levels: Sequence[str] = ()) -> pd.DataFrame:
    """Per policy and combination of the ``levels`` columns (the swept treatments, see
    :attr:`skymule.experiments.sweep.SweepSpec.level_columns`): number of missions, and mean
    and 95% CI half-width of each metric."""
    metrics = [m for m in SUMMARY_METRICS if m in results.columns]
    keys = ["policy", *(c for c in levels if c in results.columns)]
    rows = []
    for level, group in results.groupby(keys, sort=True, dropna=False):
        row: dict[str, object] = dict(zip(keys, level, strict=True))
        row["missions"] = len(group)
        for metric in metrics:
            values = group[metric].to_numpy(float)
            row[f"{metric}_mean"] = float(np.nanmean(values)) if values.size else float("nan")
            row[f"{metric}_ci95"] = ci95_half_width(values)
        rows.append(row)
    return pd.DataFrame(rows)


def write_summary(out: Path, summary: pd.DataFrame) -> Path:
    return atomic.write_with(out / SUMMARY, lambda tmp: summary.to_csv(tmp, index=False))
