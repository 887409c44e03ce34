"""Where the commands print tables and messages.

``console`` (stdout) is made on first use: ``skymule --help`` and completion never import
rich's console. Tests assign a console of a chosen width to ``skymule.cli.output.console``.
"""

from __future__ import annotations

import json
import sys
from typing import Any


def __getattr__(name: str) -> Any:
    if name != "console":
        raise AttributeError(name)
    from rich.console import Console

    made = Console()
    globals()["console"] = made  # made once per process, like sys.stdout
    return made


def say(message: str) -> None:
    """Print one message line as it is: no markup, no highlighting, and never folded at the
    terminal's width, so the paths in it can be copied (or piped) whole."""
    # the module attribute (made on first use by __getattr__, or a test's console)
    sys.modules[__name__].console.print(message, markup=False, highlight=False, soft_wrap=True)


def print_json(data: Any) -> None:
    """Print ``data`` as indented JSON on stdout (numpy scalars as numbers)."""
    print(json.dumps(data, indent=2, default=_jsonable))


def _jsonable(value: Any) -> Any:
    if hasattr(value, "item"):  # numpy scalars
        return value.item()
    return str(value)
