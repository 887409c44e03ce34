"""Where the commands print tables and messages."""

from __future__ import annotations

from rich.console import Console

console: Console = Console()
"""stdout; tests swap it for a console of a chosen width (``skymule.cli.output.console``)."""
