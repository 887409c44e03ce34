"""A command imports only what it uses: ``skymule --help`` no numpy, ``run`` of a short fixed
mission neither numba (the compiled engine does not pay for 500 slots) nor pandas nor scipy.

Start-up is most of the wait for ``run``, ``bound`` and ``compare`` of a preset (issue 25);
``benchmarks/bench_startup.py`` measures it. This test keeps the heavy imports where they pay.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "pandas", "scipy", "numba", "matplotlib", "skymule.sim.autonomous")

SCRIPT = """
import json, sys
from skymule.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
heavy = {heavy!r}
print(json.dumps(sorted(m for m in heavy if m in sys.modules)), file=sys.stderr)
"""


def heavy_imports(*args: str) -> set[str]:
    """The heavy modules ``skymule ARGS`` imported, run in a fresh interpreter."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT.format(heavy=HEAVY), *args],
        capture_output=True, text=True, env=env, timeout=300, check=True,
    )  # fmt: skip
    return set(json.loads(done.stderr.strip().splitlines()[-1]))


@pytest.mark.parametrize(
    ("args", "absent"),
    [
        (("--help",), set(HEAVY)),
        (("aadm", "--help"), set(HEAVY)),
        (("run", "paper-sim-fixed"), {"pandas", "scipy", "numba", "matplotlib"}),
        (("compare", "paper-sim-fixed"), {"pandas", "numba", "matplotlib"}),
        (("bound", "paper-sim-fixed"), {"pandas", "numba", "matplotlib"}),
    ],
)
def test_a_command_imports_only_what_it_uses(args: tuple[str, ...], absent: set[str]) -> None:
    imported = heavy_imports(*args)
    assert not imported & absent, f"skymule {' '.join(args)} imported {imported & absent}"
    if args[0] != "--help" and args[0] != "aadm":
        assert "numpy" in imported  # it did run (the check is not vacuous)
        assert "skymule.sim.autonomous" not in imported  # a fixed path needs none of it
