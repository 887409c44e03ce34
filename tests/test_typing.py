"""The package type-checks cleanly under the ``[tool.mypy]`` settings in pyproject.toml."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_package_type_checks() -> None:
    api = pytest.importorskip("mypy.api")
    stdout, stderr, status = api.run(
        ["--config-file", str(ROOT / "pyproject.toml"), str(ROOT / "src" / "skymule")]
    )
    assert status == 0, stdout + stderr
    assert "Success: no issues found" in stdout, stdout
