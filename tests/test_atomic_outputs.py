"""Outputs are whole or absent (issue 24): one atomic writer, a report staged and committed
together, Ctrl-C and a file-size limit leaving the previous report as it was."""

from __future__ import annotations

import ast
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import skymule
from conftest import run_cli
from skymule.errors import Terminated, interrupt_exit_status
from skymule.io import atomic

PACKAGE = Path(skymule.__file__).parent
WRITERS = {
    "write_text",
    "write_bytes",
    "savefig",
    "to_csv",
    "to_parquet",
    "write_table",
    "ParquetWriter",  # a file written a row group at a time: named when the writer opens
}
"""Calls that write a file (their first argument is the path)."""
LIVE_FILES = {
    ("aadm/files.py", "DownloadLogWriter.__init__"): "the controller's log, appended a row a poll",
    ("experiments/store.py", "locked"): "the lock file, created exclusively (O_EXCL)",
    ("experiments/store.py", "part_bytes"): "no file: a part's bytes in memory (remote workers)",
}
"""Writes not through a temporary path on purpose (files written in place), and why."""


def _writes(tree: ast.AST) -> list[tuple[str, ast.Call]]:
    """(enclosing function, call) of every file write not through a temporary path."""
    found: list[tuple[str, ast.Call]] = []

    def visit(node: ast.AST, where: str) -> None:
        for child in ast.iter_child_nodes(node):
            name = where
            if isinstance(child, ast.FunctionDef | ast.ClassDef):
                name = f"{where}.{child.name}" if where else child.name
            if isinstance(child, ast.Call) and isinstance(child.func, ast.Attribute):
                attr = child.func.attr
                helper = isinstance(child.func.value, ast.Name) and child.func.value.id == "atomic"
                to_tmp = any(isinstance(a, ast.Name) and a.id == "tmp" for a in child.args)
                if attr in WRITERS and child.args and not (helper or to_tmp):
                    found.append((name, child))
                modes = [a.value for a in child.args if isinstance(a, ast.Constant)]
                if attr in ("open", "fdopen") and any(m in ("w", "a", "x") for m in modes):
                    found.append((name, child))
            visit(child, name)

    visit(tree, "")
    return found


def test_every_file_is_written_through_the_atomic_helper() -> None:
    in_place = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = path.relative_to(PACKAGE).as_posix()
        if module == "io/atomic.py":
            continue
        for where, call in _writes(ast.parse(path.read_text(encoding="utf-8"))):
            if (module, where) not in LIVE_FILES:
                in_place.append(f"{module}:{call.lineno} ({where})")
    assert not in_place, f"write these through skymule.io.atomic: {in_place}"


def test_a_failed_write_keeps_the_previous_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = atomic.write_text(tmp_path / "summary.json", "old")

    def half_then_fail(tmp: Path) -> None:
        tmp.write_text("ne")
        raise OSError(27, "File too large", str(tmp))

    with pytest.raises(OSError) as caught:
        atomic.write_with(target, half_then_fail)
    assert caught.value.filename == str(target)  # the user's file, not the temporary one
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]
    with pytest.raises(KeyboardInterrupt), atomic.atomic_path(target) as tmp:
        tmp.write_text("new")
        raise KeyboardInterrupt
    assert target.read_text() == "old" and len(list(tmp_path.iterdir())) == 1


def test_ctrl_c_is_held_back_until_related_renames_are_done(tmp_path: Path) -> None:
    done = []
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal
    with pytest.raises(KeyboardInterrupt), atomic.ctrl_c_deferred():
        os.kill(os.getpid(), signal.SIGINT)
        done.append("renamed")  # still runs: the Ctrl-C waits for the block's end
    assert done == ["renamed"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    signal.signal(signal.SIGINT, before)


def test_sigterm_is_held_back_too_and_ends_as_terminated(tmp_path: Path) -> None:
    done = []
    before = signal.signal(signal.SIGTERM, signal.SIG_DFL)  # would kill pytest if not held
    try:
        with pytest.raises(Terminated), atomic.ctrl_c_deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            done.append("renamed")
        assert done == ["renamed"]
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # put back
    finally:
        signal.signal(signal.SIGTERM, before)
    assert interrupt_exit_status(Terminated()) == 143
    assert interrupt_exit_status(KeyboardInterrupt()) == 130


@pytest.fixture(scope="module")
def reported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short run folder with its report (no PDFs)."""
    run = tmp_path_factory.mktemp("atomic") / "run"
    done = run_cli("run", "paper-sim-fixed", "--out", run, "--set", "mission.duration_s=60")
    assert done.returncode == 0, done.stderr
    assert run_cli("report", run, "--no-pdf").returncode == 0
    return run


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_ctrl_c_during_a_report_prints_one_line_and_keeps_the_previous_one(
    reported: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import skymule.report.html as report_html

    run = tmp_path / "run"
    shutil.copytree(reported, run)
    before = _snapshot(run)
    drawn = []
    real = report_html.render_panel

    def interrupted_later(*args: object, **kwargs: object) -> object:
        if drawn:  # the first panel is written, then the user presses Ctrl-C
            raise KeyboardInterrupt
        drawn.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(report_html, "render_panel", interrupted_later)
    done = run_cli("report", run)  # with PDFs: would add files, were it not interrupted
    assert done.returncode == 130
    assert done.stderr.strip().splitlines() == [
        "skymule: interrupted; every file is left whole (the previous one, or none)"
    ]
    assert drawn and _snapshot(run) == before  # no new figure, no half report, no staging


# SIGINT as a terminal gives it (a test runner's worker may have it ignored; that is inherited)
CLI = (
    "import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "from skymule.cli import main; main()"
)


def _limited_report(folder: Path, limit: int) -> subprocess.CompletedProcess[str]:
    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return subprocess.run(
        [sys.executable, "-c", CLI, "report", str(folder), "--no-pdf"],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=cap,
    )


def test_a_file_size_limit_leaves_no_truncated_report(reported: Path, tmp_path: Path) -> None:
    """The audit's case: under RLIMIT_FSIZE every figure fits but the page (its figures in
    base64) cannot be written: one line, exit 2, and the previous report and figures stay,
    byte for byte, with nothing half-written beside them."""
    figures = max(p.stat().st_size for p in (reported / "figures").iterdir())
    limit = figures + 1024
    assert (reported / "report.html").stat().st_size > limit
    folder = tmp_path / "run"
    shutil.copytree(reported, folder)
    (folder / "figures" / "download.png").unlink()  # so that this report would add it
    before = _snapshot(folder)
    done = _limited_report(folder, limit)
    assert done.returncode == 2, done.stderr
    [line] = done.stderr.strip().splitlines()
    assert line == f"skymule: error: {folder / 'report.html'}: File too large"
    assert _snapshot(folder) == before
