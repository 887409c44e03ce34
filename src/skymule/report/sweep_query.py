"""The statistics of a sweep report, computed out of core by DuckDB over ``results.parquet``.

A sweep of ten million missions does not fit in a pandas frame on a laptop; DuckDB reads the
Parquet file column by column, aggregates in parallel and spills to disk past its memory
limit. Chosen over streaming pyarrow by measurement on 10,000,000 rows (2-core machine,
``benchmarks/bench_sweep.py`` README table): the per-policy means and standard deviations
took 1.6 s CPU and 172 MiB (pyarrow batches: 8.3 s, 188 MiB) and the paired gains, a
group-by over 5,000,000 parameter sets, 11 s CPU and 599 MiB (pyarrow's in-memory group-by
and join: 49 s CPU, 3.5 GiB).

Quantiles are exact (``quantile_cont``: numpy's linear interpolation); an empirical CDF of
more than ``EXACT_VALUES`` values is drawn from a histogram of ``ECDF_BINS`` equal bins
between its least and largest value (exact at each bin's upper edge; 2,000 quantiles instead
cost ten times the CPU of the whole rest of the report), and the strip of dots shows a
reservoir sample of ``DOTS`` missions per policy.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

#: Values per policy up to which an ECDF is drawn through every value (else quantiles).
EXACT_VALUES = 20_000
ECDF_BINS = 2_000
#: Missions per policy drawn as dots in the strip (all of them up to this many).
DOTS = 3_000
#: Memory DuckDB may use before it spills to disk.
MEMORY_LIMIT = "512MB"


def quoted(name: str) -> str:
    """A column name as a SQL identifier."""
    return '"' + name.replace('"', '""') + '"'


def literal(text: str) -> str:
    """A SQL string literal."""
    return "'" + text.replace("'", "''") + "'"


def finite(expression: str) -> str:
    """``expression`` as a double, NULL when it is not finite (NaN, inf or NULL)."""
    value = f"CAST({expression} AS DOUBLE)"
    return f"CASE WHEN isfinite({value}) THEN {value} END"


@dataclass(frozen=True)
class Distribution:
    """One policy's values of a metric: box statistics, an ECDF and the dots to draw."""

    n: int
    mean: float
    box: dict[str, float]  # med, q1, q3, whislo, whishi (matplotlib's bxp keys)
    ecdf_x: np.ndarray
    ecdf_y: np.ndarray
    dots: np.ndarray


@dataclass(frozen=True)
class Moments:
    """Count, mean and sample standard deviation of a group of values."""

    n: int
    mean: float
    std: float


@contextmanager
def results_query(path: Path, schema: pa.Schema) -> Iterator[ResultsQuery]:
    """Queries over ``path`` while in the block (DuckDB and its spill folder closed after)."""
    query = ResultsQuery(path, schema)
    try:
        yield query
    finally:
        query.close()


class ResultsQuery:
    """Queries over one ``results.parquet`` (see :func:`results_query`)."""

    def __init__(self, path: Path, schema: pa.Schema) -> None:
        import duckdb

        self.schema = schema
        self._scratch = tempfile.TemporaryDirectory(prefix="skymule-report-")
        self.con = duckdb.connect(
            ":memory:",
            config={
                "threads": os.cpu_count() or 1,
                "memory_limit": MEMORY_LIMIT,
                "temp_directory": self._scratch.name,
            },
        )
        self.con.execute(
            "CREATE VIEW results AS SELECT * FROM "
            f"read_parquet({literal(str(path))}, file_row_number = true)"
        )

    def close(self) -> None:
        self.con.close()
        self._scratch.cleanup()

    def rows(self, sql: str, *params: Any) -> list[tuple[Any, ...]]:
        return self.con.execute(sql, list(params)).fetchall()

    def distinct(self, column: str) -> list[str]:
        """The distinct values of a column as text, sorted."""
        sql = f"SELECT DISTINCT CAST({quoted(column)} AS VARCHAR) AS v FROM results ORDER BY v"
        return [str(v) for (v,) in self.rows(sql) if v is not None]

    def values(self, expression: str, where: str = "TRUE", *params: Any) -> np.ndarray:
        """Every finite value of ``expression`` in the rows ``where`` holds, sorted."""
        sql = (
            f"SELECT x FROM (SELECT {finite(expression)} AS x FROM results WHERE {where}) "
            "WHERE x IS NOT NULL ORDER BY x"
        )
        return np.array([v for (v,) in self.rows(sql, *params)], float)

    def quantiles(
        self, expression: str, probs: Sequence[float], where: str = "TRUE"
    ) -> list[float]:
        sql = (
            f"SELECT quantile_cont(x, {list(map(float, probs))}) FROM "
            f"(SELECT {finite(expression)} AS x FROM results WHERE {where}) WHERE x IS NOT NULL"
        )
        (found,) = self.rows(sql)[0]
        return [float(v) for v in found] if found is not None else []

    def distribution(self, metric: str, policy_column: str) -> dict[str, Distribution]:
        """Per policy: box statistics (as matplotlib's ``boxplot``), ECDF and dots."""
        x, policy = finite(quoted(metric)), f"CAST({quoted(policy_column)} AS VARCHAR)"
        found = self.rows(
            f"SELECT p, count(x), avg(x), quantile_cont(x, [0.25, 0.5, 0.75]), min(x), max(x) "
            f"FROM (SELECT {policy} AS p, {x} AS x FROM results) WHERE x IS NOT NULL GROUP BY p"
        )
        out = {}
        for p, n, mean, (q1, med, q3), least, largest in found:
            where = f"{policy} = ?"
            low, high = q1 - 1.5 * (q3 - q1), q3 + 1.5 * (q3 - q1)
            ((whislo, whishi),) = self.rows(
                f"SELECT min(x) FILTER (WHERE x >= ?), max(x) FILTER (WHERE x <= ?) FROM "
                f"(SELECT {x} AS x FROM results WHERE {where})",
                low,
                high,
                p,
            )
            box = {"med": med, "q1": q1, "q3": q3, "whislo": whislo, "whishi": whishi}
            if n <= EXACT_VALUES:
                ecdf_x = self.values(quoted(metric), where, p)
                ecdf_y = np.arange(1, n + 1) / n
                dots = ecdf_x if n <= DOTS else self.sample(metric, where, p)
            else:
                source = (
                    f"SELECT x FROM (SELECT {x} AS x FROM results WHERE {where}) "
                    "WHERE x IS NOT NULL"
                )
                ecdf_x, ecdf_y = self.histogram_ecdf(source, least, largest, p)
                dots = self.sample(metric, where, p)
            out[str(p)] = Distribution(int(n), float(mean), box, ecdf_x, ecdf_y, dots)
        return out

    def histogram_ecdf(
        self, source: str, least: float, largest: float, *params: Any
    ) -> tuple[np.ndarray, np.ndarray]:
        """The ECDF of column ``x`` of the query ``source`` at the upper edges of
        ``ECDF_BINS`` equal bins from ``least`` to ``largest`` (one pass, one small group-by)."""
        if not largest > least:
            return np.array([least], float), np.array([1.0])
        width = (largest - least) / ECDF_BINS
        found = self.rows(
            f"SELECT LEAST(CAST(floor((x - {float(least)!r}) / {width!r}) AS BIGINT), "
            f"{ECDF_BINS - 1}) AS b, count(*) FROM ({source}) GROUP BY b ORDER BY b",
            *params,
        )
        bins = np.array([b for b, _ in found], float)
        counts = np.cumsum([c for _, c in found])
        return least + (bins + 1) * width, counts / counts[-1]

    def sample(self, metric: str, where: str, *params: Any) -> np.ndarray:
        """Up to ``DOTS`` finite values of ``metric`` in the rows ``where`` holds, at random."""
        sql = (
            f"SELECT x FROM (SELECT {finite(quoted(metric))} AS x FROM results WHERE {where}) "
            f"WHERE x IS NOT NULL USING SAMPLE reservoir({DOTS} ROWS) REPEATABLE (1)"
        )
        return np.array([v for (v,) in self.rows(sql, *params)], float)

    def moments(self, metric: str, groups: Sequence[str]) -> dict[tuple[Any, ...], Moments]:
        """Per combination of the SQL expressions ``groups``: count, mean and standard
        deviation of the finite values of ``metric``."""
        x = finite(quoted(metric))
        names = [f"g{i}" for i in range(len(groups))]
        selected = ", ".join(f"{g} AS {n}" for g, n in zip(groups, names, strict=True))
        found = self.rows(
            f"SELECT {', '.join(names)}, count(x), avg(x), stddev_samp(x) FROM "
            f"(SELECT {selected}, {x} AS x FROM results) GROUP BY {', '.join(names)}"
        )
        nan = float("nan")
        return {
            tuple(row[: len(names)]): Moments(
                int(row[-3]),
                nan if row[-2] is None else float(row[-2]),
                nan if row[-1] is None else float(row[-1]),
            )
            for row in found
        }

    def approx_distinct(self, expression: str) -> int:
        ((n,),) = self.rows(f"SELECT approx_count_distinct({expression}) FROM results")
        return int(n)
