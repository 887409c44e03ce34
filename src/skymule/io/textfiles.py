"""Reading a user's text file (scenario, sweep, run JSON) into a string, or one clear error.

Every way reading can fail (missing, a folder, unreadable, not UTF-8) becomes a
:class:`~skymule.errors.SkymuleError` naming the file, so no caller shows a traceback for it.
"""

from __future__ import annotations

import json
import math
import re
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


MAX_NESTING = 100
"""Deepest nesting of lists and tables a JSON or TOML file may have. skymule's own files
nest fewer than 20 levels (a radio map with a prior map); 0.1 MB of ``[[[...`` nests 50,000,
which Python's parsers meet with a RecursionError (or, with a raised recursion limit, by
exhausting the C stack)."""

_TOO_DEEP = f"nested more than {MAX_NESTING} levels deep (a damaged or hostile file)"
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_NOT_BRACKET = bytes(set(range(256)) - set(b"[]{}"))


def _json_depth(text: str) -> int:
    """The deepest ``[``/``{`` nesting of a JSON text, strings left out (no parsing)."""
    import numpy as np  # here: reading a scenario (TOML) needs no numpy

    code = np.frombuffer(
        _JSON_STRING.sub("", text).encode("utf-8", "replace").translate(None, _NOT_BRACKET),
        np.uint8,
    )
    steps = np.zeros(code.size, np.int64)
    steps[(code == ord("[")) | (code == ord("{"))] = 1
    steps[(code == ord("]")) | (code == ord("}"))] = -1
    return int(np.cumsum(steps).max(initial=0))


def _depth(value: Any) -> int:
    """The nesting depth of parsed lists and dicts (iterative: no recursion)."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, level + 1)
            if deepest > MAX_NESTING:
                return deepest
            stack.extend((child, level + 1) for child in item if isinstance(child, dict | list))
    return deepest


def parse_json(text: str) -> Any:
    """``json.loads(text)``; a document nested more than :data:`MAX_NESTING` levels is
    refused as :class:`JsonError` (a ValueError) before it is parsed.

    Every reader of a JSON file a user gives (radio maps, GeoJSON fences, ``.plan`` files,
    run folders, ``sweep.json``) parses through here, so 0.1 MB of ``[[[...`` is one line.
    """
    if _json_depth(text) > MAX_NESTING:
        raise JsonError(_TOO_DEEP)
    try:
        return json.loads(text)
    except RecursionError:
        raise JsonError(_TOO_DEEP) from None


def read_json(path: Path, what: str = "file") -> Any:
    """The parsed JSON of ``path``; one-line SkymuleError naming the file if it cannot be read
    or parsed (:func:`read_text`, :func:`parse_json`)."""
    text = read_text(path, what)
    try:
        return parse_json(text)
    except ValueError as exc:
        raise SkymuleError(f"{what} {str(path)!r}: not valid JSON ({exc})") from None


def parse_toml(text: str) -> dict[str, Any]:
    """``tomllib.loads(text)``; nesting deeper than :data:`MAX_NESTING` levels is refused as
    a ValueError, as ``tomllib.TOMLDecodeError`` is (tomllib is pure Python: it recurses,
    it does not exhaust the C stack)."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ValueError(_TOO_DEEP) from None
    if _depth(data) > MAX_NESTING:  # parsed under a raised recursion limit: still refused
        raise ValueError(_TOO_DEEP)
    return data


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
