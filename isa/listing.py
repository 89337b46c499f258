"""Text and file outputs of an assembled :class:`~isa.program.Program`: the listing, Motorola S-records and a flat
binary image."""

from __future__ import annotations

from isa.program import Program

__all__ = ["format_listing", "format_symbols", "to_srec", "to_binary"]

#: Bytes shown per listing row (10 = the longest 68000 instruction of the subset).
_ROW_BYTES = 10
#: Rows shown for one source line before the rest is elided (long DC/DS).
_MAX_ROWS = 4


def _hex_words(data: bytes) -> str:
    return " ".join(data[i : i + 2].hex().upper() for i in range(0, len(data), 2))


def format_listing(program: Program, symbols: bool = True) -> str:
    """The listing: one row per source line (after macro/INCLUDE expansion) with the 24-bit address in hex, up to
    10 bytes in hex (longer data continues on following rows), the cycle count in 68000 clocks (``12``, or
    ``38-70`` when data-dependent) and the source text; then the symbol table (``symbols=True``)."""
    width = len(_hex_words(bytes(_ROW_BYTES)))
    out: list[str] = []
    for ln in program.listing:
        addr = f"{ln.address:06X}" if ln.address is not None else " " * 6
        cyc = ""
        if ln.cycles is not None:
            lo, hi = ln.cycles
            cyc = f"{lo}" if lo == hi else f"{lo}-{hi}"
        rows = [ln.data[i : i + _ROW_BYTES] for i in range(0, len(ln.data), _ROW_BYTES)] or [b""]
        text = ln.source.text.rstrip("\n").expandtabs(8)
        out.append(f"{addr}  {_hex_words(rows[0]):<{width}}  {cyc:>6}  {text}".rstrip())
        for k, row in enumerate(rows[1:], start=1):
            if k >= _MAX_ROWS:
                out.append(f"{'':6}  ... ({len(ln.data) - k * _ROW_BYTES} more bytes)")
                break
            out.append(f"{(ln.address or 0) + k * _ROW_BYTES:06X}  {_hex_words(row)}")
    if symbols:
        out.append("")
        out.append(format_symbols(program))
    return "\n".join(out) + "\n"


def format_symbols(program: Program) -> str:
    """The symbol table: name, value in hex, section, size in bytes (labels) or ``= decimal`` (constants), sorted by
    section (code, data, bss, absolute) then value."""
    order = {"code": 0, "data": 1, "bss": 2, "absolute": 3}
    lines = ["Symbols:", f"  {'name':<24} {'value':>9}  {'section':<8} {'size':>6}"]
    syms = sorted(program.symbols.values(), key=lambda s: (order.get(s.section, 4), s.address, s.name.lower()))
    for s in syms:
        if s.section == "absolute":
            value = f"${s.address & 0xFFFFFFFF:08X}"
            lines.append(f"  {s.name:<24} {value:>9}  {s.section:<8} {'':>6}  = {s.address}")
        else:
            lines.append(f"  {s.name:<24} {'$' + format(s.address, '06X'):>9}  {s.section:<8} {s.size:>6}")
    return "\n".join(lines)


def _record(kind: int, address: int, addr_bytes: int, data: bytes) -> str:
    body = address.to_bytes(addr_bytes, "big") + data
    count = len(body) + 1
    checksum = (~(count + sum(body))) & 0xFF
    return f"S{kind}{count:02X}{body.hex().upper()}{checksum:02X}"


def to_srec(program: Program, header: str = "fwemu", entry: int | None = None, per_record: int = 32) -> str:
    """Motorola S-records of every non-bss segment: an S0 header (``header`` text), S1 data records (16-bit
    addresses) when every byte lies below $10000, else S2 (24-bit), and the matching S9/S8 terminator carrying
    ``entry`` (default: the program origin). Each line ends with the checksum (ones' complement of the low byte of
    the sum of count, address and data bytes)."""
    segs = [s for s in program.segments if not s.bss and s.data]
    top = max((s.origin + len(s.data) for s in segs), default=0)
    wide = top > 0x10000
    kind, term, abytes = (2, 8, 3) if wide else (1, 9, 2)
    lines = [_record(0, 0, 2, header.encode("latin-1", "replace")[:64])]
    for s in sorted(segs, key=lambda s: s.origin):
        for i in range(0, len(s.data), per_record):
            lines.append(_record(kind, s.origin + i, abytes, s.data[i : i + per_record]))
    start = program.origin if entry is None else entry
    lines.append(_record(term, start, abytes, b""))
    return "\n".join(lines) + "\n"


def to_binary(program: Program) -> tuple[int, bytes]:
    """A flat image of every non-bss segment: ``(base address, bytes)`` from the lowest to the highest loaded
    address, gaps filled with zero bytes (bss is not included)."""
    segs = [s for s in program.segments if not s.bss and s.data]
    if not segs:
        return program.origin, b""
    base = min(s.origin for s in segs)
    end = max(s.origin + len(s.data) for s in segs)
    image = bytearray(end - base)
    for s in segs:
        image[s.origin - base : s.origin - base + len(s.data)] = s.data
    return base, bytes(image)
