"""Big traces (issue 24): size-checked before they are read, one line with the limit and how
to cut the trace, never numpy's "Unable to allocate" after a minute of parsing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.io.traces import read_trace, table, write_dt_export


def test_a_file_over_the_byte_limit_is_refused_unread(tmp_path: Path) -> None:
    huge = tmp_path / "flight.csv"
    with huge.open("wb") as handle:  # sparse: 1 GiB on paper, nothing on disk
        handle.truncate(2**30)
    with pytest.raises(SkymuleError) as caught:
        read_trace(huge)
    message = str(caught.value)
    assert message.startswith(f"{huge}: 1,024 MiB; a trace may have at most 256 MiB")
    assert f"head -n 1000001 {huge} > part.csv" in message and "\n" not in message
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        'name = "big"\n[[sensors]]\nname = "LW1"\nx_m = 0.0\ny_m = 0.0\nbuffer_mbit = 10\n'
        f'[signal]\nsource = "trace"\ntrace = "{huge}"\n'
    )
    done = run_cli("run", scenario)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "at most 256 MiB" in done.stderr


def _trace(path: Path, rows: int) -> Path:
    time_s = np.arange(float(rows))
    write_dt_export(path, time_s, np.zeros((rows, 1)), ["LW1"], x_m=time_s, y_m=0 * time_s,
                    z_m=0 * time_s + 30)  # fmt: skip
    return path


def test_too_many_rows_are_refused_before_parsing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(table, "MAX_TRACE_ROWS", 50)
    assert read_trace(_trace(tmp_path / "fits.csv", 50)).time_s.size == 50
    with pytest.raises(SkymuleError, match=r"more than 51 lines; .* at most 256 MiB and 50 data"):
        read_trace(_trace(tmp_path / "long.csv", 51))
    # blank lines do not count as rows, but the reader stops once it has passed the limit
    text = (tmp_path / "long.csv").read_text().replace("\n", "\n\n", 1)
    (tmp_path / "gappy.csv").write_text(text)
    monkeypatch.setattr(table, "MAX_TRACE_ROWS", 52)
    assert read_trace(tmp_path / "gappy.csv").time_s.size == 51
    monkeypatch.setattr(table, "_count_lines", lambda path, stop: 0)  # the in-loop check alone
    monkeypatch.setattr(table, "MAX_TRACE_ROWS", 50)
    with pytest.raises(SkymuleError, match="more than 50 data rows"):
        read_trace(tmp_path / "long.csv")
