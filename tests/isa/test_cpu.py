"""Interpreter semantics: faults, counters, run/call, register model and hand-computed edge cases per family.

Expected values are worked out by hand from the M68000 Programmer's Reference Manual (PRM, 1992, section 4
instruction pages; condition codes table 3-19) unless the comment says otherwise. The big random differential
tests against m68000-python/Musashi live elsewhere; a small one at the end checks flags and clocks for a few
instruction families on hypothesis-generated register states.
"""

from __future__ import annotations

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from tests.support.profiles import examples

import isa
from isa.cpu import CALL_SENTINEL, CPU, HANDLERS, MapError
from isa.errors import (AddressError, BusError, CPUFault, DivideByZero, IllegalInstruction, IsaError,
                        LimitExceeded)
from isa.table import TABLE

X, N, Z, V, C = 0x10, 8, 4, 2, 1
ORG = 0x1000


def run_src(src: str, *, setup: dict[str, int] | None = None, sr: int = 0x2700, cpu: CPU | None = None) -> CPU:
    """Assemble ``src`` (one instruction per line) followed by TRAP #0 at $1000, run it, return the CPU."""
    prog = isa.assemble(src + "\n trap #0\n", filename="t.s", origin=ORG)
    cpu = cpu or CPU()
    cpu.load(prog)
    cpu.a[7] = 0x8000
    for name, value in (setup or {}).items():
        getattr(cpu, name[0])[int(name[1])] = value
    cpu.sr = sr
    res = cpu.run(max_instructions=10_000)
    assert res.reason == "trap"
    return cpu


def one(src: str, **kw: object) -> tuple[CPU, int]:
    """Run a single instruction; return the CPU and its clock count."""
    prog = isa.assemble(src + "\n", filename="t.s", origin=ORG)
    cpu = CPU()
    cpu.load(prog)
    cpu.a[7] = 0x8000
    for name, value in kw.items():
        if name == "sr":
            cpu.sr = value  # type: ignore[assignment]  # **kw values are typed object; the sr values given are ints
        else:
            getattr(cpu, name[0])[int(name[1])] = value
    return cpu, cpu.step()


# ------------------------------------------------------------------------------------------------ contract
def test_handlers_match_table() -> None:
    assert set(HANDLERS) == {row.handler for row in TABLE}


def test_reset_state_and_register_views() -> None:
    cpu = CPU()
    assert cpu.sr == 0x2700 and cpu.pc == 0
    cpu.d[0] = -1
    assert cpu.d[0] == 0xFFFFFFFF
    cpu.a[7] = 0x1_0000_0004
    assert cpu.a[7] == 4
    cpu.sr = 0xA71F
    assert cpu.sr == 0xA71F and cpu.ccr == 0x1F
    with pytest.raises(MapError):
        cpu.d[8] = 0
    assert len(cpu.d) == 8 and list(cpu.a)[7] == 4


def test_memory_is_big_endian() -> None:
    cpu = CPU()
    cpu.write(0x2000, 0x12345678, 4)
    assert cpu.read_bytes(0x2000, 4) == b"\x12\x34\x56\x78"
    assert cpu.read(0x2002, 2) == 0x5678 and cpu.read(0x2001, 1) == 0x34


# ------------------------------------------------------------------------------------------------- faults
def mapped_cpu() -> CPU:
    cpu = CPU(mapped=False)
    cpu.map(0x0000, 0x4000, "rom", writable=False)
    cpu.map(0x4000, 0x4000, "ram")
    return cpu


def load_mapped(src: str) -> CPU:
    cpu = mapped_cpu()
    cpu.load(isa.assemble(src, filename="fault.s", origin=ORG))
    cpu.a[7] = 0x8000
    return cpu


def test_unmapped_read_is_bus_error_naming_pc_instruction_and_line() -> None:
    cpu = load_mapped(" nop\n move.w $9000,d0\n trap #0\n")
    with pytest.raises(BusError) as info:
        cpu.run()
    err = info.value
    assert err.pc == ORG + 2
    assert err.instruction.lower() == "move.w ($009000).l,d0"
    assert err.source == "fault.s:2"
    assert "$009000" in str(err) and "fault.s:2" in str(err)


@pytest.mark.parametrize("src, address", [
    (" move.l $20000,d1", 0x020000),  # wholly unmapped: its first byte (was $020002)
    (" move.l $7FFE,d1", 0x008000),  # straddles the end of RAM: the first unmapped byte (was the mapped $007FFE)
    (" movem.l $7FFC,d1-d2", 0x008000),  # the second register's long (was $008002)
    (" move.l d1,$7FFE", 0x008000),
    (" add.l $20000,d1", 0x020000),
    (" lea $7FFE,a0\n move.l (a0)+,d1", 0x008000),
])
@pytest.mark.parametrize("path", ["step", "closures", "blocks"])
def test_bus_error_on_a_long_names_the_first_unmapped_byte(src: str, address: int, path: str) -> None:
    # Issue 8.3, with RAM at $0-$7FFF as in the issue; m68000-python's stacked access address agrees
    # (tests/isa/test_vs_m68000py.py, test_bus_error_address_cases / test_bus_errors_name_the_faulting_access).
    cpu = CPU(mapped=False)
    cpu.map(0, 0x8000, "ram")
    cpu.load(isa.assemble(src + "\n trap #0\n", filename="bus.s", origin=0x1000))
    cpu.block_compile = path == "blocks"
    with pytest.raises(BusError) as info:
        if path == "step":
            for _ in range(3):
                cpu.step()
        else:
            cpu.run(max_instructions=10)
    assert f"unmapped address ${address:06X} at PC=" in str(info.value), str(info.value)


@pytest.mark.parametrize("path", ["step", "closures", "blocks"])
def test_brief_extension_bits_10_8_execute_as_on_the_68000(path: str) -> None:
    # Issue 8.1: d8(An,Xn) / d8(PC,Xn) with bits 10..8 of the brief word set (scale/full format on a 68020) run
    # as the 68000 runs them: the bits are ignored. Both forms must give the same registers and clocks.
    def run(junk: int) -> tuple[list[int], int]:
        cpu = CPU()
        # move.w 8(a0,d1.w),d2 ; lea 4(pc,d1.w),a1 (extension word at $1006) ; move.l -2(a0,d1.l),d3 ; trap #0
        words = [0x3430, 0x1008 | junk << 8, 0x43FB, 0x1004 | junk << 8, 0x2630, 0x18FE | junk << 8, 0x4E40]
        cpu.write_bytes(0x1000, b"".join(w.to_bytes(2, "big") for w in words))
        cpu.write_bytes(0x2000, bytes(range(64)))
        cpu.pc, cpu.a[0], cpu.d[1] = 0x1000, 0x2000, 0x10
        cpu.block_compile = path == "blocks"
        if path == "step":
            clocks = sum(cpu.step() for _ in range(4))
        else:
            cpu.run()
            clocks = cpu.cycles
        return [cpu.d[2], cpu.a[1], cpu.d[3]], clocks

    canonical = run(0)
    assert canonical[0] == [0x1819, 0x101A, 0x0E0F1011]
    for junk in range(1, 8):
        assert run(junk) == canonical


def test_write_to_rom_is_bus_error() -> None:
    cpu = load_mapped(" move.w d0,$0100\n")
    with pytest.raises(BusError, match="read-only"):
        cpu.step()
    assert cpu.read(0x100, 2) == 0  # nothing written


def test_host_may_write_rom_but_not_unmapped() -> None:
    cpu = mapped_cpu()
    cpu.write(0x100, 0xBEEF, 2)
    assert cpu.read(0x100, 2) == 0xBEEF
    with pytest.raises(BusError):
        cpu.write(0x9000, 1, 2)
    with pytest.raises(BusError):
        cpu.read(0x8000, 1)


def test_map_rejects_overlap_and_odd_regions() -> None:
    cpu = mapped_cpu()
    with pytest.raises(MapError, match="overlaps"):
        cpu.map(0x3000, 0x2000, "x")
    with pytest.raises(MapError, match="even"):
        cpu.map(0x9001, 2, "y")
    with pytest.raises(MapError):
        cpu.map(0xFFF000, 0x2000, "z")


def test_odd_word_access_is_address_error() -> None:
    cpu, _ = one(" nop")
    cpu2 = CPU()
    cpu2.load(isa.assemble(" move.w (a0),d0\n", filename="odd.s", origin=ORG))
    cpu2.a[0] = 0x4001
    with pytest.raises(AddressError) as info:
        cpu2.step()
    assert info.value.pc == ORG and info.value.source == "odd.s:1"
    # a byte access at the same address is fine
    cpu3 = CPU()
    cpu3.load(isa.assemble(" move.b (a0),d0\n", origin=ORG))
    cpu3.a[0] = 0x4001
    cpu3.step()


def test_odd_pc_and_odd_branch_target_are_address_errors() -> None:
    cpu = CPU()
    cpu.pc = 0x1001
    with pytest.raises(AddressError):
        cpu.step()
    cpu = CPU()
    cpu.load(isa.assemble(" jmp (a0)\n", origin=ORG))
    cpu.a[0] = 0x2001
    with pytest.raises(AddressError) as info:
        cpu.step()
    assert info.value.pc == ORG


@pytest.mark.parametrize("count, block", [(0, False), (0, True), (5, False), (5, True)])
def test_dbcc_to_an_odd_target_faults_even_when_the_count_expires(count: int, block: bool) -> None:
    # DBRA D0 with displacement $8001 (odd): UM 8-8 gives the expired case 14(3/0), three reads, one of them the
    # target word, so the 68000 address-errors whether or not the loop continues (m68000-python agrees).
    cpu = CPU()
    cpu.block_compile = block
    cpu.write_bytes(0xC000, bytes.fromhex("51c880014e71"))
    cpu.pc = 0xC000
    cpu.d[0] = count
    with pytest.raises(AddressError, match="odd"):
        cpu.run(max_instructions=2)


def test_illegal_and_undecodable_opcodes() -> None:
    cpu = load_mapped(" nop\n illegal\n")
    with pytest.raises(IllegalInstruction) as info:
        cpu.run()
    assert info.value.pc == ORG + 2 and info.value.source == "fault.s:2"
    cpu = CPU()
    cpu.write(ORG, 0xFFFF, 2)  # line-F opcode: not in the subset
    cpu.pc = ORG
    with pytest.raises(IllegalInstruction):
        cpu.step()


def test_divide_by_zero() -> None:
    cpu = load_mapped(" moveq #0,d1\n divu d1,d0\n")
    with pytest.raises(DivideByZero) as info:
        cpu.run()
    assert info.value.pc == ORG + 2 and "divu" in info.value.instruction.lower()


def test_limits() -> None:
    cpu = load_mapped("loop: bra.s loop\n")
    with pytest.raises(LimitExceeded):
        cpu.run(max_instructions=100)
    assert cpu.instructions == 100 and cpu.cycles == 1000  # BRA.S = 10 clocks (UM Table 8-8)
    res = cpu.run(max_cycles=95, stop_at_limit=True)
    # an instruction starts while fewer than 95 clocks have run: 10 BRAs
    assert res.reason == "max_cycles" and res.instructions == 10 and res.cycles == 100
    with pytest.raises(LimitExceeded):
        cpu.call(ORG, max_cycles=1000)


def test_bus_error_on_fetch_from_unmapped() -> None:
    cpu = mapped_cpu()
    cpu.pc = 0x9000
    with pytest.raises(BusError, match="fetch"):
        cpu.step()


# ------------------------------------------------------------------------------------------ run / call
def test_trap_stops_run_with_pc_after_trap() -> None:
    cpu = CPU()
    cpu.load(isa.assemble(" moveq #3,d0\n trap #5\n moveq #4,d0\n", origin=ORG))
    res = cpu.run()
    assert (res.reason, res.trap_number, res.instructions, res.pc) == ("trap", 5, 2, ORG + 4)
    assert cpu.pc == ORG + 4 and cpu.d[0] == 3
    assert res.cycles == 4 + 34  # MOVEQ 4, TRAP counted as the manual's 34 (UM Table 8-10)


def test_until_pc() -> None:
    cpu = CPU()
    cpu.load(isa.assemble(" nop\n nop\nthere: nop\n trap #0\n", origin=ORG))
    res = cpu.run(until_pc=ORG + 4)
    assert res.reason == "until_pc" and res.instructions == 2 and res.cycles == 8 and cpu.pc == ORG + 4


def test_call_counts_from_first_instruction_through_rts() -> None:
    src = """
sub:    moveq #7,d0        ; 4
        add.l d0,d1        ; 8 (ADD.L Dn,Dn, UM Table 8-4 note **)
        rts                ; 16
"""
    cpu = CPU()
    cpu.load(isa.assemble(src, origin=ORG))
    cpu.a[7] = 0x8000
    cpu.pc = 0x2222
    assert cpu.call(ORG) == 4 + 8 + 16
    assert cpu.d[1] == 7 and cpu.a[7] == 0x8000 and cpu.pc == 0x2222
    assert cpu.min_sp == 0x8000 - 4  # the pushed return address
    assert cpu.read(0x8000 - 4, 4) == CALL_SENTINEL


def test_call_with_trap_inside_raises() -> None:
    cpu = CPU()
    cpu.load(isa.assemble(" trap #1\n rts\n", origin=ORG))
    cpu.a[7] = 0x8000
    with pytest.raises(CPUFault, match="TRAP"):
        cpu.call(ORG)


def test_counters_profile_min_sp_ram_written() -> None:
    src = """
        moveq #2,d1
loop:   move.l d1,-(a7)     ; pushes
        move.w d1,$5000
        dbra d1,loop
        trap #0
"""
    cpu = CPU()
    cpu.load(isa.assemble(src, origin=ORG))
    cpu.a[7] = 0x8000
    cpu.reset_counters()
    cpu.profiling = True
    res = cpu.run()
    assert res.instructions == 1 + 3 * 3 + 1
    # 4 + 3*(12 MOVE.L Dn,-(An) + 12 MOVE.W Dn,abs.L) + DBRA 10,10,14 + TRAP 34 (UM Tables 8-2, 8-3, 8-8)
    assert res.cycles == 4 + 3 * 12 + 3 * 16 + 10 + 10 + 14 + 34
    assert cpu.instructions == res.instructions and cpu.cycles == res.cycles
    assert cpu.profile[ORG + 2] == [3, 36]
    assert cpu.min_sp == 0x8000 - 12
    assert cpu.ram_written == 12 + 2  # three longs on the stack + one word
    assert cpu.written_ranges() == [(0x5000, 0x5002), (0x8000 - 12, 0x8000)]
    cpu.reset_counters()
    assert cpu.ram_written == 0 and cpu.instructions == 0 and cpu.profile == {}


def test_self_modifying_code_invalidates_cache() -> None:
    # the loop body's first instruction is rewritten from MOVEQ #1,D0 to MOVEQ #2,D0 between passes
    src = """
        moveq #1,d3
loop:   moveq #1,d0
        add.l d0,d2
        move.w #$7002,loop
        dbra d3,loop
        trap #0
"""
    cpu = run_src(src)
    assert cpu.d[2] == 1 + 2


def test_load_program_bss_and_source_map() -> None:
    prog = isa.assemble(" section code\n move.w var,d0\n trap #0\n section bss\nvar: ds.w 1\n", origin=ORG)
    cpu = CPU()
    cpu.write_bytes(prog.symbol("var").address, b"\xff\xff")
    cpu.load(prog)
    assert cpu.read(prog.symbol("var").address, 2) == 0  # bss zeroed
    assert cpu.pc == ORG and cpu.source_map


# --------------------------------------------------------------------------------------- move family
def test_move_flags_keep_x() -> None:
    cpu, c = one(" move.w d1,d0", d0=0x12345678, d1=0xFFFF8000, sr=0x2700 | X | V | C)
    assert cpu.d[0] == 0x12348000 and cpu.sr == 0x2700 | X | N and c == 4


def test_movea_sign_extends_and_leaves_flags() -> None:
    cpu, c = one(" movea.w d1,a0", d1=0x0000FFFE, sr=0x2700 | Z)
    assert cpu.a[0] == 0xFFFFFFFE and cpu.sr == 0x2700 | Z and c == 4


def test_moveq_sign_extends() -> None:
    cpu, _ = one(" moveq #-128,d5")
    assert cpu.d[5] == 0xFFFFFF80 and cpu.ccr == N


def test_byte_access_through_a7_moves_by_two() -> None:
    cpu = run_src(" move.b d0,-(a7)\n move.b (a7)+,d1\n move.b (a0)+,d2", setup={"d0": 0xAB, "a0": 0x3000})
    assert cpu.a[7] == 0x8000 and cpu.d[1] == 0xAB and cpu.a[0] == 0x3001
    assert cpu.read(0x8000 - 2, 1) == 0xAB  # high byte of the pushed word


def test_movem_order_and_writeback() -> None:
    # PRM 4-128: -(An) stores A7..D0 downwards, An ends at the last address; the 68000 stores An's initial value
    cpu = run_src(" movem.l d0/d1/a0,-(a0)", setup={"d0": 0x11, "d1": 0x22, "a0": 0x3000})
    assert cpu.a[0] == 0x3000 - 12
    assert [cpu.read(0x3000 - 12 + 4 * i, 4) for i in range(3)] == [0x11, 0x22, 0x3000]
    # memory -> registers: words sign-extended, (An)+ written back after the loads
    cpu = CPU()
    cpu.write_bytes(0x3000, bytes.fromhex("8001 0002 7fff"))
    cpu = run_src(" movem.w (a1)+,d3/d4/a2", setup={"a1": 0x3000}, cpu=cpu)
    assert (cpu.d[3], cpu.d[4], cpu.a[2], cpu.a[1]) == (0xFFFF8001, 2, 0x7FFF, 0x3006)


def test_lea_pea_exg_swap_ext() -> None:
    cpu = run_src(" lea -4(a0,d0.w),a1\n pea 8(a1)\n exg d0,a0\n swap d1\n ext.w d2\n ext.l d3",
                  setup={"a0": 0x3000, "d0": 0x0001FFFE, "d1": 0x12348000, "d2": 0x00000080, "d3": 0xFFFF7FFF})
    assert cpu.a[1] == 0x3000 - 2 - 4
    assert cpu.read(0x8000 - 4, 4) == 0x3000 - 6 + 8
    assert cpu.a[0] == 0x0001FFFE and cpu.d[0] == 0x3000
    assert cpu.d[1] == 0x80001234
    assert cpu.d[2] == 0x0000FF80
    assert cpu.d[3] == 0x00007FFF and cpu.ccr == 0  # EXT.L result positive, nonzero


def test_swap_flags() -> None:
    cpu, _ = one(" swap d0", d0=0x00008000)  # -> $80000000: N from bit 31
    assert cpu.d[0] == 0x80000000 and cpu.ccr == N


# -------------------------------------------------------------------------------------- arithmetic
def test_add_carry_overflow_and_x() -> None:
    cpu, c = one(" add.w d1,d0", d0=0x7FFF, d1=1)
    assert cpu.d[0] == 0x8000 and cpu.ccr == N | V and c == 4
    cpu, _ = one(" add.b d1,d0", d0=0x1FF, d1=1)
    assert cpu.d[0] == 0x100 and cpu.ccr == X | Z | C


def test_sub_cmp_and_x() -> None:
    cpu, _ = one(" sub.l d1,d0", d0=0, d1=1)
    assert cpu.d[0] == 0xFFFFFFFF and cpu.ccr == X | N | C
    cpu, _ = one(" cmp.l d1,d0", d0=0x80000000, d1=1, sr=0x2700 | X)
    assert cpu.d[0] == 0x80000000 and cpu.ccr == X | V  # CMP leaves X


def test_addx_subx_negx_z_rule() -> None:
    # Z is cleared if the result is nonzero, unchanged otherwise (PRM 4-14, 4-184, 4-140)
    cpu, _ = one(" addx.l d1,d0", d0=0xFFFFFFFF, d1=0, sr=0x2700 | X | Z)
    assert cpu.d[0] == 0 and cpu.ccr == X | Z | C
    cpu, _ = one(" addx.l d1,d0", d0=0xFFFFFFFF, d1=0, sr=0x2700 | X)
    assert cpu.d[0] == 0 and cpu.ccr == X | C  # Z stays clear
    cpu, _ = one(" subx.w d1,d0", d0=5, d1=4, sr=0x2700 | X | Z)
    assert cpu.d[0] == 0 and cpu.ccr == Z
    cpu, _ = one(" negx.b d0", d0=0, sr=0x2700 | X | Z)
    assert cpu.d[0] == 0xFF and cpu.ccr == X | N | C
    cpu, _ = one(" negx.b d0", d0=0, sr=0x2700 | Z)
    assert cpu.d[0] == 0 and cpu.ccr == Z


def test_cmpm_compares_and_post_increments() -> None:
    # CMPM (Ay)+,(Ax)+ (issue 8.2): flags of (Ax) - (Ay) as CMP, X unchanged; Ay read first; A7 steps 2 for bytes.
    X, N, Z, V, C = 0x10, 0x08, 0x04, 0x02, 0x01
    cpu = CPU()
    cpu.write_bytes(0x3000, bytes.fromhex("05 80 7FFF 00000001"))
    cpu.write_bytes(0x4000, bytes.fromhex("05 7F 8000 80000000"))
    cpu.load(isa.assemble(" cmpm.b (a0)+,(a1)+\n cmpm.b (a0)+,(a1)+\n cmpm.w (a0)+,(a1)+\n cmpm.l (a0)+,(a1)+\n"
                          " cmp.b (a7)+,(a7)+\n trap #0\n", origin=ORG))
    cpu.a[0], cpu.a[1], cpu.a[7], cpu.sr = 0x3000, 0x4000, 0x5000, 0x2700 | X
    clocks = cpu.step()
    assert (cpu.sr & 0x1F, clocks, cpu.a[0], cpu.a[1]) == (X | Z, 12, 0x3001, 0x4001)  # 5 - 5
    cpu.step()
    assert cpu.sr & 0x1F == X | N | V | C  # $7F - $80 = $FF: borrow, and 127 - (-128) overflows
    cpu.step()
    assert cpu.sr & 0x1F == X | V  # $8000 - $7FFF = 1: overflow (negative minus positive gives positive)
    clocks = cpu.step()
    assert (cpu.sr & 0x1F, clocks, cpu.a[0], cpu.a[1]) == (X | V, 20, 0x3008, 0x4008)  # $80000000 - 1
    cpu.write_bytes(0x5000, bytes.fromhex("0102 0300"))
    cpu.step()  # cmp.b (a7)+,(a7)+ assembles as CMPM: reads $5000 then $5002 (A7 keeps word alignment)
    assert cpu.a[7] == 0x5004 and cpu.sr & 0x1F == X  # 3 - 1 = 2
    assert isa.assemble(" cmp.w (a2)+,(a3)+\n cmpm.l (a7)+,(a7)+\n").code == bytes.fromhex("B74A BF8F")
    with pytest.raises(IsaError, match="cmpm"):
        isa.assemble(" cmpm.b d0,d1\n")


def test_addx_memory_predecrement() -> None:
    cpu = CPU()
    cpu.write(0x3000, 0x0001, 2)
    cpu.write(0x4000, 0xFFFF, 2)
    cpu = run_src(" addx.w -(a0),-(a1)", setup={"a0": 0x3002, "a1": 0x4002}, cpu=cpu, sr=0x2700)
    assert cpu.read(0x4000, 2) == 0 and cpu.a[0] == 0x3000 and cpu.a[1] == 0x4000
    assert cpu.ccr == X | C  # Z was clear and stays clear


def test_neg_and_not() -> None:
    cpu, _ = one(" neg.w d0", d0=0x8000)
    assert cpu.d[0] == 0x8000 and cpu.ccr == X | N | V | C
    cpu, _ = one(" neg.l d0", d0=0)
    assert cpu.d[0] == 0 and cpu.ccr == Z
    cpu, _ = one(" not.b d0", d0=0xFF, sr=0x2700 | X)
    assert cpu.d[0] == 0 and cpu.ccr == X | Z


def test_adda_addq_subq_to_address_register() -> None:
    cpu, c = one(" adda.w d0,a0", d0=0xFFFF, a0=0x10, sr=0x2700 | Z)
    assert cpu.a[0] == 0xF and cpu.ccr == Z and c == 8
    cpu, c = one(" subq.w #1,a0", a0=0)  # whole register, no flags
    assert cpu.a[0] == 0xFFFFFFFF and cpu.ccr == 0 and c == 8


def test_cmpa_sign_extends_word() -> None:
    cpu, c = one(" cmpa.w d0,a0", d0=0xFFFF, a0=0xFFFFFFFF)
    assert cpu.ccr == Z and c == 6


def test_clr_tst() -> None:
    cpu, c = one(" clr.l d0", d0=5, sr=0x2700 | X | N | V | C)
    assert cpu.d[0] == 0 and cpu.ccr == X | Z and c == 6
    cpu, _ = one(" tst.w d0", d0=0x18000, sr=0x2700 | V | C)
    assert cpu.ccr == N


def test_mulu_muls() -> None:
    cpu, c = one(" mulu.w d1,d0", d0=0xFFFF, d1=0xFFFF)
    assert cpu.d[0] == 0xFFFE0001 and cpu.ccr == N and c == 38 + 2 * 16
    cpu, c = one(" muls.w d1,d0", d0=0x1234FFFF, d1=0xFFFF)  # -1 * -1
    assert cpu.d[0] == 1 and cpu.ccr == 0 and c == 38 + 2 * 1  # $FFFF<<1 = 1_1111_1111_1111_1110: one 1->0 edge


def test_divu_divs_results_and_overflow() -> None:
    cpu, _ = one(" divu.w d1,d0", d0=100_003, d1=10)
    assert cpu.d[0] == (3 << 16) | 10_000 and cpu.ccr == 0
    cpu, _ = one(" divs.w d1,d0", d0=(-7) & 0xFFFFFFFF, d1=2)  # -7/2 = -3 rem -1 (remainder has dividend's sign)
    assert cpu.d[0] == 0xFFFFFFFD and cpu.ccr == N
    # overflow: V set, Dn unchanged (PRM 4-96); N=1 Z=0 C=0 as the real chip leaves them (m68000-python, Musashi)
    cpu, c = one(" divu.w d1,d0", d0=0x00100000, d1=1, sr=0x2700 | X | Z | C)
    assert cpu.d[0] == 0x00100000 and cpu.ccr == X | N | V and c == 10
    cpu, _ = one(" divs.w d1,d0", d0=0x00008000, d1=1)
    assert cpu.d[0] == 0x00008000 and cpu.ccr & V


# ------------------------------------------------------------------------------------------- logic
def test_logic_clear_v_c_keep_x() -> None:
    cpu, _ = one(" and.w d1,d0", d0=0xFFFF, d1=0x8000, sr=0x2700 | X | V | C)
    assert cpu.d[0] == 0x8000 and cpu.ccr == X | N
    cpu, _ = one(" eori.b #$FF,d0", d0=0xFF)
    assert cpu.d[0] == 0 and cpu.ccr == Z
    cpu, _ = one(" ori.l #0,d0", d0=0)
    assert cpu.ccr == Z


# ------------------------------------------------------------------------------------------ shifts
def test_shift_by_zero_register_count() -> None:
    # count 0: C cleared, X unaffected (PRM 4-22); ROXL by 0: C = X
    cpu, c = one(" lsl.l d1,d0", d0=0x80000000, d1=64, sr=0x2700 | X | C)  # 64 mod 64 = 0
    assert cpu.d[0] == 0x80000000 and cpu.ccr == X | N and c == 8
    cpu, _ = one(" roxl.w d1,d0", d0=0x1234, d1=0, sr=0x2700 | X)
    assert cpu.d[0] == 0x1234 and cpu.ccr == X | C


def test_shift_by_width_or_more() -> None:
    cpu, c = one(" lsr.b d1,d0", d0=0x80, d1=8)
    assert cpu.d[0] == 0 and cpu.ccr == X | Z | C and c == 6 + 16
    cpu, _ = one(" lsr.b d1,d0", d0=0xFF, d1=9)
    assert cpu.d[0] == 0 and cpu.ccr == Z
    cpu, _ = one(" asr.w d1,d0", d0=0x8000, d1=40)
    assert cpu.d[0] == 0xFFFF and cpu.ccr == X | N | C
    cpu, c = one(" asl.l d1,d0", d0=1, d1=33)
    assert cpu.d[0] == 0 and cpu.ccr == Z | V and c == 8 + 66


def test_asl_overflow_if_msb_changes_anytime() -> None:
    cpu, _ = one(" asl.b #2,d0", d0=0x40)  # 0100_0000 -> 1000_0000 -> 0000_0000: MSB changed
    assert cpu.d[0] == 0 and cpu.ccr == X | Z | V | C
    cpu, _ = one(" asl.b #1,d0", d0=0xC0)  # 1100_0000 -> 1000_0000: MSB unchanged
    assert cpu.d[0] == 0x80 and cpu.ccr == X | N | C


def test_rotates() -> None:
    cpu, _ = one(" rol.w #4,d0", d0=0x1234, sr=0x2700 | X)
    assert cpu.d[0] == 0x2341 and cpu.ccr == X | C  # X unaffected, C = last bit out (bit 0 of result)
    cpu, _ = one(" ror.l #1,d0", d0=1)
    assert cpu.d[0] == 0x80000000 and cpu.ccr == N | C
    cpu, _ = one(" roxr.b #1,d0", d0=0x01, sr=0x2700 | X)  # X enters bit 7, bit 0 goes to X and C
    assert cpu.d[0] == 0x80 and cpu.ccr == X | N | C
    cpu, _ = one(" roxl.b d1,d0", d0=0x5A, d1=9)  # 9 = width + 1: back where it started
    assert cpu.d[0] == 0x5A and cpu.ccr == 0


def test_memory_shift() -> None:
    cpu = CPU()
    cpu.write(0x3000, 0x8001, 2)
    cpu = run_src(" asr.w (a0)", setup={"a0": 0x3000}, cpu=cpu)
    assert cpu.read(0x3000, 2) == 0xC000 and cpu.ccr == X | N | C


# ------------------------------------------------------------------------------------ program control
@pytest.mark.parametrize(
    ("cond", "ccr", "taken"),
    [("hi", 0, True), ("hi", C, False), ("ls", Z, True), ("ge", N | V, True), ("ge", N, False),
     ("lt", V, True), ("gt", 0, True), ("gt", Z, False), ("le", N, True), ("pl", 0, True), ("mi", N, True),
     ("vc", V, False), ("vs", V, True), ("cc", C, False), ("cs", C, True), ("ne", Z, False), ("eq", Z, True)],
)
def test_bcc_conditions_and_clocks(cond: str, ccr: int, taken: bool) -> None:
    cpu, c = one(f" b{cond}.s *+$10", sr=0x2700 | ccr)
    assert cpu.pc == (ORG + 0x10 if taken else ORG + 2)
    assert c == (10 if taken else 8)  # UM Table 8-8
    cpu, c = one(f" b{cond}.w *+$100", sr=0x2700 | ccr)
    assert c == (10 if taken else 12)


def test_dbcc_cases() -> None:
    cpu, c = one(" dbeq d0,*-4", d0=5, sr=0x2700 | Z)  # condition true: fall through, 12
    assert cpu.d[0] == 5 and cpu.pc == ORG + 4 and c == 12
    cpu, c = one(" dbra d0,*-4", d0=0x12340001)  # loop: 10
    assert cpu.d[0] == 0x12340000 and cpu.pc == ORG - 4 and c == 10
    cpu, c = one(" dbra d0,*-4", d0=0x12340000)  # expired: 14, low word -1, upper word kept
    assert cpu.d[0] == 0x1234FFFF and cpu.pc == ORG + 4 and c == 14


def test_scc() -> None:
    cpu, c = one(" seq d0", d0=0x12345600, sr=0x2700 | Z)
    assert cpu.d[0] == 0x123456FF and c == 6
    cpu, c = one(" sne d0", d0=0x123456FF, sr=0x2700 | Z)
    assert cpu.d[0] == 0x12345600 and c == 4


def test_bsr_jsr_rts() -> None:
    src = """
        bsr.s sub          ; 18
        jsr sub            ; abs.L: 20
        trap #0
sub:    addq.l #1,d0       ; 8
        rts                ; 16
"""
    cpu = CPU()
    cpu.load(isa.assemble(src, origin=ORG))
    cpu.a[7] = 0x8000
    res = cpu.run()
    assert cpu.d[0] == 2 and cpu.a[7] == 0x8000
    assert res.cycles == 18 + 8 + 16 + 20 + 8 + 16 + 34


# ------------------------------------------------------------------------ differential spot check
try:
    from m68000_python import CPUState, M68000CPU

    HAVE_REF = True
except ImportError:  # pragma: no cover
    HAVE_REF = False

_FAMILY = [" add.l d1,d0", " sub.w d1,d0", " addx.b d1,d0", " subx.l d1,d0", " negx.w d0", " cmp.b d1,d0",
           " asl.w d1,d0", " asr.l d1,d0", " roxl.b d1,d0", " roxr.l d1,d0", " rol.w d1,d0", " lsr.b d1,d0",
           " muls.w d1,d0", " mulu.w d1,d0", " divu.w d1,d0", " divs.w d1,d0", " ext.l d0", " neg.b d0"]


@pytest.mark.skipif(not HAVE_REF, reason="m68000-python not installed")
@given(st.sampled_from(_FAMILY), st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1), st.integers(0, 31))
def test_against_m68000_python(src: str, d0: int, d1: int, ccr: int) -> None:
    if "div" in src and d1 & 0xFFFF == 0:
        d1 |= 1
    prog = isa.assemble(src + "\n", origin=ORG)
    cpu = CPU()
    cpu.load(prog)
    cpu.d[0], cpu.d[1], cpu.sr = d0, d1, 0x2700 | ccr
    clocks = cpu.step()
    mem = bytearray(0x2000)
    mem[ORG : ORG + len(prog.code)] = prog.code

    def rw(a: int) -> int:
        a &= 0xFFFFFF
        return (mem[a] << 8) | mem[a + 1] if a + 1 < len(mem) else 0

    ref = M68000CPU(lambda a: mem[a & 0x1FFF], rw, lambda a, v: None, lambda a, v: None)
    ref.restore_state(CPUState(d=(d0, d1) + (0,) * 6, ssp=0x1800, sr=0x2700 | ccr, pc=ORG, ir=rw(ORG),
                               irc=rw(ORG + 2)))
    ref_clocks = ref.step()
    assert (cpu.d[0], cpu.d[1], cpu.ccr, clocks) == (ref.R[0], ref.R[1], ref.SR & 0x1F, ref_clocks)


def test_execute_hand_built_instruction() -> None:
    from isa.operands import Instruction, Mode, Operand, Size

    cpu = CPU()
    cpu.pc = 0x2000
    cpu.d[1], cpu.d[2] = 0xFFFFFFFF, 1
    ins = Instruction("add", Size.L, (Operand(Mode.DREG, 2), Operand(Mode.DREG, 1)))
    assert cpu.execute(ins, 2) == 8  # ADD.L Dn,Dn (UM Table 8-4 note **)
    assert cpu.d[1] == 0 and cpu.ccr == X | Z | C and cpu.pc == 0x2002 and cpu.instructions == 1


# ------------------------------------------------------------------------------------------ caller()
_CALLER_ROUTINES = {
    "one block": " moveq #7,d0\n add.l d0,d1\n move.l d1,$5000\n rts\n",
    "loop": " moveq #3,d2\nloop: add.l d2,d1\n move.w d1,$5002\n dbra d2,loop\n rts\n",
    "two blocks": " bsr.s sub\n addq.l #1,d3\n rts\nsub: addq.l #2,d3\n rts\n",
    "bus error": " addq.l #1,d4\n move.l $9000,d0\n rts\n",
    "trap": " addq.l #1,d4\n trap #1\n rts\n",
    "runaway": "loop: addq.l #1,d5\n bra.s loop\n",
    "rewrites itself": "top: addq.l #1,d6\n move.w #$5287,top\n rts\n",  # ADDQ.L #1,D6 becomes ADDQ.L #1,D7
}


def _caller_cpu() -> CPU:
    cpu = CPU(mapped=False)
    cpu.map(0, 0x8000, "ram")  # $9000 and above unmapped; $8000..$8FFF a ROM
    cpu.map(0x8000, 0x1000, "rom", writable=False)
    cpu.a[7] = 0x7000
    return cpu


def _cpu_state(cpu: CPU) -> tuple[object, ...]:
    return (list(cpu.d), list(cpu.a), cpu.pc, cpu.sr, cpu.instructions, cpu.cycles, cpu.min_sp, cpu.ram_written,
            cpu.written_ranges(), cpu.read_bytes(0, 0x8000), cpu.last_trap, dict(cpu.profile))


@given(routine=st.sampled_from(sorted(_CALLER_ROUTINES)), budget=st.sampled_from([3, 40, 500, 10_000]),
       steps=st.lists(st.tuples(st.sampled_from(["", "", "sp", "profiling", "blocks"]),
                                st.sampled_from([0x6FFE, 0x7002, 0x8000, 0x8008, 0x9004, 0x4])),
                      min_size=2, max_size=8))
@settings(max_examples=examples(60), deadline=None)
@example(routine="one block", budget=10_000, steps=[("", 0)] * 3)
@example(routine="loop", budget=500, steps=[("", 0), ("", 0), ("profiling", 0), ("", 0), ("blocks", 0), ("", 0)])
@example(routine="two blocks", budget=10_000, steps=[("", 0)] * 3)
@example(routine="bus error", budget=10_000, steps=[("", 0)] * 3)
@example(routine="trap", budget=10_000, steps=[("", 0)] * 3)
@example(routine="runaway", budget=500, steps=[("", 0)] * 3)
@example(routine="rewrites itself", budget=10_000, steps=[("", 0)] * 3)
@example(routine="one block", budget=10_000, steps=[("", 0), ("sp", 0x8008), ("sp", 0x9004), ("", 0)])
def test_caller_does_exactly_what_call_does(routine: str, budget: int, steps: list[tuple[str, int]]) -> None:
    """caller(address, budget)() against call(address, budget) on a twin CPU, and against the per-instruction
    closures (block_compile off) on a third: same clocks or the same fault (class and message), then the same
    registers, PC, counters, min_sp, RAM and profile. Each step first sets the stack pointer back to $7000 (the
    return address then goes to RAM written before: the lean path), or moves it elsewhere (odd, into the ROM,
    unmapped), or switches profiling or block compiling; then it calls."""
    prog = isa.assemble(_CALLER_ROUTINES[routine], filename="r.s", origin=ORG)
    twins = [_caller_cpu() for _ in range(3)]
    twins[2].block_compile = False
    for cpu in twins:
        cpu.load(prog)
        cpu.pc = 0x2222
    run = twins[1].caller(ORG, max_cycles=budget)
    for op, value in steps:
        if op in ("", "sp"):
            for cpu in twins:
                cpu.a[7] = value if op else 0x7000
        else:
            for cpu in twins[:2]:
                if op == "profiling":
                    cpu.profiling = not cpu.profiling
                else:
                    cpu.block_compile = not cpu.block_compile
            twins[2].profiling = twins[0].profiling
        outcomes = []
        for i, cpu in enumerate(twins):
            try:
                outcomes.append(run() if i == 1 else cpu.call(ORG, max_cycles=budget))
            except CPUFault as exc:
                outcomes.append((type(exc), str(exc)))
        assert outcomes[0] == outcomes[1] == outcomes[2]
        assert _cpu_state(twins[0]) == _cpu_state(twins[1]) == _cpu_state(twins[2])


def test_caller_runs_the_entry_block_itself() -> None:
    """The lean path is taken (not call()) once the entry block is compiled, and a recompiled block is used; the
    clocks and D1 equal a twin CPU's plain call()s."""
    cpu, twin = _caller_cpu(), _caller_cpu()
    for c in (cpu, twin):
        c.load(isa.assemble(_CALLER_ROUTINES["one block"], origin=ORG))
    calls = []
    plain = cpu.call
    cpu.call = lambda *a, **k: (calls.append(a), plain(*a, **k))[1]  # type: ignore[method-assign]  # a spy wraps the method for the test
    run = cpu.caller(ORG)
    assert [run() for _ in range(4)] == [twin.call(ORG) for _ in range(4)]
    assert len(calls) == 1 and cpu.d[1] == twin.d[1] == 28
    for c in (cpu, twin):
        c.write(ORG, 0x7009, 2)  # host write over the code: MOVEQ #9,D0; the block is dropped
    assert run() == twin.call(ORG) and len(calls) == 2 and cpu.d[1] == twin.d[1] == 37
    assert run() == twin.call(ORG) and len(calls) == 2 and cpu.d[1] == twin.d[1] == 46
