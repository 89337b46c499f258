"""``fwemu asm`` and ``fwemu exec``: assemble a 68000 source file (listing with cycles, symbols, binary and
S-record output) or assemble and run it on the interpreter to a ``TRAP`` or a limit.

Both commands load code at ``--origin`` (default ``$1000``). ``exec`` maps only the program's sections (code,
data, bss, as RAM) and a stack of ``--stack-size`` bytes (default 64 KiB) below ``--stack`` (default ``$FFFF00``),
plus every ``--map START:SIZE[:ro]`` given (``--map 0:0x1000000`` maps all 16 MiB as before); everything else is a
bus error, so a program that runs off its end, or returns with nothing on the stack, stops at once with a bus
error naming the PC, and memory stays bounded by what is mapped. It sets A7 to ``--stack`` and SR to ``$2700``,
runs from the origin and prints D0-D7, A0-A7, PC, SR and the instruction and cycle totals. It exits 0 when the
program stopped at a ``TRAP`` and 1 when it reached ``--max-instructions`` / ``--max-cycles``; CPU faults and
assembly errors exit 2 with one ``fwemu: error:`` line (plus the source line and a caret for assembly errors).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

from isa.errors import BusError, IsaError
from isa.program import Program

#: Default load address of ``fwemu asm`` / ``fwemu exec``.
DEFAULT_ORIGIN = 0x1000
#: Default initial A7 of ``fwemu exec``.
DEFAULT_STACK = 0xFFFF00
#: Default size of the stack region ``fwemu exec`` maps below the initial A7.
DEFAULT_STACK_SIZE = 0x10000


def parse_int(text: str) -> int:
    """An integer from the command line: decimal, ``$hex``, ``0x`` hex, ``%bin``/``0b`` binary."""
    t = text.strip().replace("_", "")
    try:
        if t.startswith("$"):
            return int(t[1:], 16)
        if t.startswith("%"):
            return int(t[1:], 2)
        return int(t, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r} (use decimal, $hex or 0xhex)") from None


def _address(text: str) -> int:
    value = parse_int(text)
    if not 0 <= value < (1 << 24) or value & 1:
        raise argparse.ArgumentTypeError(f"address {text!r} must be even and inside the 24-bit address space")
    return value


def _count(text: str) -> int:
    value = parse_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"limit {text!r} must be a positive integer")
    return value


def _region(text: str) -> tuple[int, int, bool]:
    """``START:SIZE[:ro]`` of ``--map`` (both even, inside the 24-bit space) -> (start, size, writable)."""
    parts = text.split(":")
    if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2].lower() not in ("ro", "rw")):
        raise argparse.ArgumentTypeError(f"bad region {text!r} (use START:SIZE or START:SIZE:ro)")
    start, size = parse_int(parts[0]), parse_int(parts[1])
    if size <= 0 or start < 0 or start + size > 1 << 24 or start & 1 or size & 1:
        raise argparse.ArgumentTypeError(f"region {text!r} must be even, non-empty and inside $000000-$FFFFFF")
    return start, size, not (len(parts) == 3 and parts[2].lower() == "ro")


def _define(text: str) -> tuple[str, int]:
    m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)(?:=(.*))?", text)
    if m is None:
        raise argparse.ArgumentTypeError(f"bad define {text!r} (use NAME or NAME=VALUE)")
    return m.group(1), parse_int(m.group(2)) if m.group(2) is not None else 1


def _add_source_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="FILE.s", help="68000 assembly source (Motorola syntax)")
    p.add_argument("--origin", type=_address, default=DEFAULT_ORIGIN, metavar="N",
                   help="address of the first code byte (default $1000)")
    p.add_argument("-I", dest="include", action="append", default=[], metavar="DIR",
                   help="directory searched for INCLUDE files after the including file's own (repeatable)")
    p.add_argument("-D", dest="defines", action="append", type=_define, default=[], metavar="NAME[=VALUE]",
                   help="pre-define an EQU symbol (repeatable; VALUE defaults to 1)")


def register(subparsers: Any) -> None:
    """Add the ``asm`` and ``exec`` subcommands to the ``fwemu`` parser's ``subparsers``."""
    p = subparsers.add_parser("asm", help="assemble a 68000 source: listing with cycles, symbols, .bin/.s19 output",
                              description="Assemble FILE.s and print the listing (address, bytes, cycles, source) "
                              "and the symbol table. Warnings go to stderr.")
    _add_source_args(p)
    p.add_argument("-o", "--output", metavar="FILE.bin",
                   help="write a flat binary image (lowest to highest loaded address, gaps zero-filled, no bss)")
    p.add_argument("--srec", metavar="FILE.s19", help="write Motorola S-records (S0/S1/S9, or S2/S8 above $FFFF)")
    p.add_argument("-q", "--quiet", action="store_true", help="do not print the listing")
    p.set_defaults(func=cmd_asm)

    p = subparsers.add_parser("exec", help="assemble a 68000 source and run it to a TRAP or a limit",
                              description="Assemble FILE.s, load it into a CPU that maps only its sections and a "
                              "stack (--map adds memory; everything else is a bus error), run from the origin until "
                              "TRAP #n or a limit, and print the registers and totals. Exit status 0 at a TRAP, 1 at "
                              "a limit.")
    _add_source_args(p)
    p.add_argument("--max-instructions", type=_count, default=10_000_000, metavar="N",
                   help="stop after N instructions (default 10000000)")
    p.add_argument("--max-cycles", type=_count, default=None, metavar="N", help="stop after N clock cycles")
    p.add_argument("--stack", type=_address, default=DEFAULT_STACK, metavar="N",
                   help="initial A7 (default $FFFF00)")
    p.add_argument("--stack-size", type=_count, default=DEFAULT_STACK_SIZE, metavar="N",
                   help="bytes of RAM mapped below the initial A7 (default 65536)")
    p.add_argument("--map", dest="regions", action="append", type=_region, default=[], metavar="START:SIZE[:ro]",
                   help="also map SIZE bytes at START (RAM, or ROM with :ro; repeatable). Only the program's "
                   "sections and the stack are mapped otherwise; --map 0:0x1000000 maps everything")
    p.set_defaults(func=cmd_exec)


def _assemble(args: argparse.Namespace) -> Program:
    from isa.assembler import assemble, decode_source

    path = Path(args.source)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise IsaError(f"cannot read {path}: {exc.strerror or exc}") from None
    text = decode_source(data, str(path))
    program = assemble(text, filename=str(path), origin=args.origin, include_paths=args.include,
                       defines=dict(args.defines))
    for warning in program.warnings:
        print(warning, file=sys.stderr)
    return program


def _write(path: str, data: bytes | str) -> None:
    """Write ``data`` to ``path`` atomically: a temporary file beside it, then ``os.replace``, so that a full disk
    or an interrupt leaves the previous file intact and no temporary file (``isa`` does not import
    ``firmware_model.runtime.output``, which does the same for the firmware CLI)."""
    import os
    import tempfile

    raw = data.encode("ascii") if isinstance(data, str) else data
    target = Path(path)
    tmp = None
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        tmp = Path(name)
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            os.fsync(f.fileno())
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        os.replace(tmp, target)
        tmp = None
    except OSError as exc:
        raise IsaError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if tmp is not None:
            try:
                tmp.unlink()
            except OSError:
                pass


def cmd_asm(args: argparse.Namespace) -> int:
    """``fwemu asm``: print the listing and symbols; write ``-o`` binary and ``--srec`` S-records if asked."""
    from isa.listing import format_listing, to_binary, to_srec

    program = _assemble(args)
    if not args.quiet:
        sys.stdout.write(format_listing(program))
    if args.output:
        base, image = to_binary(program)
        _write(args.output, image)
        print(f"wrote {args.output}: {len(image)} bytes at ${base:06X}", file=sys.stderr)
    if args.srec:
        _write(args.srec, to_srec(program, header=Path(args.source).name))
        print(f"wrote {args.srec}", file=sys.stderr)
    return 0


def format_registers(cpu: Any) -> str:
    """D0-D7 and A0-A7 as ``$XXXXXXXX`` with the signed decimal value of the data registers, then PC and SR
    with the X N Z V C flags."""
    lines = []
    for i in range(8):
        d = cpu.d[i]
        signed = d - (1 << 32) if d & 0x80000000 else d
        lines.append(f"D{i} = ${d:08X} {signed:>12}    A{i} = ${cpu.a[i]:08X}")
    sr = cpu.sr
    flags = "".join(ch if sr & bit else "-" for ch, bit in zip("XNZVC", (16, 8, 4, 2, 1)))
    lines.append(f"PC = ${cpu.pc:06X}    SR = ${sr:04X} (XNZVC {flags})")
    return "\n".join(lines)


def _merge(ranges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Union of half-open ``(start, end)`` ranges, sorted."""
    out: list[tuple[int, int]] = []
    for lo, hi in sorted(r for r in ranges if r[1] > r[0]):
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def map_for_exec(cpu: Any, program: Program, stack: int, stack_size: int,
                 regions: list[tuple[int, int, bool]]) -> str:
    """Map ``regions`` (``--map``) and, as RAM, the parts of the program's sections and of the stack
    ``[stack - stack_size, stack)`` they do not cover (rounded out to even addresses). Returns the map as text
    for error messages. Overlapping ``--map`` regions are an error."""
    from isa.cpu import MapError

    for start, size, writable in regions:
        try:
            cpu.map(start, size, f"--map ${start:06X}", writable=writable)
        except MapError as exc:
            raise IsaError(f"--map: {exc}") from None
    wanted = [(s.origin & ~1, (s.origin + len(s.data) + 1) & ~1) for s in program.segments]
    wanted.append((max(stack - stack_size, 0), stack))
    taken = _merge([(start, start + size) for start, size, _ in regions])
    for lo, hi in _merge(wanted):
        for t_lo, t_hi in taken:  # leave out what --map covers
            if t_hi <= lo or hi <= t_lo:
                continue
            if lo < t_lo:
                cpu.map(lo, t_lo - lo, "exec", writable=True)
            lo = max(lo, t_hi)
            if lo >= hi:
                break
        if lo < hi:
            cpu.map(lo, hi - lo, "exec", writable=True)
    return ", ".join(f"${r.start:06X}-${r.start + r.size - 1:06X}{'' if r.writable else ' (ro)'}"
                     for r in cpu.regions)


def cmd_exec(args: argparse.Namespace) -> int:
    """``fwemu exec``: assemble, run to a TRAP or a limit, print registers and totals; 0 at a TRAP, 1 at a limit."""
    from isa.cpu import CPU

    program = _assemble(args)
    cpu = CPU(mapped=False)
    mapped = map_for_exec(cpu, program, args.stack, args.stack_size, args.regions)
    cpu.load(program)
    cpu.a[7] = args.stack
    try:
        result = cpu.run(max_instructions=args.max_instructions, max_cycles=args.max_cycles, stop_at_limit=True)
    except BusError as exc:
        hint = "; the program ran off its end or jumped outside it" if "instruction fetch" in str(exc) else ""
        raise IsaError(f"{exc}{hint}; mapped: {mapped} (--map START:SIZE[:ro] maps more)") from None
    if result.reason == "trap":
        print(f"stopped: TRAP #{result.trap_number} (PC after the TRAP ${result.pc:06X})")
    elif result.reason == "max_instructions":
        print(f"stopped: instruction limit {args.max_instructions} reached at PC ${result.pc:06X}")
    elif result.reason == "max_cycles":
        print(f"stopped: cycle limit {args.max_cycles} reached at PC ${result.pc:06X}")
    else:  # pragma: no cover - run() has no other reason without until_pc
        print(f"stopped: {result.reason} at PC ${result.pc:06X}")
    print(format_registers(cpu))
    print(f"instructions: {result.instructions}    cycles: {result.cycles}")
    return 0 if result.reason == "trap" else 1


def main(argv: list[str] | None = None) -> int:
    """Run ``asm``/``exec`` alone (``python -m isa.cli asm FILE.s``), without the rest of ``fwemu``."""
    parser = argparse.ArgumentParser(prog="fwemu")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    register(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except IsaError as exc:
        print(f"fwemu: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
