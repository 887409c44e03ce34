"""Tables that never crop a value.

On a terminal wide enough, a rich table; on a narrow one, one block per row (``label  value``
lines), folded rather than cut if even that does not fit. Piped (not a terminal), plain
aligned text with every value in full, so ``skymule compare ... | grep`` sees every digit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Console


COLUMN_LABELS = {
    "total_downloaded_mbit": "Mbit",
    "completion": "done",
    "handovers": "switches",
    "hover_time_s": "hover s",
    "distance_m": "dist m",
    "energy_kj": "kJ",
    "aadm_score": "AADM",
    "gap_to_bound_mbit": "gap Mbit",
    "gap_to_bound_frac": "gap",
}
"""Short terminal headers (the files keep the full field names)."""

LEFT_ALIGNED = {"policy", "quantity", "source", "sensor", "value", "value_text"}
"""Columns read as text (numbers right-aligned); so is any column of text only."""
MIXED_COLUMNS = {"value"}
"""Columns whose rows are different quantities (``bound``'s quantity/value table): each cell
is formatted for itself."""
_GAP = 2


def decimals(values: Sequence[object]) -> int:
    """Decimals that show every number of one quantity alike: none when all are whole (a
    count, or a hover time of 0 and 155 s), else 1 from 10 up and 3 below (by the largest)."""
    numbers = [abs(v) for v in values if isinstance(v, float) and math.isfinite(v)]
    if all(v == int(v) for v in numbers):
        return 0
    return 1 if max(numbers) >= 10 else 3


def fmt(value: object, places: int | None = None) -> str:
    """A cell: a float with ``places`` decimals (default: :func:`decimals` of the value
    alone); None as empty."""
    if value is None:
        return ""
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        return f"{value:.{decimals([value]) if places is None else places}f}"
    return str(value)


def fmt_mean_ci(mean: float, half_width: float) -> str:
    """``mean ± half_width``, both with the mean's decimals (``134.7 ± 2.8``)."""
    places = decimals([float(mean), float(half_width)])
    return f"{fmt(float(mean), places)} ± {fmt(float(half_width), places)}"


def _is_text(value: object) -> bool:
    return value is None or (isinstance(value, str) and not value[:1].isdigit())


def left_aligned(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> set[str]:
    """The columns to align left: :data:`LEFT_ALIGNED` and those holding only words (a
    ``mean ± CI`` text is a number: right)."""
    texts = {c for c in columns if all(_is_text(r.get(c)) for r in rows)}
    return LEFT_ALIGNED | texts


def label(column: str) -> str:
    return COLUMN_LABELS.get(column, column)


def cells(rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> list[list[str]]:
    """The text of every cell; the numbers of one column with the same decimals."""
    places = {
        c: None if c in MIXED_COLUMNS else decimals([row.get(c) for row in rows]) for c in columns
    }
    return [[fmt(row.get(c, ""), places[c]) for c in columns] for row in rows]


def print_table(
    console: Console, title: str, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]
) -> None:
    """Print ``rows`` so that every value reads in full at any width."""
    if not console.is_terminal:
        console.print(
            plain_table(title, rows, columns),
            markup=False,
            highlight=False,
            crop=False,
            soft_wrap=True,
        )
        return
    table = _rich_table(title, rows, columns)
    wide = console.options.update_width(100_000)  # measure unclamped, then compare
    if console.measure(table, options=wide).maximum <= console.width:
        console.print(table)
    else:
        _print_vertical(console, title, rows, columns)


def plain_table(title: str, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> str:
    """Aligned plain text (for pipes and files): header, rule, one line per row."""
    body = cells(rows, columns)
    widths = [max([len(label(c))] + [len(r[i]) for r in body]) for i, c in enumerate(columns)]
    left = left_aligned(rows, columns)

    def line(values: Sequence[str]) -> str:
        parts = [
            v.ljust(w) if c in left else v.rjust(w)
            for v, w, c in zip(values, widths, columns, strict=True)
        ]
        return (" " * _GAP).join(parts).rstrip()

    header = line([label(c) for c in columns])
    rule = (" " * _GAP).join("-" * w for w in widths)
    return "\n".join([title, header, rule, *(line(r) for r in body)])


def _rich_table(title: str, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> Any:
    from rich import box
    from rich.table import Table

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    body = cells(rows, columns)
    left = left_aligned(rows, columns)
    for i, column in enumerate(columns):
        table.add_column(
            label(column),
            justify="left" if column in left else "right",
            no_wrap=True,
            min_width=max([len(label(column))] + [len(r[i]) for r in body]),
        )
    for row in body:
        table.add_row(*row)
    return table


def _print_vertical(
    console: Console, title: str, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]
) -> None:
    """One block per row: ``label  value`` lines; long values fold, never crop."""
    from rich.text import Text

    width = max(len(label(c)) for c in columns)
    console.print(Text(title, style="bold"))
    for values in cells(rows, columns):
        console.rule(style="dim")
        for column, value in zip(columns, values, strict=True):
            if value == "":
                continue
            console.print(Text(f"{label(column):<{width}}  {value}"), overflow="fold")
