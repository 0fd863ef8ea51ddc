"""zstd-compressed scenario files: written atomically as one frame, read transparently by every reader."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
import zstandard
from scenario_builders import make_scenario

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.fileio import ZSTD_MAGIC, atomic_open, open_input, read_head
from langtraj.scenario import Scenario
from langtraj.scenario.compare import scenario_differences
from langtraj.scenario.io import (
    detect_format,
    expand_scenario_paths,
    format_for_output,
    read_scenario,
    read_scenarios,
    write_scenarios,
)
from langtraj.scenario.io.tfrecord import count_records


@pytest.fixture
def scenes() -> list[Scenario]:
    return [make_scenario(5, scenario_id=f"s{i}", seed=i) for i in range(4)]


@pytest.fixture
def pair(tmp_path: Path, scenes: list[Scenario]) -> tuple[Path, Path]:
    """The same scenarios written plain and compressed."""
    plain, packed = tmp_path / "shard.tfrecord", tmp_path / "shard.tfrecord.zst"
    assert write_scenarios(plain, scenes) == write_scenarios(packed, scenes) == len(scenes)
    return plain, packed


def test_a_zst_name_writes_one_zstd_frame_of_the_plain_bytes(pair: tuple[Path, Path]) -> None:
    plain, packed = pair
    data = packed.read_bytes()
    assert data[:4] == ZSTD_MAGIC
    params = zstandard.get_frame_parameters(data)
    assert params.content_size == plain.stat().st_size and params.has_checksum
    assert zstandard.ZstdDecompressor().decompress(data, allow_extra_data=False) == plain.read_bytes()
    assert sorted(p.name for p in plain.parent.iterdir()) == ["shard.tfrecord", "shard.tfrecord.zst"]  # no temp left


def test_compressed_reads_equal_plain_reads_in_every_field(pair: tuple[Path, Path]) -> None:
    plain, packed = pair
    assert detect_format(packed).name == "womd"
    for a, b in zip(read_scenarios(plain), read_scenarios(packed), strict=True):
        assert scenario_differences(a, b) == []
    assert count_records(packed) == count_records(plain) == 4


def test_real_record_survives_compression(real_data_dir: Path, tmp_path: Path) -> None:
    real = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    write_scenarios(tmp_path / "real.tfrecord.zst", [real])
    assert scenario_differences(real, read_scenario(tmp_path / "real.tfrecord.zst")) == []


def test_random_access_in_a_compressed_file(pair: tuple[Path, Path], scenes: list[Scenario]) -> None:
    _, packed = pair
    for index in (3, 0, 2):
        assert scenario_differences(read_scenario(packed, index), scenes[index]) == []
    with pytest.raises(InputError, match=r"shard\.tfrecord\.zst: no scenario at index 4"):
        read_scenario(packed, 4)


def test_compress_flag_overrides_the_name_and_scenarionet_compresses_too(tmp_path: Path, scenes) -> None:
    forced = tmp_path / "forced.tfrecord"
    write_scenarios(forced, scenes[:2], compress=True)
    assert forced.read_bytes()[:4] == ZSTD_MAGIC
    assert [s.scenario_id for s in read_scenarios(forced)] == ["s0", "s1"]
    pickle = tmp_path / "one.pkl.zst"
    assert format_for_output(pickle).name == "scenarionet"
    write_scenarios(pickle, scenes[:1])
    assert pickle.read_bytes()[:4] == ZSTD_MAGIC
    assert detect_format(pickle).name == "scenarionet"
    assert read_scenario(pickle).scenario_id == "s0"


def test_folder_expansion_finds_compressed_shards(tmp_path: Path, scenes) -> None:
    write_scenarios(tmp_path / "shards" / "a-0000.tfrecord.zst", scenes[:2])
    write_scenarios(tmp_path / "shards" / "a-0001.tfrecord", scenes[2:])
    (tmp_path / "shards" / "notes.txt.zst").write_bytes(zstandard.ZstdCompressor().compress(b"not scenarios"))
    found = expand_scenario_paths([tmp_path])
    assert [p.name for p in found] == ["a-0000.tfrecord.zst", "a-0001.tfrecord"]
    assert [s.scenario_id for p in found for s in read_scenarios(p)] == ["s0", "s1", "s2", "s3"]


def test_sniffing_decompresses_only_the_head(pair: tuple[Path, Path], tmp_path: Path) -> None:
    plain, packed = pair
    assert read_head(packed, 64) == plain.read_bytes()[:64] == read_head(plain, 64)
    big = tmp_path / "big.tfrecord.zst"
    write_scenarios(big, [make_scenario(5, scenario_id=f"b{i}", seed=i) for i in range(40)])
    cut = tmp_path / "cut.tfrecord.zst"
    cut.write_bytes(big.read_bytes()[: big.stat().st_size // 2])
    assert read_head(cut, 64) == read_head(big, 64)  # the missing tail is never reached
    assert detect_format(cut).name == "womd"


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda data: data[: len(data) // 2], "ends inside a frame"),
        (lambda data: data[:4] + b"\x00" * 40, "corrupt zstd data"),
        (lambda data: data[:6], "corrupt zstd data"),
        (lambda data: data + b"trailing junk", "corrupt zstd data"),
        (lambda data: data[:-1] + bytes([data[-1] ^ 0xFF]), "checksum"),
    ],
    ids=["truncated", "garbage", "header-only", "trailing", "checksum"],
)
def test_corrupt_compressed_file_is_one_input_error_naming_it(pair, damage, message, tmp_path, capsys) -> None:
    _, packed = pair
    bad = tmp_path / "bad.tfrecord.zst"
    bad.write_bytes(damage(packed.read_bytes()))
    for read in (open_input, lambda path: list(read_scenarios(path))):
        with pytest.raises(InputError, match=rf"bad\.tfrecord\.zst: .*{message}"):
            read(bad)
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "bad.tfrecord.zst" in err and "corrupt zstd data" in err and "\n" not in err


def test_frames_of_unknown_size_and_several_frames_are_read(tmp_path: Path, pair) -> None:
    plain, _ = pair
    data = plain.read_bytes()
    streamed = io.BytesIO()
    with zstandard.ZstdCompressor().stream_writer(streamed, closefd=False) as writer:  # no content size
        writer.write(data)
    half = len(data) // 2
    cctx = zstandard.ZstdCompressor()
    for name, blob in (
        ("streamed", streamed.getvalue()),
        ("frames", cctx.compress(data[:half]) + cctx.compress(data[half:])),
    ):
        path = tmp_path / f"{name}.tfrecord.zst"
        path.write_bytes(blob)
        assert zstandard.frame_content_size(blob) == (-1 if name == "streamed" else half)
        assert [s.scenario_id for s in read_scenarios(path)] == ["s0", "s1", "s2", "s3"]


def test_a_failed_compressed_write_leaves_the_old_file(pair: tuple[Path, Path], scenes) -> None:
    _, packed = pair
    before = packed.read_bytes()

    def broken():
        yield scenes[0]
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        write_scenarios(packed, broken())
    assert packed.read_bytes() == before
    assert sorted(p.name for p in packed.parent.iterdir()) == ["shard.tfrecord", "shard.tfrecord.zst"]
    with pytest.raises(ValueError, match="mode 'wb'"), atomic_open(packed.parent / "x.zst", "w", compress=True):
        pass


def test_convert_compresses_and_decompresses(pair: tuple[Path, Path], tmp_path: Path, capsys) -> None:
    plain, packed = pair
    by_name, by_flag, back = tmp_path / "n.tfrecord.zst", tmp_path / "f.tfrecord", tmp_path / "back.tfrecord"
    assert main(["convert", str(plain), str(by_name)]) == 0
    assert main(["convert", str(plain), str(by_flag), "--compress"]) == 0
    assert main(["convert", str(packed), str(back)]) == 0
    assert by_name.read_bytes() == by_flag.read_bytes() == packed.read_bytes()
    assert back.read_bytes() == plain.read_bytes()  # a plain TFRecord again, byte for byte
    assert plain.is_file() and packed.is_file()  # inputs are never removed
    folder = tmp_path / "one-per-scenario"
    assert main(["convert", str(packed), str(folder), "--format", "womd", "--compress"]) == 0
    assert sorted(p.name for p in folder.iterdir()) == [f"s{i}.tfrecord.zst" for i in range(4)]
    assert read_scenario(folder / "s2.tfrecord.zst").scenario_id == "s2"
    capsys.readouterr()


def test_an_empty_scenarionet_write_names_the_target(tmp_path: Path, scenes) -> None:
    target = tmp_path / "none.pkl.zst"
    with pytest.raises(InputError, match=r"none\.pkl\.zst: a ScenarioNet file holds exactly one"):
        write_scenarios(target, scenes)
    assert not target.exists()
