"""Reading a user's text file (scenario, sweep, run JSON) into a string, or one clear error.

Every way reading can fail (missing, a folder, unreadable, not UTF-8) becomes a
:class:`~skymule.errors.SkymuleError` naming the file, so no caller shows a traceback for it.
"""

from __future__ import annotations

from pathlib import Path

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
