"""Reading a user's text file (scenario, sweep, run JSON) into a string, or one clear error.

Every way reading can fail (missing, a folder, unreadable, not UTF-8) becomes a
:class:`~skymule.errors.SkymuleError` naming the file, so no caller shows a traceback for it.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from skymule.errors import SkymuleError


def read_text(path: Path, what: str = "file") -> str:
    """The file's text (UTF-8, a leading BOM dropped); one-line SkymuleError if unreadable.

    Args:
        path: the file.
        what: what the file is, for the message (e.g. ``"scenario"``, ``"sweep file"``).
    """
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise SkymuleError(f"{what} {str(path)!r}: no such file") from None
    except IsADirectoryError:
        raise SkymuleError(f"{what} {str(path)!r}: is a folder, expected a file") from None
    except UnicodeDecodeError as exc:
        raise SkymuleError(
            f"{path}: not a UTF-8 text file (bad byte 0x{exc.object[exc.start]:02x} at offset "
            f"{exc.start}); save it as UTF-8"
        ) from None
    except OSError as exc:
        raise SkymuleError(f"{path}: cannot read ({exc.strerror or exc})") from None


class JsonError(ValueError):
    """A text that is not a JSON document this reader accepts (a ValueError, as
    :class:`json.JSONDecodeError` is, so callers catching ValueError catch it)."""


def parse_json(text: str) -> Any:
    """``json.loads(text)``, with nesting too deep for Python's parser refused as
    :class:`JsonError` (a ValueError) instead of a RecursionError.

    Every reader of a JSON file a user gives (radio maps, GeoJSON fences, ``.plan`` files,
    run folders, ``sweep.json``) parses through here, so 0.1 MB of ``[[[...`` is one line.
    """
    try:
        return json.loads(text)
    except RecursionError:
        raise JsonError("nested too deeply to be read (a damaged or hostile file)") from None


def read_json(path: Path, what: str = "file") -> Any:
    """The parsed JSON of ``path``; one-line SkymuleError naming the file if it cannot be read
    or parsed (:func:`read_text`, :func:`parse_json`)."""
    text = read_text(path, what)
    try:
        return parse_json(text)
    except ValueError as exc:
        raise SkymuleError(f"{what} {str(path)!r}: not valid JSON ({exc})") from None


def parse_toml(text: str) -> dict[str, Any]:
    """``tomllib.loads(text)``, with nesting too deep for the parser refused as a ValueError
    (:class:`JsonError`'s sibling case; ``tomllib.TOMLDecodeError`` is a ValueError too)."""
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise ValueError("nested too deeply to be read (a damaged or hostile file)") from None


def json_safe(value: Any) -> Any:
    """``value`` with NaN and infinities as None, so ``json.dumps(..., allow_nan=False)``
    writes strict JSON (bare ``NaN`` is not JSON; other readers refuse it)."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
