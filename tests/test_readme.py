"""The README's Python quick start runs as written."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_blocks_run() -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "the README should show a Python quick start"
    namespace: dict[str, object] = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    result = namespace["result"]
    plugin = namespace["LargestBufferFirst"]
    policy = plugin(plugin.Params(min_snr_db=3))  # type: ignore[attr-defined,operator]
    assert policy.name == "largest-buffer-first" and policy.params.min_snr_db == 3
    batched = namespace["batched"]  # the README's batched form, run beside the per-mission one
    assert float(batched.downloaded_bit.sum()) > 0  # type: ignore[attr-defined]
    assert namespace["LargestBufferFirstBatched"].batched is True  # type: ignore[attr-defined]
    comparison = namespace["comparison"]
    gaps = [round(r["gap_to_bound_mbit"], 1) for r in comparison.rows()]  # type: ignore[attr-defined]
    assert gaps == [562.4, 243.6]
    assert result.summary["policy"] == "greedy"  # type: ignore[attr-defined]


def test_readme_states_the_two_setup_commands() -> None:
    text = README.read_text()
    assert "pip install -e '.[test,dask,browser,fast]'" in text
    assert "python -m pytest -q" in text
    ci = (README.parent / ".ci" / "run").read_text()
    assert "pip install -q -e '.[test,dask,browser,fast]'" in ci and "python -m pytest -q" in ci
