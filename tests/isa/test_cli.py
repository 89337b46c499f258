"""End-to-end tests of ``fwemu asm`` / ``fwemu exec`` (:mod:`isa.cli`) and of the shipped demo program.

The demo's results are checked against the same computation done independently in Python (sort, sums, checksum),
and its bytes against GNU as (``m68k-linux-gnu-as`` + ``ld``) when those are installed.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import isa.cli
from isa.assembler import assemble
from isa.listing import to_binary

DEMO = Path(isa.cli.__file__).parent / "demo" / "demo.s"
REPO = Path(__file__).resolve().parents[2]
DEMO_TABLE = [907, -12, 33, 4096, -2048, 0, 77, -1, 15000, 250, -32768, 32767, 5]


def fwemu(argv: list[str]) -> int:
    """Run ``fwemu`` through the real entry point when every command module exists, else ``isa.cli`` alone (same
    ``register`` contract and error handling)."""
    try:
        from firmware_model.cli.main import build_parser, main

        build_parser()
    except ModuleNotFoundError:
        return isa.cli.main(argv)
    return main(argv)


def registers(out: str) -> dict[str, int]:
    return {name: int(value, 16) for name, value in re.findall(r"\b([DA][0-7]|PC|SR) = \$([0-9A-F]+)", out)}


# --- exec ---------------------------------------------------------------------------------------------------------


def test_exec_demo_matches_an_independent_computation(capsys: pytest.CaptureFixture[str]) -> None:
    assert fwemu(["exec", str(DEMO)]) == 0
    out = capsys.readouterr().out
    regs = registers(out)
    table = sorted(DEMO_TABLE)
    checksum = 0
    for v in table:  # rol.w #3 then eor.w
        checksum = (((checksum << 3) | (checksum >> 13)) & 0xFFFF) ^ (v & 0xFFFF)
    assert regs["D0"] == sum(table) & 0xFFFFFFFF
    assert regs["D1"] & 0xFFFF == checksum
    assert regs["D2"] == sum(v * v for v in table) & 0xFFFFFFFF
    assert regs["D3"] == table[len(table) // 2] & 0xFFFFFFFF
    assert regs["A7"] == isa.cli.DEFAULT_STACK and regs["SR"] == 0x2700
    assert "stopped: TRAP #0" in out
    m = re.search(r"instructions: (\d+)\s+cycles: (\d+)", out)
    assert m is not None and int(m.group(1)) > 100 and int(m.group(2)) > 4 * int(m.group(1))
    # The data section follows the code, so the sorted table ends right after the code: A1 = end of table.
    prog = assemble(DEMO.read_text(), filename=str(DEMO), origin=isa.cli.DEFAULT_ORIGIN)
    assert regs["A0"] == prog.symbol("table").address and regs["A1"] == prog.symbol("table_end").address
    # TRAP #0 is the last code word and data follows the code directly: PC after the TRAP = the table address.
    assert regs["PC"] == prog.symbol("table").address


def test_exec_stops_at_instruction_limit(capsys: pytest.CaptureFixture[str]) -> None:
    assert fwemu(["exec", str(DEMO), "--max-instructions", "10"]) == 1
    out = capsys.readouterr().out
    assert "instruction limit 10" in out and "instructions: 10 " in out


def test_exec_stops_at_cycle_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "spin.s"
    src.write_text("loop bra.s loop\n")  # BRA.S: 10 clocks each
    assert fwemu(["exec", str(src), "--max-cycles", "100"]) == 1
    out = capsys.readouterr().out
    assert "cycle limit 100" in out and "instructions: 10    cycles: 100" in out


def test_exec_fault_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "odd.s"
    src.write_text(" nop\n move.w $1001,d0 ; odd address\n trap #0\n")
    assert fwemu(["exec", str(src)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fwemu: error: ") and err.count("\n") == 1
    assert "$001002" in err and f"{src}:2" in err and "Traceback" not in err


def test_exec_origin_and_defines(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "d.s"
    src.write_text(" move.l #N,d0\n lea *(pc),a0\n trap #1\n")
    assert fwemu(["exec", str(src), "--origin", "$2000", "-D", "N=0x1234"]) == 0
    regs = registers(capsys.readouterr().out)
    assert regs["D0"] == 0x1234 and regs["A0"] == 0x2006 and regs["PC"] == 0x200C


# --- asm ----------------------------------------------------------------------------------------------------------


def test_asm_listing_outputs_and_warnings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "inc").mkdir()
    (tmp_path / "inc" / "consts.inc").write_text("VALUE equ $4E71\n")
    src = tmp_path / "p.s"
    src.write_text(' include "consts.inc"\nstart: shr.l #1,d0\n muls d1,d0\n dc.w VALUE\n')
    binf, srecf = tmp_path / "p.bin", tmp_path / "p.s19"
    assert fwemu(["asm", str(src), "-I", str(tmp_path / "inc"), "-o", str(binf), "--srec", str(srecf)]) == 0
    cap = capsys.readouterr()
    assert re.search(r"^001000  E288 +10  start: shr.l #1,d0$", cap.out, re.M)  # LSR.L #1,D0: 8+2n = 10
    assert re.search(r"^001002  C1C1 +38-70 ", cap.out, re.M)
    assert re.search(r"^  start +\$001000  code +6$", cap.out, re.M)
    assert re.search(r"^  VALUE +\$00004E71  absolute +  = 20081$", cap.out, re.M)
    assert f"{src}:2:8: warning: 'shr'" in cap.err
    assert binf.read_bytes() == bytes.fromhex("E288 C1C1 4E71")
    records = srecf.read_text().splitlines()
    assert records[0].startswith("S0") and records[-1] == "S9031000EC"
    checksum = ~(0x09 + 0x10 + 0x00 + 0xE2 + 0x88 + 0xC1 + 0xC1 + 0x4E + 0x71) & 0xFF  # count, address, data
    assert records[1] == "S109" + "1000" + "E288C1C14E71" + f"{checksum:02X}"


def test_asm_error_is_reported_with_position(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "bad.s"
    src.write_text(" nop\n moveq #300,d0\n")
    assert fwemu(["asm", str(src)]) == 2
    err = capsys.readouterr().err
    first = err.splitlines()[0]
    assert first.startswith(f"fwemu: error: {src}:2:8: cannot encode 'moveq #300,d0'")
    assert "Traceback" not in err


def test_asm_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert fwemu(["asm", str(tmp_path / "nope.s")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fwemu: error: cannot read ") and "nope.s" in err


def run_fwemu(*argv: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """The real ``fwemu`` (``python -m firmware_model.cli.main``) in a subprocess, with this tree first on the path."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *argv], capture_output=True, text=True,
                          env=env, timeout=timeout)


def test_asm_latin1_byte_in_a_comment_names_file_line(tmp_path: Path) -> None:
    src = tmp_path / "latin.s"
    src.write_bytes(b" nop\n nop ; caf\xe9\n trap #0\n")
    res = run_fwemu("asm", str(src))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    first = res.stderr.splitlines()[0]
    assert first.startswith(f"fwemu: error: {src}:2:11: byte $E9 is not UTF-8"), res.stderr
    assert "position" not in res.stderr


def test_asm_recursive_macro_is_a_short_error(tmp_path: Path) -> None:
    src = tmp_path / "rec.s"
    src.write_text("m macro\n m\n endm\n nop\n m\n")
    res = run_fwemu("asm", str(src))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    first = res.stderr.splitlines()[0]
    assert f"{src}:2:2:" in first and "macro 'm'" in first and "64 levels" in first and f"{src}:5" in first
    assert len(res.stderr) < 400, res.stderr


def test_exec_running_off_the_program_is_a_bus_error_at_once(tmp_path: Path) -> None:
    # Issue 8.4: with all 16 MiB mapped, `start: nop` ran on through zeroed RAM (ORI.B #0,D0) at ~10,500
    # instructions/s, growing ~1 KB per instruction. exec now maps only the program and a stack.
    src = tmp_path / "nop.s"
    src.write_text("start: nop\n")
    res = run_fwemu("exec", str(src), timeout=60)
    assert res.returncode == 2 and "Traceback" not in res.stderr and res.stderr.count("\n") == 1, res.stderr
    assert "instruction fetch from unmapped address $001002 at PC=$001002" in res.stderr
    assert "ran off its end" in res.stderr and "mapped: $001000-$001001, $FEFF00-$FFFEFF" in res.stderr
    src.write_text(" rts\n")  # nothing to return to: the pop reads above the stack
    res = run_fwemu("exec", str(src), timeout=60)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert "long read of unmapped address $FFFF00 at PC=$001000 (rts)" in res.stderr and f"{src}:1" in res.stderr


def test_exec_map_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "io.s"
    src.write_text(" move.l #$12345678,$20000\n move.w $20002,d1\n trap #0\n")
    assert fwemu(["exec", str(src)]) == 2
    err = capsys.readouterr().err
    assert "write to unmapped address $020000" in err and "--map" in err
    assert fwemu(["exec", str(src), "--map", "$20000:4"]) == 0
    assert registers(capsys.readouterr().out)["D1"] == 0x5678
    assert fwemu(["exec", str(src), "--map", "$20000:4:ro"]) == 2
    assert "read-only" in capsys.readouterr().err
    assert fwemu(["exec", str(src), "--map", "0:0x1000000"]) == 0  # everything, as before
    capsys.readouterr()
    assert fwemu(["exec", str(src), "--map", "0:0x1000", "--map", "0x800:0x1000"]) == 2
    assert "overlaps" in capsys.readouterr().err
    src.write_text(" move.l #1,-(a7)\n move.l #2,-(a7)\n trap #0\n")
    assert fwemu(["exec", str(src), "--stack", "$8000", "--stack-size", "4"]) == 2  # the second push is below
    assert "write to unmapped address $007FF8" in capsys.readouterr().err


@pytest.mark.parametrize("bad", ["0:3", "1:2", "0", "0:2:rx", "$FFFFFE:4", "0:0"])
def test_exec_bad_map_is_a_usage_error(bad: str, capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = fwemu(["exec", str(DEMO), "--map", bad])
    except SystemExit as exc:
        code = exc.code
    assert code == 2 and "--map" in capsys.readouterr().err


def test_bad_origin_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    try:  # fwemu's main returns argparse's exit status; isa.cli.main alone lets SystemExit through
        code = fwemu(["asm", str(DEMO), "--origin", "$1001"])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert "must be even" in capsys.readouterr().err


# --- the demo against GNU as ----------------------------------------------------------------------------------------

_GNU_TOOLS = ("m68k-linux-gnu-as", "m68k-linux-gnu-ld", "m68k-linux-gnu-objcopy")


def _to_gnu(src: str) -> str:
    """Translate the demo's Motorola syntax to GNU as syntax (registers %, 0x hex, .text/.data, .word, .equ)."""
    out = []
    for line in src.splitlines():
        s = line.lstrip()
        if not s or s[0] in "*;":
            continue
        code = line.partition(";")[0].rstrip()
        label = ""
        m = re.match(r"([A-Za-z_.]\w*):?(\s+|$)(.*)", code)
        if m and not code[0].isspace():
            label, code = m.group(1), " " + m.group(3)
            eq = re.match(r"\s*equ\s+(.*)", code, re.I)
            if eq:
                out.append(f".equ {label}, {eq.group(1)}")
                continue
            label += ":"
        code = re.sub(r"(?<![\w.%])(d[0-7]|a[0-7]|sp|pc)\b", r"%\1", code, flags=re.I)
        code = re.sub(r"\$([0-9A-Fa-f]+)", r"0x\1", code)
        code = re.sub(r"^\s*section\s+code\s*$", " .text", code, flags=re.I)
        code = re.sub(r"^\s*section\s+data\s*$", " .data", code, flags=re.I)
        code = re.sub(r"^(\s*)dc\.w\b", r"\1.word", code, flags=re.I)
        out.append(label + code)
    return "\n".join(out) + "\n"


@pytest.mark.skipif(not all(shutil.which(t) for t in _GNU_TOOLS), reason="binutils-m68k-linux-gnu not installed")
def test_demo_bytes_equal_gnu_as(tmp_path: Path) -> None:
    prog = assemble(DEMO.read_text(), filename=str(DEMO), origin=0x1000)
    segs = {s.name: s for s in prog.segments}
    (tmp_path / "demo.s").write_text(_to_gnu(DEMO.read_text()))
    run = lambda *cmd: subprocess.run(cmd, cwd=tmp_path, check=True, capture_output=True)
    run("m68k-linux-gnu-as", "-m68000", "-o", "demo.o", "demo.s")
    run("m68k-linux-gnu-ld", "-e", "0", "-Ttext=0x1000", f"-Tdata=0x{segs['data'].origin:x}", "-o", "demo.elf",
        "demo.o")
    for section, name in ((".text", "code"), (".data", "data")):
        run("m68k-linux-gnu-objcopy", "-O", "binary", "-j", section, "demo.elf", f"{name}.bin")
        assert (tmp_path / f"{name}.bin").read_bytes() == segs[name].data, section
    base, image = to_binary(prog)
    assert base == 0x1000 and image == segs["code"].data + segs["data"].data


def test_asm_outputs_are_atomic(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                monkeypatch: pytest.MonkeyPatch) -> None:
    """-o / --srec write a temporary file beside the target and rename it: a write that fails before the rename
    (here fsync reports a full disk) leaves the previous file's bytes and no temporary file."""
    import errno

    src = tmp_path / "p.s"
    src.write_text("start: moveq #1,d0\n rts\n", encoding="ascii")
    binf, srecf = tmp_path / "p.bin", tmp_path / "p.s19"
    binf.write_bytes(b"old")
    srecf.write_text("old", encoding="ascii")

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    assert fwemu(["asm", str(src), "-q", "-o", str(binf), "--srec", str(srecf)]) == 2
    assert "cannot write" in capsys.readouterr().err
    assert binf.read_bytes() == b"old" and srecf.read_text(encoding="ascii") == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.bin", "p.s", "p.s19"]
    monkeypatch.undo()
    assert fwemu(["asm", str(src), "-q", "-o", str(binf), "--srec", str(srecf)]) == 0
    assert binf.read_bytes() != b"old" and srecf.read_text(encoding="ascii").startswith("S0")
    assert (binf.stat().st_mode & 0o777) == 0o666 & ~_umask()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
