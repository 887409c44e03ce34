"""Bad inputs at the edges (issue 15): one clear line naming the file, never a wrong result."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import run_cli
from skymule.errors import ScenarioError, SkymuleError
from skymule.io.traces import TraceError, read_trace
from skymule.scenario import MAX_BUFFER_MBIT, load_scenario, preset_names

SENSOR = 'name = "{name}"\nseed = 1\n[[sensors]]\nname = "S1"\nx_m = 0\ny_m = 0\n'


def _scenario(tmp_path: Path, extra: str, buffer: str = "buffer_mbit = 100") -> Path:
    path = tmp_path / "s.toml"
    path.write_text(SENSOR.format(name="bad") + buffer + "\n" + extra)
    return path


def _message(path: Path) -> str:
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    assert "\n" not in str(caught.value)
    return str(caught.value)


@pytest.mark.parametrize(
    ("buffer", "expected"),
    [
        ("buffer_mbit = 1e305", "sensors[0].buffer_mbit = 1e+305: Input should be less than"),
        (f"buffer_mbit = {MAX_BUFFER_MBIT * 10}", "sensors[0].buffer_mbit"),
        ("buffer_mbit = true", "sensors[0].buffer_mbit = True: must be a number"),
        ('buffer_mbit = "500"', "sensors[0].buffer_mbit = '500': must be a number"),
        ("buffer_mbit = inf", "sensors[0].buffer_mbit = inf"),
    ],
)
def test_buffer_must_be_a_sane_number(tmp_path: Path, buffer: str, expected: str) -> None:
    assert expected in _message(_scenario(tmp_path, "", buffer))


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ('[mission]\nduration_s = "200"\n', "mission.duration_s = '200': must be a number"),
        ("[mission]\nduration_s = 1e300\n", "mission.duration_s = 1e+300"),
        ("[mission]\nslot_s = false\n", "mission.slot_s = False: must be a number"),
        ("[policy]\nmax_hover_s = true\n", "policy.params.max_hover_s = True: must be a number"),
        ("[trajectory]\nreturn_home = 1\n", "trajectory.return_home = 1: must be true or false"),
        ("[radio]\nmodel = 3\n", "radio.model = 3: must be a string"),
    ],
)
def test_strict_types_across_the_scenario(tmp_path: Path, extra: str, expected: str) -> None:
    assert expected in _message(_scenario(tmp_path, extra))


def test_seed_must_be_a_whole_number(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(SENSOR.format(name="x").replace("seed = 1", "seed = 1.5") + "buffer_mbit = 1\n")
    assert "seed = 1.5: must be a whole number" in _message(path)


def test_integers_still_count_as_numbers_and_presets_load(tmp_path: Path) -> None:
    scenario = load_scenario(_scenario(tmp_path, "[mission]\nduration_s = 200\n"))
    assert scenario.mission.duration_s == 200.0 and scenario.sensors[0].buffer_mbit == 100.0
    assert {load_scenario(name).name for name in preset_names()} == set(preset_names())


def test_largest_buffers_sum_without_overflow(tmp_path: Path) -> None:
    buffers = "".join(
        f'[[sensors]]\nname = "S{i}"\nx_m = {i}\ny_m = 0\nbuffer_mbit = {MAX_BUFFER_MBIT}\n'
        for i in range(2, 6)
    )
    scenario = load_scenario(_scenario(tmp_path, buffers, f"buffer_mbit = {MAX_BUFFER_MBIT}"))
    total_bit = sum(s.buffer_mbit for s in scenario.sensors) * 1e6 * 1e7  # x slots, generously
    assert total_bit < float("inf")


def test_scenario_that_is_not_utf8_is_one_line_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes((SENSOR.format(name="Zürich") + "buffer_mbit = 1\n").encode("latin-1"))
    assert f"{path}: not a UTF-8 text file" in _message(path)
    done = run_cli("run", str(path))
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "not a UTF-8 text file" in done.stderr


def test_sweep_file_that_is_not_utf8_is_one_line_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "sweep.toml"
    path.write_bytes(b'base = "paper-sim-fixed"\n# caf\xe9\n[axes]\nseed = [1, 2]\n')
    done = run_cli("sweep", str(path), "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert f"{path}: not a UTF-8 text file" in done.stderr


def test_a_folder_given_as_scenario(tmp_path: Path) -> None:
    with pytest.raises(SkymuleError, match="is a folder"):
        load_scenario(tmp_path)


HEADER = "time,snr_lw1,snr_lw2,snr_lw3,snr_lw4,Longitude,Latitude,Altitude\n"


def _aadm(tmp_path: Path, stamps: list[str]) -> Path:
    rows = "".join(f"{s},10,11,12,13,-78.696,35.727,30\n" for s in stamps)
    path = tmp_path / "flight.csv"
    path.write_text(HEADER + rows)
    return path


def _stamps(count: int, offset: str = "") -> list[str]:
    return [f"2025-05-24 16:{19 + i // 60:02d}:{i % 60:02d}.186{offset}" for i in range(count)]


def test_trace_mixing_offset_and_naive_times_is_one_error(tmp_path: Path) -> None:
    stamps = _stamps(60)
    stamps[0] += "+02:00"  # the log: first stamp aware, the other 59 naive
    with pytest.raises(TraceError) as caught:
        read_trace(_aadm(tmp_path, stamps))
    message = str(caught.value)
    assert "flight.csv: row 3, column 'time': '2025-05-24 16:19:01.186' has no UTC offset" in (
        message
    )
    assert "unlike row 2's '2025-05-24 16:19:00.186+02:00'" in message


def test_trace_with_consistent_offsets_is_read_on_one_clock(tmp_path: Path) -> None:
    aware = read_trace(_aadm(tmp_path, _stamps(60, "+02:00")))
    assert aware.n_samples == 60 and aware.time_s[-1] == pytest.approx(59.0)
    stamps = _stamps(3, "+02:00")
    stamps[2] = "2025-05-24 15:19:02.186+01:00"  # same instant as 16:19:02+02:00
    mixed_zones = read_trace(_aadm(tmp_path, stamps))
    assert mixed_zones.time_s.tolist() == pytest.approx([0.0, 1.0, 2.0])


def test_scenario_saved_with_a_byte_order_mark_loads(tmp_path: Path) -> None:
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (SENSOR.format(name="bom") + "buffer_mbit = 1\n").encode())
    assert load_scenario(path).name == "bom"
