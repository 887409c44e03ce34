"""The sweep result store: a locked folder, Parquet parts written atomically, resume, merging.

Layout of a sweep folder ``DIR``::

    DIR/sweep.json                       which sweep file it holds (sha256) and the id scheme
    DIR/.lock                            the operating system's lock while a sweep runs
    DIR/.lock.holder                     while a sweep runs: its pid, host and start time
    DIR/results/part-*.parquet ...       one part per finished chunk (unique tmp + os.replace)
    DIR/results.parquet                  every mission of the sweep exactly once, in order
    DIR/summary.csv                      per policy and swept value: missions, mean and 95% CI

A part is either complete or absent: each writer writes a temporary file under a name no other
writer uses and renames it into place, so the mission ids in the parts are exactly the missions
done. A part that cannot be read (a damaged disk, a stray file) is set aside as
``*.parquet.damaged`` on resume and its missions run again.

Nothing here holds a sweep in memory: resuming keeps one byte per mission (:class:`Done`),
and ``results.parquet`` and ``summary.csv`` are written by a streamed merge of the parts
(:func:`consolidate`).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import filelock
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from skymule.errors import SkymuleError
from skymule.io import atomic
from skymule.io.textfiles import parse_json
from skymule.metrics.summary import HEADLINE_METRICS

PARTS = "results"
RESULTS = "results.parquet"
SUMMARY = "summary.csv"
METADATA = "sweep.json"
LOCK = ".lock"
HOLDER = ".lock.holder"
SUMMARY_METRICS = HEADLINE_METRICS
ID_SCHEME = 2
"""Version of the mission-id scheme (1: sha256 of each resolved scenario's JSON, no sweep.json;
2: sha256 of the sweep identity plus the mission's axis values)."""


def part_paths(out: Path) -> list[Path]:
    return sorted((out / PARTS).glob("part-*.parquet"))


def read_part(path: Path, columns: list[str] | None = None) -> pa.Table:
    """A part (or some of its columns). Parts are small: one thread and no read-ahead cost
    a quarter of ``pq.read_table``'s CPU, which adds up over a sweep's thousands of parts."""
    return pq.ParquetFile(path, pre_buffer=False).read(columns, use_threads=False)


# --- one sweep per folder: the lock and the sweep file it belongs to ----------------------


@dataclass(frozen=True)
class Holder:
    """Who holds a folder's lock (written beside it, for the message a second sweep gets)."""

    pid: int
    host: str
    started: str


def _read_holder(path: Path) -> Holder:
    try:
        data = parse_json(path.read_text())
        return Holder(int(data["pid"]), str(data["host"]), str(data["started"]))
    except (OSError, ValueError, KeyError, TypeError):
        return Holder(-1, "?", "?")  # not written yet, or foreign


@contextlib.contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock while the block runs; a second sweep on it gets one clear line.

    The lock is the operating system's (``filelock``): it goes with the process that holds it,
    so a sweep that died leaves no lock to clean up. Its holder (pid, host, start time) is
    written to :data:`HOLDER` while it runs."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SkymuleError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    lock = filelock.FileLock(out / LOCK)
    try:
        lock.acquire(timeout=0)
    except filelock.Timeout:
        holder = _read_holder(out / HOLDER)
        raise SkymuleError(
            f"--out {out}: another sweep is using this folder (pid {holder.pid} on "
            f"{holder.host}, started {holder.started}); wait for it to finish"
        ) from None
    except OSError as exc:
        raise SkymuleError(f"--out {out}: cannot lock {out / LOCK} ({exc.strerror})") from None
    try:
        me = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        atomic.write_text(out / HOLDER, json.dumps(me))
        yield
    finally:
        (out / HOLDER).unlink(missing_ok=True)
        lock.release()


def claim(out: Path, digest: str, source: str) -> None:
    """Tie ``out`` to one sweep file (by ``digest``); refuse another file or older ids."""
    meta = out / METADATA
    if meta.exists():
        try:
            data = parse_json(meta.read_text())
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


def _sorted_table(frame: pd.DataFrame) -> pa.Table:
    """A chunk's rows as an Arrow table in mission order (no pandas index kept)."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    return table.sort_by("mission_index") if len(table) else table


def part_bytes(frame: pd.DataFrame) -> bytes:
    """A chunk's rows as the bytes of a part file (what a worker on another host returns)."""
    sink = pa.BufferOutputStream()
    pq.write_table(_sorted_table(frame), sink)
    return bytes(sink.getvalue().to_pybytes())


def _part_path(out: Path, first: int) -> Path:
    folder = out / PARTS
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"part-{first:012d}-{uuid.uuid4().hex[:12]}.parquet"


def write_part_bytes(out: Path, data: bytes) -> Path:
    """Store a part made elsewhere (:func:`part_bytes`), atomically, under a fresh name."""
    first = pq.read_metadata(pa.BufferReader(data)).row_group(0).column(0).statistics
    path = _part_path(out, int(first.min) if first is not None and first.has_min_max else 0)
    return atomic.write_bytes(path, data, sync=True)  # a resume trusts a part in place


def write_part(out: Path, frame: pd.DataFrame) -> Path:
    """Store one finished chunk as a new part (atomically, under a name no writer reuses)."""
    first = int(frame["mission_index"].min()) if len(frame) else 0
    path = _part_path(out, first)
    _atomic_parquet(_sorted_table(frame), path)
    return path


@dataclass(frozen=True)
class Done:
    """Missions already stored in a folder's parts, and the parts that could not be read.

    ``mask[i]`` is True when mission ``i`` is stored (one byte per mission up to the largest
    index stored: 10 MB for 10 million missions, where a set of their ids took ~1 GB).
    """

    mask: np.ndarray
    damaged: tuple[Path, ...]

    @property
    def count(self) -> int:
        return int(self.mask.sum())

    def which(self, indices: np.ndarray) -> np.ndarray:
        """True for each of ``indices`` already stored."""
        inside = indices < self.mask.size
        found = np.zeros(indices.shape, bool)
        found[inside] = self.mask[indices[inside]]
        return found


def done_ids(out: Path) -> set[str]:
    """Mission ids already stored in ``out``'s readable parts (for small folders: one Python
    string per mission)."""
    ids: set[str] = set()
    for path in part_paths(out):
        with contextlib.suppress(OSError, pa.ArrowException, KeyError):
            ids.update(read_part(path, ["mission_id"]).column(0).to_pylist())
    return ids


def scan(out: Path, *, set_aside: bool = False) -> Done:
    """Missions stored in ``out``'s parts; unreadable parts are listed (and renamed with
    ``set_aside``)."""
    indices = []
    damaged = []
    for path in part_paths(out):
        try:
            column = read_part(path, ["mission_index"]).column(0)
        except (OSError, pa.ArrowException, KeyError):
            damaged.append(path)
            if set_aside:
                os.replace(path, path.with_name(path.name + ".damaged"))
            continue
        indices.append(column.to_numpy())
    mask = np.zeros(max((int(i.max()) + 1 for i in indices if i.size), default=0), bool)
    for found in indices:
        mask[found] = True
    return Done(mask, tuple(damaged))


# --- consolidating: results.parquet and summary.csv, streamed -------------------------

#: Rows per bucket of the merge, and per row group of results.parquet (~5 MB of Arrow: the
#: merge holds a few copies of one bucket, so this bounds its memory).
BUCKET_ROWS = 1 << 14


@dataclass(frozen=True)
class _Part:
    path: Path
    buckets: tuple[int, ...]  # the buckets (mission_index // BUCKET_ROWS) it holds rows of


def _index_range(meta: pq.FileMetaData) -> tuple[int, int] | None:
    """Smallest and largest mission_index of a part from its footer (None: no statistics)."""
    column = meta.schema.to_arrow_schema().get_field_index("mission_index")
    lows, highs = [], []
    for group in range(meta.num_row_groups):
        stats = meta.row_group(group).column(column).statistics
        if stats is None or not stats.has_min_max:
            return None
        lows.append(int(stats.min))
        highs.append(int(stats.max))
    return (min(lows), max(highs)) if lows else None


def _survey(out: Path) -> tuple[list[_Part], pa.Schema]:
    """Which buckets each part feeds and the schema of all parts (footers, mostly)."""
    parts: list[_Part] = []
    schemas: dict[str, pa.Schema] = {}
    for path in part_paths(out):
        meta = pq.read_metadata(path)
        if meta.num_rows == 0:
            continue
        schema = meta.schema.to_arrow_schema().remove_metadata()
        schemas.setdefault(schema.to_string(), schema)
        span = _index_range(meta)
        if span is not None and span[0] // BUCKET_ROWS == span[1] // BUCKET_ROWS:
            buckets: tuple[int, ...] = (span[0] // BUCKET_ROWS,)
        else:
            index = read_part(path, ["mission_index"]).column(0).to_numpy()
            buckets = tuple(int(b) for b in np.unique(index // BUCKET_ROWS))
        parts.append(_Part(path, buckets))
    if not schemas:
        return parts, pa.schema([])
    return parts, pa.unify_schemas(list(schemas.values()), promote_options="permissive")


def _conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` with ``schema``'s columns, in its order and types (absent ones null)."""
    if table.schema.equals(schema, check_metadata=False):
        return table.replace_schema_metadata(None)
    columns = [
        table.column(field.name).cast(field.type)
        if field.name in table.column_names
        else pa.nulls(len(table), field.type)
        for field in schema
    ]
    return pa.Table.from_arrays(columns, schema=schema)


def _bucket(parts: list[_Part], bucket: int, schema: pa.Schema) -> pa.Table:
    """The rows of one bucket from every part, in mission order, each mission once."""
    low, high = bucket * BUCKET_ROWS, (bucket + 1) * BUCKET_ROWS
    tables = []
    for part in parts:
        table = read_part(part.path)
        if len(part.buckets) > 1:
            index = table.column("mission_index")
            table = table.filter(pc.and_(pc.greater_equal(index, low), pc.less(index, high)))
        tables.append(_conform(table, schema))
    merged = pa.concat_tables(tables).sort_by("mission_index")
    index = merged.column("mission_index").to_numpy()
    first = np.ones(index.size, bool)
    first[1:] = index[1:] != index[:-1]  # a mission stored twice (an orphaned worker's part)
    return merged if first.all() else merged.filter(pa.array(first))


@dataclass(frozen=True)
class Consolidated:
    """What :func:`consolidate` wrote: the number of rows and the summary (per policy and
    swept value)."""

    rows: int
    summary: pd.DataFrame


def consolidate(out: Path, levels: Sequence[str] = ()) -> Consolidated:
    """``results.parquet`` (every stored mission exactly once, in mission order) and the
    summary per policy and combination of the ``levels`` columns (:class:`SummaryStats`),
    streamed: memory holds one bucket of rows, never the sweep.

    The parts are merged bucket by bucket (``BUCKET_ROWS`` consecutive missions each, one row
    group of the output): a part is read for each bucket it holds rows of (once when its
    missions are consecutive, once per ``policy.*`` combination when a policy axis comes
    first in a product sweep). Row groups and the summary's order of additions follow the
    mission indices only, so the bytes do not depend on chunking, executor or resumes.
    """
    parts, schema = _survey(out)
    by_bucket: dict[int, list[_Part]] = {}
    for part in parts:
        for bucket in part.buckets:
            by_bucket.setdefault(bucket, []).append(part)
    summary = SummaryStats(levels)
    rows = 0
    with (
        atomic.atomic_path(out / RESULTS, sync=True) as tmp,
        pq.ParquetWriter(tmp, schema) as writer,
    ):
        for bucket in sorted(by_bucket):
            table = _bucket(by_bucket[bucket], bucket, schema)
            writer.write(table, row_group_size=BUCKET_ROWS)
            summary.add(table)
            rows += len(table)
    return Consolidated(rows, summary.table())


def ci95_half_width(values: np.ndarray) -> float:
    """Half-width of the 95% confidence interval of the mean (Student t; NaN for n < 2)."""
    values = values[np.isfinite(values)]
    if values.size < 2:
        return float("nan")
    return t_half_width(values.size, float(values.std(ddof=1)))


def t_half_width(n: int, std: float) -> float:
    """Half-width of the 95% CI of a mean of ``n`` values of sample std ``std`` (Student t)."""
    from scipy.special import stdtrit  # the t quantile scipy.stats.t.ppf uses; a light import

    if n < 2:
        return float("nan")
    return float(stdtrit(n - 1, 0.975) * std / np.sqrt(n))


Group = tuple[object, ...]
"""A summary row's key: the policy, then the value of each level column (None: null or NaN)."""


class SummaryStats:
    """Per policy and combination of the ``levels`` columns, per metric: count, mean and
    spread, added to batch by batch.

    Batches merge by Chan, Golub and LeVeque's pairwise update of (n, mean, M2) ("Updating
    formulae and a pairwise algorithm for computing sample variances", 1979), so a sweep of any
    size costs one batch of memory plus a few numbers per group (policies times swept values,
    a small number). Means are over the non-NaN values (an infinite value makes the mean
    infinite, as ``numpy.nanmean`` does); the CI is over the finite ones.
    """

    def __init__(self, levels: Sequence[str] = ()) -> None:
        self.levels = tuple(levels)
        self.keys: list[str] | None = None  # policy + the levels the rows have, at the first add
        self.metrics: list[str] | None = None
        self.stats: dict[Group, np.ndarray] = {}  # group -> rows n, mean, M2, +inf, -inf, rows

    def add(self, table: pa.Table) -> None:
        """Add a batch of result rows (a ``policy`` column, the level columns, the metrics)."""
        if "policy" not in table.column_names or not len(table):
            return
        if self.keys is None or self.metrics is None:
            self.keys = ["policy", *(c for c in self.levels if c in table.column_names)]
            self.metrics = [m for m in SUMMARY_METRICS if m in table.column_names]
        values = np.column_stack(
            [
                table.column(m).cast(pa.float64()).to_numpy(zero_copy_only=False)
                for m in self.metrics
            ]
            or [np.empty(len(table))]
        )[:, : len(self.metrics)]
        codes, groups = _group_codes(table, self.keys)
        for code, group in enumerate(groups):
            self._merge(group, values[codes == code])

    def _merge(self, group: Group, values: np.ndarray) -> None:
        finite = np.isfinite(values)
        n_b = finite.sum(axis=0).astype(float)
        # shifted by a value of the batch: equal values give their mean and M2 = 0 exactly
        shift = values[np.argmax(finite, axis=0), np.arange(values.shape[1])]
        shift = np.where(n_b > 0, shift, 0.0)
        centred = np.where(finite, values - shift, 0.0).sum(axis=0)
        mean_b = shift + np.divide(centred, n_b, out=np.zeros_like(n_b), where=n_b > 0)
        m2_b = (np.where(finite, values - mean_b, 0.0) ** 2).sum(axis=0)
        batch = np.stack(
            [
                n_b,
                mean_b,
                m2_b,
                (values == np.inf).sum(axis=0),
                (values == -np.inf).sum(axis=0),
                np.full(n_b.shape, len(values), float),
            ]
        )
        held = self.stats.get(group)
        if held is None:
            self.stats[group] = batch
            return
        n_a, mean_a, m2_a = held[0], held[1], held[2]
        n = n_a + n_b
        delta = mean_b - mean_a
        share = np.divide(n_b, n, out=np.zeros_like(n), where=n > 0)
        held[1] = mean_a + delta * share
        held[2] = m2_a + m2_b + delta**2 * n_a * share
        held[0] = n
        held[3:] += batch[3:]

    def table(self) -> pd.DataFrame:
        """One row per group, sorted by policy then level values (missing values last):
        the group's columns, missions, and mean and 95% CI half-width of each metric."""
        rows = []
        for group, (n, mean, m2, up, down, missions) in self.stats.items():
            row: dict[str, object] = dict(zip(self.keys or (), group, strict=True))
            row["missions"] = int(missions[0])
            for k, metric in enumerate(self.metrics or []):
                value = float(mean[k]) if n[k] > 0 else float("nan")
                if up[k] or down[k]:
                    value = float("nan") if up[k] and down[k] else (np.inf if up[k] else -np.inf)
                row[f"{metric}_mean"] = value
                std = float(np.sqrt(m2[k] / (n[k] - 1))) if n[k] > 1 else float("nan")
                row[f"{metric}_ci95"] = t_half_width(int(n[k]), std)
            rows.append(row)
        frame = pd.DataFrame(rows)
        if not rows:
            return frame
        # the order pandas' groupby(sort=True, dropna=False) gives; stable, so it never
        # depends on the order the groups were first met in
        ordered = frame.sort_values(self.keys or [], na_position="last", kind="stable")
        return ordered.reset_index(drop=True)


def _group_codes(table: pa.Table, keys: Sequence[str]) -> tuple[np.ndarray, list[Group]]:
    """Each row's group number, and the groups (tuples of ``keys`` values; a null or NaN
    value is None) in order of their numbers."""
    codes = np.zeros(len(table), np.int64)
    groups: list[Group] = [()]
    for key in keys:
        encoded = pc.dictionary_encode(table.column(key)).combine_chunks()
        values = [*(_plain(v) for v in encoded.dictionary.to_pylist()), None]
        index = encoded.indices.fill_null(len(values) - 1).to_numpy(zero_copy_only=False)
        # renumbered after each column, so a code stays below the number of rows
        present, codes = np.unique(codes * len(values) + index, return_inverse=True)
        groups = [groups[c // len(values)] + (values[c % len(values)],) for c in present.tolist()]
    return codes.reshape(-1), groups


def _plain(value: object) -> object:
    """A key value as a dictionary key: NaN (never equal to itself) as None, like a null."""
    return None if isinstance(value, float) and value != value else value


def summary_table(results: pd.DataFrame, levels: Sequence[str] = ()) -> pd.DataFrame:
    """Per policy and combination of the ``levels`` columns (the swept treatments, see
    :attr:`skymule.experiments.sweep.SweepSpec.level_columns`): number of missions, and mean
    and 95% CI half-width of each metric."""
    stats = SummaryStats(levels)
    stats.add(pa.Table.from_pandas(results, preserve_index=False))
    return stats.table()


def summary_of(path: Path, levels: Sequence[str] = ()) -> pd.DataFrame:
    """:func:`summary_table` of a results.parquet, read one row group at a time."""
    file = pq.ParquetFile(path)
    names = file.schema_arrow.names
    columns = [c for c in ("policy", *levels, *SUMMARY_METRICS) if c in names]
    stats = SummaryStats(levels)
    for group in range(file.num_row_groups):
        stats.add(file.read_row_group(group, columns))
    return stats.table()


def write_summary(out: Path, summary: pd.DataFrame) -> Path:
    return atomic.write_with(out / SUMMARY, lambda tmp: summary.to_csv(tmp, index=False))
