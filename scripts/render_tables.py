"""Fill the tables of README.md and docs/*.md from the benchmarks' saved JSON.

Run from anywhere: ``python scripts/render_tables.py [--check] [--results DIR]``.

Every measured table sits between ``<!-- table:NAME -->`` and ``<!-- /table:NAME -->``; the
lines between the two markers are this script's, the rest of the page is never touched.
``NAME`` names a table of a JSON file in ``benchmarks/results/`` (several names joined by
``+`` render one table of their rows in turn, e.g. the speed table from several benchmarks).
Each benchmark writes that format with ``--json PATH`` (``benchmarks/_results.py``)::

    {"tables": {NAME: {"columns": [...], "rows": [[...], ...], "note": "...",
                       "align": "lrr..."}}}

``note`` (optional) is printed as a paragraph under the table; ``align`` (optional) holds one
``l`` or ``r`` per column, else a column is right-aligned when every cell is a number
(possibly signed, with a unit or a ``±``) or ``n/a``. A cell is printed as written.

To refresh a table: run its benchmark with ``--json benchmarks/results/NAME.json`` (each
benchmark's docstring says how long it takes), then this script. ``--check`` writes nothing
and exits 1, naming the page and table, when a page differs from what the JSON renders
(``tests/test_readme_tables.py`` runs it, so no table can drift from its saved output).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
OPEN, CLOSE = "<!-- table:", "<!-- /table:"
NUMERIC_START = "0123456789+-−."


class TableError(ValueError):
    """A results file or a page that cannot be rendered: the message names file and table."""


def pages(root: Path = ROOT) -> list[Path]:
    """The pages whose tables this script fills: README.md and docs/*.md."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def _check_table(name: str, table: Any, where: str) -> dict[str, Any]:
    """``table`` if it has the documented shape, else a :class:`TableError` naming it."""
    if not isinstance(table, dict) or not isinstance(table.get("columns"), list):
        raise TableError(f"{where}: table {name!r} needs a list 'columns'")
    width = len(table["columns"])
    rows = table.get("rows")
    if not isinstance(rows, list) or not all(isinstance(r, list) for r in rows):
        raise TableError(f"{where}: table {name!r} needs 'rows', a list of lists")
    for i, row in enumerate(rows):
        if len(row) != width:
            raise TableError(f"{where}: table {name!r} row {i} has {len(row)} cells, not {width}")
    align = table.get("align")
    if align is not None and (len(align) != width or set(align) - {"l", "r"}):
        raise TableError(f"{where}: table {name!r}: 'align' needs {width} letters l or r")
    if not isinstance(table.get("note", ""), str):
        raise TableError(f"{where}: table {name!r}: 'note' must be text")
    return table


def load_tables(folder: Path = RESULTS) -> dict[str, dict[str, Any]]:
    """Every table of every ``*.json`` in ``folder``, by name; a name in two files is refused."""
    tables: dict[str, dict[str, Any]] = {}
    origin: dict[str, str] = {}
    for path in sorted(folder.glob("*.json")):
        try:
            found = json.loads(path.read_text(encoding="utf-8"))["tables"]
        except (ValueError, KeyError, TypeError) as exc:
            raise TableError(f"{path.name}: not a results file ({exc})") from None
        if not isinstance(found, dict):
            raise TableError(f"{path.name}: 'tables' must map names to tables")
        for name, table in found.items():
            if name in tables:
                raise TableError(f"table {name!r} is in both {origin[name]} and {path.name}")
            tables[name] = _check_table(name, table, path.name)
            origin[name] = path.name
    return tables


def _numeric(cell: str) -> bool:
    return cell in ("", "n/a") or cell[0] in NUMERIC_START


def markdown(columns: list[str], rows: list[list[Any]], align: str | None = None) -> list[str]:
    """A GitHub markdown table of ``rows`` under ``columns``."""
    cells = [[str(c) for c in row] for row in rows]
    if align is None:
        align = "".join(
            "r" if cells and all(_numeric(row[i]) for row in cells) else "l"
            for i in range(len(columns))
        )
    rule = "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"
    lines = ["| " + " | ".join(row) + " |" for row in [list(columns), *cells]]
    return [lines[0], rule, *lines[1:]]


def render_block(spec: str, tables: dict[str, dict[str, Any]], where: str) -> list[str]:
    """The lines between the markers of ``spec`` (``NAME`` or ``NAME+NAME...``)."""
    names = spec.split("+")
    missing = [n for n in names if n not in tables]
    if missing:
        raise TableError(f"{where}: no table {missing[0]!r} in benchmarks/results/*.json")
    first = tables[names[0]]
    for name in names[1:]:
        if tables[name]["columns"] != first["columns"]:
            raise TableError(f"{where}: {name!r} has other columns than {names[0]!r}")
    rows = [row for name in names for row in tables[name]["rows"]]
    lines = markdown(first["columns"], rows, first.get("align"))
    for name in names:
        if tables[name].get("note"):
            lines += ["", tables[name]["note"]]
    return lines


def render(text: str, tables: dict[str, dict[str, Any]], page: str) -> str:
    """``text`` with the lines of every marked table replaced by what the JSON renders."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        out.append(line)
        i += 1
        if not (line.startswith(OPEN) and line.endswith(" -->")):
            continue
        spec = line[len(OPEN) : -len(" -->")]
        close = f"{CLOSE}{spec} -->"
        try:
            end = lines.index(close, i)
        except ValueError:
            raise TableError(f"{page}:{i}: {line} has no {close}") from None
        out += render_block(spec, tables, f"{page}:{i}")
        out.append(close)
        i = end + 1
    return "\n".join(out)


def changed_tables(old: str, new: str) -> list[str]:
    """The markers of the tables that differ between two renderings of a page."""
    a, b = old.split("\n"), new.split("\n")
    specs = [line for line in b if line.startswith(OPEN)]
    return [
        spec
        for spec in specs
        if a[a.index(spec) : a.index(spec.replace(OPEN, CLOSE, 1))]
        != b[b.index(spec) : b.index(spec.replace(OPEN, CLOSE, 1))]
    ]


def main(argv: list[str] | None = None) -> int:
    """Render every page's tables (or, with ``--check``, report the ones that differ)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 on drift")
    parser.add_argument("--results", type=Path, default=RESULTS, help="folder of *.json")
    parser.add_argument("--root", type=Path, default=ROOT, help="folder of README.md, docs/")
    args = parser.parse_args(argv)
    try:
        tables = load_tables(args.results)
        drift = []
        for page in pages(args.root):
            old = page.read_text(encoding="utf-8")
            new = render(old, tables, str(page.relative_to(args.root)))
            if new == old:
                continue
            if args.check:
                drift += [f"{page.relative_to(args.root)}: {s}" for s in changed_tables(old, new)]
            else:
                temporary = page.with_name(f".{page.name}.tmp")
                temporary.write_text(new, encoding="utf-8")
                temporary.replace(page)  # atomic: the page is the old one or the new one
                print(f"rendered {page.relative_to(args.root)}", file=sys.stderr)
    except TableError as exc:
        print(f"render_tables: {exc}", file=sys.stderr)
        return 2
    if drift:
        print("tables differ from benchmarks/results (run python scripts/render_tables.py):")
        print("\n".join(drift))
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
