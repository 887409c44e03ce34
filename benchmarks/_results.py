"""The benchmarks' saved results: ``python benchmarks/bench_X.py --json PATH``.

Every benchmark takes ``--json PATH`` and writes its tables there, in the one format that
``scripts/render_tables.py`` turns into the tables of README.md and docs/*.md::

    {"tables": {NAME: {"columns": [...], "rows": [[...], ...], "note": "..."}}}

Cells are text, formatted as the page prints them; ``note`` (optional) is a paragraph under
the table, ``align`` (optional) one ``l`` or ``r`` per column. The saved outputs the pages
show live in ``benchmarks/results/NAME.json``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

Table = dict[str, Any]


def json_option(argv: list[str] | None = None) -> Path | None:
    """The ``PATH`` of ``--json PATH`` (or ``--json=PATH``), taken out of ``argv``
    (``sys.argv`` by default) so that the benchmark's own argument parsing never sees it."""
    args = sys.argv if argv is None else argv
    for i, word in enumerate(args):
        if word == "--json":
            if i + 1 >= len(args):
                raise SystemExit("--json needs a PATH: the JSON file to write the tables to")
            path = args[i + 1]
            del args[i : i + 2]
            return Path(path)
        if word.startswith("--json="):
            del args[i]
            return Path(word.split("=", 1)[1])
    return None


def table(
    columns: Sequence[str],
    rows: Sequence[Sequence[object]],
    note: str = "",
    align: str | None = None,
) -> Table:
    """One table: ``rows`` of cells (printed with ``str``) under ``columns``."""
    out: Table = {"columns": list(columns), "rows": [[str(c) for c in row] for row in rows]}
    if any(len(row) != len(columns) for row in out["rows"]):
        raise ValueError(f"every row needs {len(columns)} cells: {out['rows']}")
    if note:
        out["note"] = note
    if align is not None:
        out["align"] = align
    return out


def dumps(tables: dict[str, Table]) -> str:
    """The results file's text: one row a line, so that a re-run's diff shows what moved."""
    parts = []
    for name, t in tables.items():
        fields = [f'   "columns": {json.dumps(t["columns"], ensure_ascii=False)}']
        rows = ",\n".join(f"    {json.dumps(row, ensure_ascii=False)}" for row in t["rows"])
        fields.append(f'   "rows": [\n{rows}\n   ]')
        fields += [
            f"   {json.dumps(key)}: {json.dumps(t[key], ensure_ascii=False)}"
            for key in ("note", "align")
            if key in t
        ]
        parts.append(f"  {json.dumps(name)}: {{\n" + ",\n".join(fields) + "\n  }")
    return '{\n "tables": {\n' + ",\n".join(parts) + "\n }\n}\n"


def write(path: Path | None, tables: dict[str, Table], merge_on: int = 0) -> None:
    """Write ``tables`` to ``path`` (nothing when ``path`` is None), atomically.

    ``merge_on=k`` keeps the rows of a table already in the file whose first ``k`` cells no
    new row has (runs of different sizes filling one table), sorted by those cells."""
    if path is None:
        return
    if merge_on and path.exists():
        old = json.loads(path.read_text(encoding="utf-8"))["tables"]
        for name, t in tables.items():
            if name in old:
                keys = {tuple(row[:merge_on]) for row in t["rows"]}
                kept = [row for row in old[name]["rows"] if tuple(row[:merge_on]) not in keys]
                t["rows"] = sorted([*kept, *t["rows"]], key=lambda r: _order(r[:merge_on]))
    json.loads(dumps(tables))  # what is written parses
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(dumps(tables), encoding="utf-8")
    temporary.replace(path)
    print(f"tables {', '.join(tables)} written to {path}", file=sys.stderr)


def _order(cells: list[str]) -> tuple[tuple[float, bool, str], ...]:
    """Sort key: numbers (``1,000``) by value, then text (code, in backticks, last)."""
    key = []
    for cell in cells:
        try:
            key.append((float(cell.replace(",", "")), False, ""))
        except ValueError:
            key.append((float("inf"), cell.startswith("`"), cell))
    return tuple(key)
