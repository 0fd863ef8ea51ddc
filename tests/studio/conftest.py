"""The studio's fixtures: a catalog over the real scenes in ../shared/data/real plus a deliberately corrupt
file, and apps over it with their own data folders."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.studio.catalog import Catalog

CORRUPT_NAME = "corrupt.tfrecord"


@pytest.fixture(scope="session")
def studio_files(real_data_dir: Path, tmp_path_factory) -> tuple[Path, ...]:
    """The real scenes (a folder) and a corrupt scenario file beside them."""
    corrupt = tmp_path_factory.mktemp("corrupt") / CORRUPT_NAME
    corrupt.write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00garbage that is no TFRecord")
    return (real_data_dir, corrupt)


@pytest.fixture(scope="session")
def catalog(studio_files: tuple[Path, ...]) -> Catalog:
    return Catalog.build(studio_files)
