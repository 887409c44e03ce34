"""Wall time of a command a user types, start to exit, against ``skymule --help``.

Every command pays for starting Python and importing what it needs before it does its work;
for ``run``, ``bound`` and ``compare`` of a preset that start-up is most of the wait (issue 25:
the target is each within 3x the wall time of ``skymule --help``). The commands run as a user
runs them (a fresh ``python -m skymule`` process each, output discarded), round-robin so a
neighbour's load falls on all of them alike; the median of ``--repeat`` runs is reported,
with the load average during the measurement. The commands run as an installed package runs:
with Python's bytecode cache (``PYTHONDONTWRITEBYTECODE`` is dropped for them; without the
cache every module of skymule is compiled from source at every start, ~0.3 s more).
``--importtime`` also prints, per command, the packages it spends most time importing.

Run: python benchmarks/bench_startup.py [--repeat N] [--importtime] [--json PATH]
(``--json benchmarks/results/startup.json``: the speed table's start-up row, docs/speed.md)
(SKYMULE_BENCH_TINY=1: --repeat 1, ``--help`` and ``run`` only, no unmeasured first run)
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from _results import json_option, table, write
from _sizes import size

PRESET = "paper-sim-fixed"
COMMANDS: dict[str, tuple[str, ...]] = {
    "--help": ("--help",),
    "run": ("run", PRESET),
    "bound": ("bound", PRESET),
    "compare": ("compare", PRESET),
    "run --out": ("run", PRESET, "--out", "{scratch}/run", "--force"),
}
"""Label -> the command's arguments (``{scratch}``: a temporary folder)."""

TARGET_RATIO = 3.0


CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _argv(args: tuple[str, ...], scratch: str, *python: str) -> list[str]:
    return [sys.executable, *python, "-m", "skymule", *(a.format(scratch=scratch) for a in args)]


def timed(args: tuple[str, ...], scratch: str) -> tuple[float, float]:
    """(wall, CPU) seconds from starting ``python -m skymule ARGS`` to its exit (it must
    succeed); CPU is the process's user + system time, which a neighbour's load moves less."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(_argv(args, scratch), check=True, stdout=subprocess.DEVNULL, env=CHILD_ENV)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def slowest_imports(args: tuple[str, ...], scratch: str, top: int = 6) -> list[tuple[str, float]]:
    """The ``top`` packages the command spends most time importing [s]: each module's own
    import time (``python -X importtime``, not counting what it imports) summed by its
    top-level package."""
    done = subprocess.run(
        _argv(args, scratch, "-X", "importtime"),
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=CHILD_ENV,
    )
    packages: dict[str, float] = {}
    for line in done.stderr.splitlines():
        found = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
        if found:
            name = found.group(2).split(".")[0]
            packages[name] = packages.get(name, 0.0) + int(found.group(1)) / 1e6
    return sorted(packages.items(), key=lambda item: -item[1])[:top]


def main() -> None:
    json_path = json_option()
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=size(10, 1))
    parser.add_argument("--importtime", action="store_true")
    args = parser.parse_args()
    commands = {k: COMMANDS[k] for k in size(list(COMMANDS), ["--help", "run"])}
    walls: dict[str, list[float]] = {label: [] for label in commands}
    cpus: dict[str, list[float]] = {label: [] for label in commands}
    with tempfile.TemporaryDirectory() as scratch:
        for command in size(list(commands.values()), []):  # unmeasured: disk, bytecode caches
            timed(command, scratch)
        load_before = os.getloadavg()[0]
        for _ in range(args.repeat):
            for label, command in commands.items():
                wall, cpu = timed(command, scratch)
                walls[label].append(wall)
                cpus[label].append(cpu)
        load_after = os.getloadavg()[0]
        help_wall = statistics.median(walls["--help"])
        help_cpu = statistics.median(cpus["--help"])
        print(
            f"start-up of `python -m skymule ...` ({PRESET}), median of {args.repeat} runs "
            f"(load {load_before:.1f} -> {load_after:.1f} on {os.cpu_count()} cores):"
        )
        for label in commands:
            wall, cpu = statistics.median(walls[label]), statistics.median(cpus[label])
            fastest = min(walls[label])
            line = f"  {label:10s} wall {wall:6.3f} s (min {fastest:.3f}), CPU {cpu:.3f} s"
            if label != "--help":
                line += (
                    f"; {wall / help_wall:.2f}x --help in wall time, {cpu / help_cpu:.2f}x in "
                    f"CPU (target <= {TARGET_RATIO:.0f}x)"
                )
            print(line)
        if args.importtime:
            for label, command in commands.items():
                shown = ", ".join(f"{n} {s:.2f} s" for n, s in slowest_imports(command, scratch))
                print(f"  imports of {label}: {shown}")
    medians = {
        label: (statistics.median(walls[label]), statistics.median(cpus[label]))
        for label in commands
    }
    write(json_path, {"speed-startup": speed_row(medians, args.repeat, load_before)})


def speed_row(medians: dict[str, tuple[float, float]], runs: int, load: float) -> dict[str, object]:
    """The speed table's start-up row from each command's median (wall, CPU) [s]."""
    help_wall, help_cpu = medians["--help"]
    parts = [f"`--help` {help_wall:.2f} s ({help_cpu:.2f} s CPU)"]
    parts += [
        f"`{label}` {wall:.2f} s (×{wall / help_wall:.1f}; {cpu:.2f} s CPU, ×{cpu / help_cpu:.1f})"
        for label, (wall, cpu) in medians.items()
        if label != "--help"
    ]
    row = [
        "start-up: `skymule --help`, and `run`, `bound`, `compare` of paper-sim-fixed, wall "
        "time of a fresh process (×: against `--help`)",
        f"{', '.join(parts)}; median of {runs}, load {load:.1f} on {os.cpu_count()} cores",
        "`python benchmarks/bench_startup.py`",
    ]
    return table(["what", "figure", "command"], [row], align="lll")


if __name__ == "__main__":
    main()
