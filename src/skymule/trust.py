"""Which model files the user trusts to run code as they load.

A stable-baselines3 ``.zip`` holds pickled Python objects (its ``data`` entry, the optimizer
and policy state): unpickling one can run any code its author put there. Scenario, sweep and
run files are shared, so a model a *file* names (``[policy] name = "rl:model.zip"``, a sweep
axis, ``--policies``) is loaded only when the user has said, on the command line, that they
trust that very file: ``--trust-model PATH`` (repeatable).

The opt-in travels in the environment variable :data:`TRUST_ENV` (absolute paths separated by
:data:`os.pathsep`) so that the local workers a sweep starts see it too; a remote Dask worker
needs it set on its own machine. The command line sets it for the duration of one command
(:func:`trusting`); a library caller may use :func:`trusting` or set the variable.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

from skymule.errors import SkymuleError

TRUST_ENV = "SKYMULE_TRUST_MODELS"
"""Environment variable listing the model files the user trusts (``os.pathsep``-separated)."""


def _canonical(path: str | os.PathLike[str]) -> str:
    return str(Path(path).expanduser().resolve())


def trusted_models() -> frozenset[str]:
    """The trusted model files (absolute, symlinks resolved)."""
    raw = os.environ.get(TRUST_ENV, "")
    return frozenset(_canonical(p) for p in raw.split(os.pathsep) if p)


def is_trusted(path: str | os.PathLike[str]) -> bool:
    """True when the user opted in to loading ``path`` (``--trust-model``)."""
    return _canonical(path) in trusted_models()


def check_trusted(name: str, path: Path) -> None:
    """Raise the one-line refusal unless the user trusts the model file ``path``."""
    if not is_trusted(path):
        raise SkymuleError(
            f"policy {name!r}: not loaded: a stable-baselines3 zip holds pickled Python "
            "objects, which run code as they load; if you trust where it comes from, "
            f"add --trust-model {path}"
        )


TRUST_HELP = (
    "Load this stable-baselines3 model for an rl:PATH policy. Its zip holds pickles, which "
    "run code as they load: only for files you trust (repeatable)."
)
"""Help of the ``--trust-model`` option of every command that runs policies."""


def trust_option(paths: list[Path] | None) -> list[Path] | None:
    """``--trust-model``'s callback: trust ``paths`` for the rest of the command."""
    trust(paths or ())
    return paths


def trust(paths: Iterable[str | os.PathLike[str]]) -> None:
    """Trust the model files ``paths`` from now on in this process and the workers it starts
    (what ``--trust-model`` does; :func:`trusting` limits it to a block)."""
    chosen = [_canonical(p) for p in paths]
    held = os.environ.get(TRUST_ENV)
    if chosen:
        os.environ[TRUST_ENV] = os.pathsep.join([*chosen, *([held] if held else [])])


@contextlib.contextmanager
def trusting(paths: Iterable[str | os.PathLike[str]] = ()) -> Iterator[None]:
    """Trust the model files ``paths`` inside the block; afterwards exactly the files trusted
    before it (also those :func:`trust` added inside)."""
    saved = os.environ.get(TRUST_ENV)
    trust(paths)
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop(TRUST_ENV, None)
        else:
            os.environ[TRUST_ENV] = saved
