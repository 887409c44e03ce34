"""The ``skymule`` command line.

The commands only parse arguments, call the library (:mod:`skymule.tasks.simulate`,
:mod:`skymule.tasks.compare`, :mod:`skymule.tasks.radiomaps`, ...) and print. User mistakes (bad
scenario, trace, flag) print one line and exit with status 2; the library raises
:class:`~skymule.errors.SkymuleError` for them and :func:`main` turns it into that line.
Anything else is a bug and keeps its traceback.

Heavy modules (numpy, pandas, the engines) are imported inside the commands, so that
``skymule --help`` and shell completion start fast.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

from skymule.cli import files, missions, resilience
from skymule.cli.app import app
from skymule.errors import SkymuleError, Terminated, interrupt_exit_status

# the commands, in the order `skymule --help` lists them
app.command()(missions.run)
app.command()(missions.compare)
app.command()(missions.bound)
app.command()(missions.sweep)
app.command()(missions.scenarios)
app.command()(resilience.resilience)
app.command()(files.plot)
app.command()(files.report)
app.command()(files.export)
app.command()(files.analyze)
app.command("fit-radiomap")(files.fit_radiomap_command)
app.command("score-radiomap")(files.score_radiomap_command)
app.command("sim2real")(files.sim2real_command)

__all__ = ["app", "main"]

INTERRUPTED = "skymule: interrupted; every file is left whole (the previous one, or none)"
"""The one line a Ctrl-C prints (outputs are written atomically: :mod:`skymule.io.atomic`)."""


def _raise_terminated(number: int, frame: FrameType | None) -> None:
    raise Terminated


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM ends a command as Ctrl-C does (temporary files removed, one line, resume hint),
    with status 143, instead of killing it mid-write. The caller's handler is put back (a
    test calling :func:`main` in-process keeps its own)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app, turning user mistakes into one line and exit status 2.

    Click handles bad flags itself (usage line, exit 2); library errors that are the
    user's doing arrive as SkymuleError.
    """
    from typer.exceptions import Abort, TyperException

    from skymule.trust import trusting

    try:
        # standalone_mode=False: Ctrl-C reaches the handler below instead of click's;
        # trusting(): a --trust-model holds for this one command
        with _sigterm_interrupts(), trusting():
            code = app(args=argv, standalone_mode=False)
    except Abort:
        print(INTERRUPTED, file=sys.stderr)
        sys.exit(130)
    except TyperException as exc:  # usage errors: click's usage line and message
        show = getattr(exc, "show", None)
        if callable(show):
            show()
        else:
            print(f"skymule: error: {exc.format_message()}", file=sys.stderr)
        sys.exit(exc.exit_code)
    except SkymuleError as exc:
        print(f"skymule: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except OSError as exc:
        # a file or folder the user named cannot be read or written (permissions, full disk)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"skymule: error: {where}{exc.strerror or exc}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt as interrupt:
        print(INTERRUPTED, file=sys.stderr)
        sys.exit(interrupt_exit_status(interrupt))
    if code == 130:  # typer turns a Ctrl-C inside a command into this exit code, silently
        print(INTERRUPTED, file=sys.stderr)
    if isinstance(code, int) and code != 0:
        sys.exit(code)
