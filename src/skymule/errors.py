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


class Terminated(KeyboardInterrupt):
    """A SIGTERM (``kill``, a batch system's time limit), handled as a Ctrl-C is: outputs are
    left whole, the command prints its one line and exits with status 143 (128 + 15)."""


def interrupt_exit_status(interrupt: KeyboardInterrupt) -> int:
    """The shell's exit status for a command ended by this interrupt: 130 for SIGINT (Ctrl-C),
    143 for SIGTERM."""
    return 143 if isinstance(interrupt, Terminated) else 130
