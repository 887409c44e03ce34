"""User-facing errors.

Every mistake a user can make in a scenario, trace, sweep file or CLI flag is raised as a
:class:`SkymuleError` whose message is one line naming the field or file, the bad value and
what is allowed. The CLI prints that line and exits with status 2; it never shows a traceback
for these.
"""

from __future__ import annotations


class SkymuleError(ValueError):
    """A user mistake: bad scenario, trace, sweep file or command-line argument."""


class ScenarioError(SkymuleError):
    """A scenario file (or preset) that does not validate."""
