"""Process-wide code caches (isa/codecache.py): a second CPU running the same program decodes and compiles
nothing; cached and uncached runs are identical; the key is the code bytes and the memory map; memory stays
bounded."""

from __future__ import annotations

import numpy as np
import pytest

import isa
from isa import codecache
from isa.errors import BusError

LOOP = """
        moveq   #0,d0
        move.w  #300,d7
        lea     $6000,a0
loop:   add.l   d7,d0
        move.l  d0,(a0)+
        muls.w  d7,d1
        dbra    d7,loop
        trap    #0
"""


def _run(code: bytes, origin: int = 0x1000) -> tuple[object, ...]:
    cpu = isa.CPU()
    cpu.write_bytes(origin, code)
    cpu.pc = origin
    cpu.a[7] = 0x8000
    res = cpu.run()
    return res, tuple(cpu.d), tuple(cpu.a), cpu.sr, cpu.read_bytes(0x6000, 0x500), cpu.instructions, cpu.cycles


def _delta(before: dict[str, int]) -> dict[str, int]:
    return {k: codecache.stats[k] - before[k] for k in before}


def test_second_cpu_decodes_and_compiles_nothing() -> None:
    code = isa.assemble(LOOP, origin=0x1000).code
    codecache.clear()
    before = dict(codecache.stats)
    first = _run(code)
    d1 = _delta(before)
    assert d1["compiles"] >= 1 and d1["decodes"] >= 7  # not vacuous: the first CPU did the work
    before = dict(codecache.stats)
    second = _run(code)
    d2 = _delta(before)
    assert d2["compiles"] == 0 and d2["decodes"] == 0, d2
    assert d2["block_hits"] >= 1
    assert first == second


def test_cached_and_uncached_runs_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    code = isa.assemble(LOOP, origin=0x1000).code
    _run(code)  # fill the cache
    cached = _run(code)
    monkeypatch.setattr(codecache, "enabled", False)
    before = dict(codecache.stats)
    uncached = _run(code)
    assert _delta(before)["compiles"] >= 1 and _delta(before)["block_hits"] == 0
    assert cached == uncached


def test_firmware_second_run_compiles_nothing_and_is_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.spec.config import BuildConfig
    from firmware_model.firmware.harness import run_firmware

    build = build_firmware(BuildConfig(program="kalman_accel", k=6))
    rng = np.random.default_rng(5)
    adc = rng.integers(20000, 40000, size=(3, 60))
    acc = rng.integers(-3000, 3000, size=(3, 60))
    codecache.clear()
    before = dict(codecache.stats)
    first = run_firmware(build, adc, acc)  # three streams = three CPUs: only the first one compiles
    after_first = _delta(before)
    before = dict(codecache.stats)
    second = run_firmware(build, adc, acc)
    assert _delta(before)["compiles"] == 0 and _delta(before)["decodes"] == 0
    monkeypatch.setattr(codecache, "enabled", False)
    uncached = run_firmware(build, adc, acc)
    assert after_first["compiles"] >= 2
    for t in (second, uncached):
        assert np.array_equal(t.words, first.words) and np.array_equal(t.cycles, first.cycles)
        assert np.array_equal(t.init_words, first.init_words) and np.array_equal(t.init_cycles, first.init_cycles)
        assert (t.stack_bytes, t.ram_written) == (first.stack_bytes, first.ram_written)


def test_other_bytes_at_the_same_address_are_not_reused() -> None:
    """Same origin, one immediate different: the second program must not run the first one's block."""
    a = isa.assemble(" moveq #5,d0\n addq.l #1,d0\n trap #0\n", origin=0x1000).code
    b = isa.assemble(" moveq #9,d0\n addq.l #1,d0\n trap #0\n", origin=0x1000).code
    ra, rb = _run(a), _run(b)
    assert ra[1][0] == 6 and rb[1][0] == 10


def test_a_cached_decode_is_not_used_where_its_extension_word_is_unmapped() -> None:
    """CPU 1 decodes MOVE.L #imm,D0 with everything mapped; CPU 2 holds the same opcode word but only it is
    mapped: CPU 2 must bus-error on the immediate's fetch, not reuse CPU 1's decode."""
    code = isa.assemble(" move.l #$12345678,d0\n trap #0\n", origin=0x2000).code
    one = isa.CPU()
    one.write_bytes(0x2000, code)
    one.pc = 0x2000
    one.step()
    assert one.d[0] == 0x12345678
    two = isa.CPU(mapped=False)
    two.map(0x2000, 2, "tiny")
    two.write_bytes(0x2000, code[:2])
    two.pc = 0x2000
    with pytest.raises(BusError):
        two.step()
    with pytest.raises(BusError):
        two.run(max_instructions=5)


def test_the_memory_map_is_part_of_the_block_key() -> None:
    code = isa.assemble(LOOP, origin=0x1000).code
    _run(code)
    cpu = isa.CPU(mapped=False)
    cpu.map(0, 0x10000, "ram")
    cpu.write_bytes(0x1000, code)
    cpu.pc, cpu.a[7] = 0x1000, 0x8000
    before = dict(codecache.stats)
    cpu.run()
    assert _delta(before)["compiles"] >= 1  # another map: compiled for it
    assert cpu.d[0] == _run(code)[1][0]


def test_running_off_into_zero_filled_ram_keeps_the_cache_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    """$0000 words are ORI.B #0,D0: a CPU started in empty RAM compiles a new block every 160 instructions; the
    process-wide caches stay within their caps."""
    monkeypatch.setattr(codecache, "MAX_BLOCKS", 40)
    monkeypatch.setattr(codecache, "MAX_DECODED", 500)
    codecache.clear()
    cpu = isa.CPU()
    cpu.pc = 0x10000
    res = cpu.run(max_instructions=100 * 160, stop_at_limit=True)
    assert res.reason == "max_instructions" and cpu.pc == 0x10000 + 4 * 100 * 160
    assert codecache._n_blocks[0] <= 40 and sum(len(v) for v in codecache._blocks.values()) <= 40
    assert len(codecache._decoded) <= 500
    assert codecache.stats["evicted"] > 0
    codecache.clear()


# ------------------------------------------------------------------------------------------ block code on disk
FAULTING = """
        moveq   #5,d0
        lea     $6000,a0
        move.w  #20,d7
loop:   addx.l  d0,d1
        lsl.l   d0,d1
        roxr.w  #3,d2
        divu.w  d0,d3
        move.l  d1,(a0)+
        dbra    d7,loop
        move.l  $A00000,d4
        trap    #0
"""


def _fault_run(code: bytes) -> tuple[object, ...]:
    cpu = isa.CPU(mapped=False)
    cpu.map(0, 0x10000, "ram")
    cpu.write_bytes(0x1000, code)
    cpu.pc = 0x1000
    cpu.a[7] = 0x8000
    cpu.d[3] = 0x12345
    try:
        cpu.run()
        outcome: tuple[object, ...] = ("ok", "", None)
    except BusError as exc:
        outcome = ("bus", str(exc), exc.pc)
    return outcome + (tuple(cpu.d), tuple(cpu.a), cpu.sr, cpu.instructions, cpu.cycles,
                      cpu.read_bytes(0x6000, 0x100))


@pytest.mark.parametrize("text", [LOOP, FAULTING])
def test_block_code_from_disk_runs_like_generated_code(tmp_path, text: str) -> None:
    """Blocks compiled once and stored (use_disk), then loaded in a cleared process cache: the same registers,
    memory, counters and fault (PC, message: the line map survives marshal) as generated code and as closures;
    a corrupt file is a miss and is rewritten."""
    code = isa.assemble(text, origin=0x1000).code
    codecache.clear()
    plain = _fault_run(code)
    try:
        codecache.use_disk(tmp_path)
        before = dict(codecache.stats)
        codecache.clear()
        stored = _fault_run(code)
        d = _delta(before)
        assert d["disk_stores"] >= 1 and d["disk_hits"] == 0
        codecache.clear()
        loaded = _fault_run(code)
        d = _delta(before)
        assert d["disk_hits"] >= 1 and d["disk_hits"] == d["disk_stores"]
        assert plain == stored == loaded
        files = sorted(tmp_path.rglob("*.marshal"))
        assert files and not list(tmp_path.rglob(".tmp-*"))
        for f in files:
            f.write_bytes(b"not marshal data")
        codecache.clear()
        hits = codecache.stats["disk_hits"]
        assert _fault_run(code) == plain and codecache.stats["disk_hits"] == hits
        assert all(f.read_bytes() != b"not marshal data" for f in files)
    finally:
        codecache.use_disk(None)
        codecache.clear()
    closures = isa.CPU(mapped=False)
    closures.block_compile = False
    closures.map(0, 0x10000, "ram")
    closures.write_bytes(0x1000, code)
    closures.pc, closures.a[7], closures.d[3] = 0x1000, 0x8000, 0x12345
    try:
        closures.run()
        assert plain[:3] == ("ok", "", None)
    except BusError as exc:
        assert plain[:3] == ("bus", str(exc), exc.pc)
    assert plain[3:] == (tuple(closures.d), tuple(closures.a), closures.sr, closures.instructions,
                         closures.cycles, closures.read_bytes(0x6000, 0x100))
