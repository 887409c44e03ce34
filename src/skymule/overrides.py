"""``--set key=value``: dotted scenario keys applied to a scenario's TOML tables.

``sensors[2].buffer_mbit=900`` or ``policy.params.max_hover_s=30``: the key is a dotted path
with ``[i]`` list indices, the value a TOML value (a bare word is read as a string). The
result is validated like a file, so a bad value gets the same one-line error.
"""

from __future__ import annotations

import re
from typing import Any

from skymule.errors import ScenarioError
from skymule.io.textfiles import parse_toml

_KEY_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_-]*)((?:\[\d+\])*)")


def parse_override_key(key: str) -> list[str | int]:
    """``sensors[2].buffer_mbit`` -> ``["sensors", 2, "buffer_mbit"]`` (one-line error if bad)."""
    path: list[str | int] = []
    for part in key.split("."):
        match = _KEY_PART.fullmatch(part.strip())
        if match is None:
            raise ScenarioError(
                f"--set {key!r}: not a scenario key; use dotted names with [i], "
                "e.g. sensors[2].buffer_mbit or policy.params.max_hover_s"
            )
        path.append(match.group(1))
        path.extend(int(i) for i in re.findall(r"\[(\d+)\]", match.group(2)))
    return path


def parse_override_value(text: str) -> Any:
    """A TOML value (``3``, ``1.5``, ``true``, ``[1, 2]``, ``"a"``); a bare word is a string."""
    try:
        return parse_toml(f"v = {text}")["v"]
    except ValueError:  # tomllib.TOMLDecodeError, or nested too deeply
        return text.strip()


def apply_override(data: dict[str, Any], override: str) -> dict[str, Any]:
    """``data`` (a scenario's TOML tables) with one ``key=value`` override applied."""
    key, sep, value = override.partition("=")
    if not sep or not key.strip():
        raise ScenarioError(f"--set {override!r}: expected key=value, e.g. seed=3")
    path = parse_override_key(key.strip())
    if len(path) >= 2 and path[-2] == "params":
        # an older flat key next to [params] would override the value set here
        data = _assign(data, path[:-2], _without(_lookup(data, path[:-2]), path[-1]), key)
    return _assign(data, path, parse_override_value(value), key.strip())


def _lookup(data: Any, path: list[str | int]) -> Any:
    for part in path:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _without(section: Any, key: str | int) -> Any:
    return {k: v for k, v in section.items() if k != key} if isinstance(section, dict) else section


def _assign(node: Any, path: list[str | int], value: Any, key: str) -> Any:
    if not path:
        return value
    head, rest = path[0], path[1:]
    if isinstance(head, int):
        if not isinstance(node, list) or not 0 <= head < len(node):
            size = len(node) if isinstance(node, list) else 0
            raise ScenarioError(f"--set {key}: index [{head}] is out of range (0..{size - 1})")
        copy = list(node)
        copy[head] = _assign(node[head], rest, value, key)
        return copy
    if node is None:
        node = {}
    if not isinstance(node, dict):
        raise ScenarioError(f"--set {key}: {head!r} is inside a value, not a table")
    return {**node, head: _assign(node.get(head), rest, value, key)}
