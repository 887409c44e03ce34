"""Every command in a ```bash block of README.md and docs/*.md runs as written.

Each document's blocks run in order, in a temporary folder of its own laid out like a clone
(``examples/``, ``benchmarks/`` and ``scripts/`` copied), so a block uses what an earlier
block of the same page wrote, as a reader following the page would. ``skymule ...`` runs in
this process (``run_cli``); ``cp`` is done here; ``python benchmarks/...`` and
``python scripts/...`` run as subprocesses with ``SKYMULE_BENCH_TINY=1`` (their tiny size).
The README's policy module (the Python block that starts ``# <file name>``) is written to the
folder and put on the import path, as the README says. Two things keep the test fast without
changing a command: the sweep file in the copied ``examples/`` has 3 seeds instead of 500,
and ``tcp://HOST:8786`` is replaced by a local in-process Dask scheduler's address.

Commands that cannot run inside the suite are listed in ``NOT_RUN`` with the reason; a command
in the docs that is neither runnable nor listed fails the test.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SAMPLES_README = ROOT / "examples" / "samples" / "README.md"

NOT_RUN = {
    "pip install -e '.[test,dask,browser,fast]'": "installs the package",
    "pip install -e .": "installs the package",
    "pip install torch==2.13.0": "installs the rl extra's CPU torch",
    "pip install -e '.[rl]'": "installs the rl extra",
    "pip install -e '.[marl]'": "installs the marl extra",
    "python -m pytest -q": "runs this suite",
}
"""Commands the docs show that this test does not run, and why."""

NOT_RUN_PREFIXES = {
    "skymule aadm controller": "a server that runs until stopped (tests/test_aadm_controller.py)",
    "skymule aadm comm": "the comm stand-in serves its peer until stopped (test_aadm_agent.py)",
    "skymule aadm agent": "needs the controller of the line above running (test_aadm_agent.py)",
    "dask scheduler": "a server until stopped; test_sweep_scale.py runs a sweep through the "
    "scheduler address of a cluster of worker processes",
    "dask worker": "joins the scheduler of the line above until stopped (test_sweep_scale.py)",
    "skymule aadm towers": "serves the tower ports until stopped (tests/test_aadm_testbed.py)",
}
"""Commands shown as terminals side by side: tested by the AADM tests instead."""

SMALL_SWEEP_SEEDS = "seed = { range = [0, 3] }"


@dataclass(frozen=True)
class Command:
    """One command of a bash block: its words and where it is written."""

    words: tuple[str, ...]
    where: str

    @property
    def text(self) -> str:
        return shlex.join(self.words)


def bash_blocks(path: Path) -> list[tuple[int, str]]:
    """(line number, body) of every ```bash block in ``path``."""
    text = path.read_text()
    return [
        (text.count("\n", 0, match.start()) + 2, match.group(1))
        for match in re.finditer(r"^```bash\n(.*?)^```", text, flags=re.S | re.M)
    ]


def commands(path: Path) -> list[Command]:
    """The commands of ``path``'s bash blocks, in order (``&&`` and ``;`` chains split,
    comments cut)."""
    found = []
    for first_line, body in bash_blocks(path):
        for offset, line in enumerate(body.replace("\\\n", " ").splitlines()):
            words = shlex.split(line.replace("; ", " && "), comments=True)
            where = f"{path.name}:{first_line + offset}"
            while words:
                end = words.index("&&") if "&&" in words else len(words)
                found.append(Command(tuple(words[:end]), where))
                words = words[end + 1 :]
    return found


def test_every_document_has_commands_and_no_unknown_program() -> None:
    """The parser sees the blocks, and every command is one this test knows how to run."""
    programs = {c.words[0] for doc in [*DOCUMENTS, SAMPLES_README] for c in commands(doc)} - {
        "skymule",
        "python",
        "cp",
        "pip",
        "dask",  # dask scheduler / dask worker: listed in NOT_RUN_PREFIXES
    }
    assert not programs, f"commands the docs test cannot run: {sorted(programs)}"
    assert len(commands(ROOT / "README.md")) >= 8  # set-up, quick start, own policy
    assert sum(len(commands(doc)) for doc in DOCUMENTS) >= 60  # the rest moved to docs/


@pytest.fixture(scope="module")
def dask_scheduler() -> Iterator[str]:
    """Address of an in-process Dask scheduler with one worker thread (for ``--scheduler``)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1,
        processes=False,
        threads_per_worker=1,
        dashboard_address="127.0.0.1:0",
        scheduler_kwargs={"dashboard": False},
    ) as cluster:
        yield cluster.scheduler_address


def clone_layout(folder: Path) -> None:
    """The parts of a clone the docs' commands read, in ``folder``; the sweep made small."""
    shutil.copytree(ROOT / "examples", folder / "examples")
    if (ROOT / "models").is_dir():
        shutil.copytree(ROOT / "models", folder / "models")
    for name in ("benchmarks", "scripts"):  # copies: scripts write next to themselves
        shutil.copytree(ROOT / name, folder / name, ignore=shutil.ignore_patterns("__pycache__"))
    sweep = folder / "examples" / "sweep-paper.toml"
    text = sweep.read_text()
    assert "seed = { range = [0, 500] }" in text
    sweep.write_text(text.replace("seed = { range = [0, 500] }", SMALL_SWEEP_SEEDS))


def write_named_files(folder: Path) -> None:
    """The README's file blocks (a python or toml block whose first line is ``# <name>``,
    e.g. the own-policy module and its scenario), saved where the README says."""
    blocks = re.findall(
        r"```(?:python|toml)\n# ([\w.-]+\.(?:py|toml))\b[^\n]*\n(.*?)```",
        (ROOT / "README.md").read_text(),
        re.S,
    )
    assert blocks, "README.md should show the own-policy module and its scenario file"
    for name, body in blocks:
        (folder / name).write_text(body)


def run(command: Command, folder: Path, scheduler: str) -> None:
    """Run one command in ``folder``; fail with the command, its place and its output."""
    words = [w.replace("tcp://HOST:8786", scheduler) for w in command.words]
    if command.text in NOT_RUN or command.text.startswith(tuple(NOT_RUN_PREFIXES)):
        return
    learned = "train_ppo" in command.text or "rl:" in command.text
    if learned and importlib.util.find_spec("stable_baselines3") is None:
        return  # the rl extra is not installed here (docs/learning.md says how)
    redirect = None
    if ">" in words:  # `command > file`: the command's standard output saved in the folder
        redirect, words = folder / words[words.index(">") + 1], words[: words.index(">")]
    if words[:3] == ["python", "-m", "skymule"]:  # the module is the same program
        words = ["skymule", *words[3:]]
    if words[0] == "skymule":
        result = run_cli(*words[1:], cwd=folder)
        code, output = result.returncode, result.stdout + result.stderr
        if redirect is not None:
            redirect.write_text(result.stdout)
    elif words[0] == "cp" and len(words) == 3:
        target = folder / words[2]
        shutil.copy(folder / words[1], target / Path(words[1]).name if target.is_dir() else target)
        code, output = 0, ""
    elif words[0] == "python" and words[1].split("/")[0] in ("benchmarks", "scripts"):
        env = {**os.environ, "SKYMULE_BENCH_TINY": "1", "PYTHONPATH": str(ROOT / "src")}
        done = subprocess.run(
            [sys.executable, *words[1:]], cwd=folder, env=env, capture_output=True, text=True
        )
        code, output = done.returncode, done.stdout + done.stderr
    else:
        pytest.fail(f"{command.where}: cannot run {command.text!r}; add it to NOT_RUN with why")
    assert code == 0, f"{command.where}: {command.text} exited {code}:\n{output[-3000:]}"


@pytest.mark.filterwarnings("ignore::ResourceWarning")
@pytest.mark.parametrize(
    "document", [*DOCUMENTS, SAMPLES_README], ids=lambda path: str(path.relative_to(ROOT))
)
def test_documented_commands_run_as_written(
    document: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, dask_scheduler: str
) -> None:
    """Each document in a fresh clone-like folder, its commands in order (a reader follows one
    page from a clone); a command already run there is not run again (same command, same
    folder: same result). One test per document lets the suite spread them over cores."""
    clone_layout(tmp_path)
    write_named_files(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))  # "in the folder you run skymule from"
    done: set[str] = set()
    for command in commands(document):
        if command.text not in done:
            run(command, tmp_path, dask_scheduler)
            done.add(command.text)


PENDING: set[str] = set()
"""Files the docs already point to that another change adds (the lead moves the slot contract
from outside the repository to docs/contract.md); remove an entry once the file exists."""


def test_docs_point_only_to_files_in_the_repository() -> None:
    """Every relative link and every repository path in backticks names an existing file."""
    missing = []
    for document in [*DOCUMENTS, SAMPLES_README]:
        text = document.read_text()
        links = [
            (document.parent / target).resolve()
            for target in re.findall(r"\]\(([^)#\s]+)\)", text)
            if "://" not in target
        ]
        paths = [
            ROOT / token
            for token in re.findall(
                r"`((?:docs|examples|src|benchmarks|scripts|tests)/[\w./-]+)`", text
            )
        ]
        if document.name != "architecture.md":  # the lead's, who is replacing its ../ link
            paths += [
                (document.parent / token).resolve()
                for token in re.findall(r"`(\.\./[\w./-]+)`", text)
            ]
        for path in links + paths:
            relative = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            if not path.is_relative_to(ROOT):
                missing.append(f"{document.name}: {relative} is outside the repository")
            elif not path.exists() and str(relative) not in PENDING:
                missing.append(f"{document.name}: {relative} does not exist")
    assert not missing, "\n".join(missing)


PACKAGE_DIRS = "|".join(
    sorted(
        p.name
        for p in (ROOT / "src" / "skymule").iterdir()
        if p.is_dir() and p.name != "__pycache__"
    )
)
NOT_CHECKED = {"architecture.md"}
"""The lead's, being rewritten for the new engine layout (issue 25 leaves it to them)."""


def _resolves(dotted: str) -> bool:
    """``skymule.a.b.c``: a module, or an attribute of the longest module prefix."""
    import importlib

    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for name in parts[cut:]:
            if not hasattr(found, name):
                return False
            found = getattr(found, name)
        return True
    return False


def test_docs_name_only_modules_and_files_that_exist() -> None:
    """A dotted ``skymule.x.y`` in backticks imports (or is an attribute of what does), and a
    package path such as ``sim/fixed.py`` exists under src/skymule: a reader who follows a
    name after a refactor finds it (the README pointed to skymule.sim.engine)."""
    missing = []
    for document in DOCUMENTS:
        if document.name in NOT_CHECKED:
            continue
        text = document.read_text()
        for dotted in re.findall(r"`(skymule(?:\.\w+)+)", text):
            if not _resolves(dotted):
                missing.append(f"{document.name}: {dotted} does not import")
        for path in re.findall(rf"`((?:{PACKAGE_DIRS})/\w+\.py)`", text):
            if not (ROOT / "src" / "skymule" / path).exists():
                missing.append(f"{document.name}: src/skymule/{path} does not exist")
    assert not missing, "\n".join(sorted(set(missing)))
