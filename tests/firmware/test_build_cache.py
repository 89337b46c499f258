"""The on-disk cache of assembled firmware builds (firmware_model/firmware/assemble.py): content-keyed, never stale,
atomic."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from firmware_model.firmware import assemble as build_mod
from firmware_model.spec.config import BuildConfig


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("FWEMU_CACHE_DIR", str(tmp_path))
    build_mod.clear_cache()
    yield tmp_path
    build_mod.clear_cache()


def _same(a: build_mod.FirmwareBuild, b: build_mod.FirmwareBuild) -> None:
    assert a.program.code == b.program.code and a.rom_image == b.rom_image
    assert a.program.segments == b.program.segments and a.program.symbols == b.program.symbols
    assert a.program.source_map == b.program.source_map and a.program.listing == b.program.listing
    assert (a.init_address, a.step_address, dict(a.variables)) == (b.init_address, b.step_address, dict(b.variables))


def test_second_process_loads_instead_of_assembling(cache: Path) -> None:
    cfg = BuildConfig(program="kalman_baro", k=6)
    n = dict(build_mod.cache_stats)
    first = build_mod.build_firmware(cfg)
    assert build_mod.cache_stats["assembled"] == n["assembled"] + 1
    files = list((cache / "builds").glob("*.pickle"))
    assert len(files) == 1 and not list((cache / "builds").glob(".tmp-*"))
    build_mod.clear_cache()  # what a new process sees: only the disk
    second = build_mod.build_firmware(cfg)
    assert build_mod.cache_stats["assembled"] == n["assembled"] + 1
    assert build_mod.cache_stats["disk_hits"] == n["disk_hits"] + 1
    _same(first, second)


def test_key_changes_with_constants_and_sources(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg6, cfg7 = BuildConfig(program="kalman_baro", k=6), BuildConfig(program="kalman_baro", k=7)
    b6 = build_mod.build_firmware(cfg6)
    b7 = build_mod.build_firmware(cfg7)
    assert b6.program.code != b7.program.code
    assert len(list((cache / "builds").glob("*.pickle"))) == 2
    eq = tuple(sorted(b6.consts.equates().items()))
    k = build_mod.build_key("kalman_baro", eq, b6.source_sha256)
    assert k != build_mod.build_key("kalman_baro", eq, "0" * 64)  # another source text
    monkeypatch.setattr(build_mod, "_assembler_digest", lambda: "another assembler")
    assert k != build_mod.build_key("kalman_baro", eq, b6.source_sha256)


def test_a_corrupt_cache_file_is_rebuilt(cache: Path) -> None:
    cfg = BuildConfig(program="recursive", k=5)
    good = build_mod.build_firmware(cfg)
    (path,) = (cache / "builds").glob("*.pickle")
    path.write_bytes(b"not a pickle")
    build_mod.clear_cache()
    n = build_mod.cache_stats["assembled"]
    again = build_mod.build_firmware(cfg)
    assert build_mod.cache_stats["assembled"] == n + 1
    _same(good, again)
    build_mod.clear_cache()
    d = build_mod.cache_stats["disk_hits"]
    build_mod.build_firmware(cfg)
    assert build_mod.cache_stats["disk_hits"] == d + 1  # the rebuilt file replaced the corrupt one


def test_disk_cache_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FWEMU_CACHE_DIR", "off")
    assert build_mod.cache_dir() is None
    monkeypatch.delenv("FWEMU_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert build_mod.cache_dir() == tmp_path / "fwemu"


def test_unwritable_cache_dir_only_costs_the_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("FWEMU_CACHE_DIR", str(blocker / "sub"))  # a path under a regular file: mkdir fails
    build_mod.clear_cache()
    b = build_mod.build_firmware(BuildConfig(program="recursive", k=4))
    assert b.rom_bytes > 0 and os.listdir(tmp_path) == ["file"]
    build_mod.clear_cache()
