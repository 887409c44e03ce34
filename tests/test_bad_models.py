"""Model files that gave a traceback or were read whole (issue 32): a ``learned:`` weights
file is judged from its zip directory and ``.npy`` headers before any array is read, and a
zip that is not a stable-baselines3 model is one line even when trusted."""

from __future__ import annotations

import io
import sys
import tracemalloc
import types
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.lib import format as npy_format

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.policies.learned import FEATURE_NAMES, FORMAT, MAX_WEIGHTS_BYTES, initial_net, load_net

MB = 2**20


def _arrays() -> dict[str, np.ndarray]:
    net = initial_net(np.random.default_rng(0))
    weights = {name: value[0] for name, value in vars(net).items()}
    return {"format": np.array(FORMAT), "features": np.array(FEATURE_NAMES), **weights}


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    npy_format.write_array(buffer, array, allow_pickle=False)
    return buffer.getvalue()


def _header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    """A ``.npy`` header declaring ``shape`` (the data itself is not written)."""
    buffer = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    npy_format.write_array_header_1_0(buffer, header)
    return buffer.getvalue()


def _weights(
    path: Path, arrays: dict[str, np.ndarray], raw: dict[str, Callable[[Any], None]] | None = None
) -> Path:
    """A .npz of ``arrays``, plus members written by ``raw[name](handle)`` (deflated)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, array in arrays.items():
            archive.writestr(f"{name}.npy", _npy(array))
        for name, write in (raw or {}).items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as handle:
                write(handle)
    return path


def _refused(path: Path, needle: str) -> int:
    """load_net's one line (holding ``needle``); returns the peak bytes allocated meanwhile."""
    tracemalloc.start()
    try:
        with pytest.raises(SkymuleError) as caught:
            load_net(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(caught.value)
    assert needle in message and path.name in message and "\n" not in message, message
    return peak


def test_a_declared_shape_of_2_to_the_45_is_refused_from_the_header(tmp_path: Path) -> None:
    arrays = _arrays()
    del arrays["hidden_w"]
    huge = {"hidden_w": lambda handle: handle.write(_header((2**45, 32)) + b"\0" * 64)}
    path = _weights(tmp_path / "huge.npz", arrays, huge)
    assert _refused(path, "hidden_w declares shape (35184372088832, 32)") < 5 * MB


def test_an_extra_zero_filled_entry_is_refused_unread(tmp_path: Path) -> None:
    """A 40 MB entry of zeros deflates to ~40 kB; its name is refused from the directory,
    before any of it is inflated (it was read whole: 2.4 GB RSS for a 2.35 MB file)."""

    def zeros(handle: Any) -> None:
        handle.write(_header((5 * MB,)))
        for _ in range(40):
            handle.write(bytes(MB))

    path = _weights(tmp_path / "padded.npz", _arrays(), {"padding": zeros})
    assert path.stat().st_size < 1 * MB
    assert _refused(path, "unexpected padding") < 5 * MB


def test_arrays_unpacking_past_the_cap_are_refused_unread(tmp_path: Path) -> None:
    def zeros(handle: Any) -> None:
        handle.write(_header((9 * MB,)))
        for _ in range(72):
            handle.write(bytes(MB))

    path = _weights(tmp_path / "big.npz", {}, {"hidden_w": zeros})
    assert _refused(path, f"at most {MAX_WEIGHTS_BYTES:,} are read") < 5 * MB


def test_a_400_mb_file_is_not_read(tmp_path: Path) -> None:
    path = tmp_path / "large.npz"
    with path.open("wb") as handle:
        handle.truncate(400 * MB)  # sparse: no disk used, and nothing of it may be read
    assert _refused(path, "the file is 419,430,400 bytes") < 5 * MB


def test_integer_weights_are_refused(tmp_path: Path) -> None:
    arrays = _arrays()
    arrays["hidden_w"] = np.ones(arrays["hidden_w"].shape, dtype=np.int64)
    path = _weights(tmp_path / "ints.npz", arrays)
    _refused(path, "hidden_w has dtype int64; allowed: floats")


def test_text_where_a_weight_belongs_is_refused_from_the_header(tmp_path: Path) -> None:
    arrays = _arrays()
    arrays["format"] = np.zeros(3)
    _refused(_weights(tmp_path / "fmt.npz", arrays), "format is float64 of shape (3,)")


def test_the_shipped_and_a_rewritten_model_still_load(tmp_path: Path) -> None:
    path = _weights(tmp_path / "ok.npz", _arrays())
    assert load_net(path).hidden_w.shape[0] == 1
    done = run_cli(
        "run", "paper-sim-autonomous", "--policy", f"learned:{path}",
        "--set", "mission.duration_s=60", "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr


def test_the_cli_refuses_a_huge_declared_shape_in_one_line(tmp_path: Path) -> None:
    arrays = _arrays()
    del arrays["encoder_b"]
    huge = {"encoder_b": lambda handle: handle.write(_header((2**45,)))}
    path = _weights(tmp_path / "huge.npz", arrays, huge)
    done = run_cli("run", "paper-sim-autonomous", "--policy", f"learned:{path}")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "encoder_b declares shape" in done.stderr


def test_a_trusted_zip_that_is_not_a_model_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """stable-baselines3's error for a foreign zip spans several lines (6 in the audit); the
    refusal keeps the first. The library is stood in for (the rl extra is optional)."""
    model = tmp_path / "notes.zip"
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("notes.txt", "not a model")

    class PPO:
        @staticmethod
        def load(path: str, device: str = "cpu") -> None:
            raise ValueError(
                "There is no item named 'data' in the archive\n"
                "  File ...\n    line 2\n    line 3\n    line 4\n    line 5"
            )

    fake = types.ModuleType("stable_baselines3")
    fake.PPO = PPO  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "stable_baselines3", fake)
    done = run_cli("run", "paper-sim-fixed", "--policy", f"rl:{model}", "--trust-model", model)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "not a stable-baselines3 PPO model" in done.stderr
    assert "There is no item named 'data'" in done.stderr
