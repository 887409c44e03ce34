"""Writing files whole or not at all: every file skymule writes goes through here.

A file is written under a temporary name in its own folder (so the rename stays on one file
system) and renamed into place with :func:`os.replace`, which POSIX and Windows make atomic:
a reader, a Ctrl-C, a full disk or a file-size limit (``RLIMIT_FSIZE``) sees the previous
complete file or the new complete one, never half of it. A write that fails removes its
temporary file. Several files that belong together (a report and its figures) are written
into a staging folder and moved into place by :func:`commit_staged` with Ctrl-C held back
until the last rename.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import threading
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from skymule.errors import Terminated


def temporary_path(path: Path) -> Path:
    """A hidden name next to ``path`` that no other writer (process or host) uses."""
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp")


@contextlib.contextmanager
def atomic_path(path: Path, *, sync: bool = False) -> Iterator[Path]:
    """Yield a temporary path to write ``path``'s new content to; renamed into place when the
    block ends normally, removed when it raises (Ctrl-C included). ``sync``: flush it to disk
    before the rename (for files a resume relies on)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_path(path)
    try:
        yield tmp
        if sync:
            with open(tmp, "rb") as handle:
                os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as exc:  # name the file the user knows, not the temporary one (or none)
        raise _renamed(exc, {str(tmp): str(path), "": str(path)}) from None
    finally:
        tmp.unlink(missing_ok=True)


def _renamed(exc: OSError, names: dict[str, str]) -> OSError:
    """``exc`` with its file name mapped through ``names`` (a prefix for folders; ``""`` names
    an error that has none, such as a write past a file-size limit)."""
    if exc.errno is None:
        return exc
    filename = str(exc.filename) if exc.filename is not None else ""
    for old, new in names.items():
        if (filename.startswith(old) and old) or filename == old:
            return type(exc)(exc.errno, exc.strerror, new + filename[len(old) :])
    return exc


def write_text(path: Path, text: str, encoding: str = "utf-8") -> Path:
    """Replace ``path`` with ``text`` in one step; returns ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return path


def write_bytes(path: Path, data: bytes, *, sync: bool = False) -> Path:
    """Replace ``path`` with ``data`` in one step (``sync``: on disk before the rename);
    returns ``path``."""
    with atomic_path(path, sync=sync) as tmp:
        tmp.write_bytes(data)
    return path


def write_with(path: Path, writer: Callable[[Path], Any]) -> Path:
    """Replace ``path`` with what ``writer(tmp)`` writes to a temporary path (e.g. a
    DataFrame's ``to_csv``, a figure's ``savefig``); returns ``path``."""
    with atomic_path(path) as tmp:
        writer(tmp)
    return path


@contextlib.contextmanager
def ctrl_c_deferred() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) or SIGTERM back until the block is done, then raise it as
    :class:`KeyboardInterrupt` (:class:`~skymule.errors.Terminated` for SIGTERM): renames that
    belong together all happen. Outside the main thread (where signals cannot be handled) a
    no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {
        number: signal.signal(number, lambda number, frame: caught.append(number))
        for number in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    if signal.SIGTERM in caught:
        raise Terminated
    if caught:
        raise KeyboardInterrupt


_TEMPORARY = re.compile(r"\.(?P<what>.+)\.(?P<pid>\d+)\.[0-9a-f]{12}\.tmp")
"""The names :func:`temporary_path` and :func:`staging_folder` give: ``.<what>.<pid>.<hex>.tmp``."""


def _pid_alive(pid: int) -> bool:
    """True when process ``pid`` runs on this host (or may: no permission to ask)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True
    return True


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files and staging folders in ``folder`` that a process killed
    mid-write left (SIGKILL runs no clean-up): those whose writer's pid no longer runs on
    this host. A live writer's, this process's and unknown names are kept; returns what was
    removed."""
    removed: list[Path] = []
    try:
        entries = list(folder.iterdir())
    except OSError:
        return removed
    for entry in entries:
        match = _TEMPORARY.fullmatch(entry.name)
        if match is None:
            continue
        pid = int(match["pid"])
        if pid == os.getpid() or _pid_alive(pid):
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
        removed.append(entry)
    return removed


@contextlib.contextmanager
def staging_folder(folder: Path, what: str = "staged") -> Iterator[Path]:
    """A hidden empty folder inside ``folder`` to write several files into; removed with what
    is left in it when the block ends (move the files out with :func:`commit_staged`).
    Staging folders and temporary files that killed processes left in ``folder`` are removed
    first (:func:`remove_stale_temporaries`)."""
    folder.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(folder)
    stage = folder / f".{what}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp"
    stage.mkdir()
    try:
        yield stage
    except OSError as exc:
        raise _renamed(exc, {str(stage): str(folder)}) from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def commit_staged(stage: Path, folder: Path, remove: tuple[Path, ...] = ()) -> list[Path]:
    """Move every file under ``stage`` to the same place under ``folder`` (one ``os.replace``
    each, folders made as needed) and delete ``remove``, with Ctrl-C held back until all is
    done; returns the files now in place. Files are moved deepest first, so a file at the top
    (the page that names the others) changes last."""
    files = sorted(
        (p for p in stage.rglob("*") if p.is_file()),
        key=lambda p: (-len(p.relative_to(stage).parts), str(p)),
    )
    placed = []
    with ctrl_c_deferred():
        for source in files:
            target = folder / source.relative_to(stage)
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(source, target)
            placed.append(target)
        for path in remove:
            path.unlink(missing_ok=True)
    return placed
