"""The 68000's 24-bit address space: a region map, the program's memory accessors and host access.

Contract with :mod:`isa.cpu` (the only user; the public methods are re-exported there as ``CPU.map``,
``CPU.read``, ...):

* Storage: ``mem``, 16 MiB (+ :data:`_PAD` never-mapped bytes past ``$FFFFFF``) of big-endian bytes, and
  ``flags``, one flag byte per address: :data:`_MAPPED`, :data:`_WRITABLE` (set by :meth:`Memory.map`),
  :data:`_WRITTEN` (set by the first program write, read by :attr:`Memory.ram_written`) and :data:`_CODE`, which
  belongs to the CPU: it marks bytes that hold decoded instructions. Both are anonymous mmaps (zero-filled lazily
  by the OS), so an unused 16 MiB space costs nothing to create. :meth:`Memory.map` sets a region's flag bytes
  with one ``memset`` (no temporary copy); a memory made to map all 16 MiB at once (``prefault=True``, what
  ``CPU()`` does) asks the OS for the flag pages up front (``MAP_POPULATE``, where the platform has it), which is
  cheaper than faulting in 4,096 pages one by one (a ``CPU()``: ~13 -> ~5 ms here).
* Program access: ``rd[n](address) -> value`` and ``wr[n](address, value)`` for n = 1, 2, 4 mask the address to 24
  bits, raise :class:`isa.semantics._Fault` (AddressError for an odd word/long address, BusError for an unmapped
  byte or a write to ROM), and mark written bytes. A program write to a byte marked ``_CODE`` calls the hook
  ``code_written(address)`` (the CPU drops the closures and blocks that hold it). The closures reach memory only
  through these six functions. Generated block code (:mod:`isa.blocks`) also reads ``mem`` directly where
  :class:`MapFacts` or a span check guarantees the address is mapped, and writes ``mem`` directly where one look
  at ``flags16``/``flags32`` says mapped, writable and no code (setting the written bits of a first write as
  :meth:`Memory._slow_write` would); everything else goes through the accessors.
* Host access (:meth:`Memory.read`, :meth:`Memory.write`, :meth:`Memory.read_bytes`, :meth:`Memory.write_bytes`):
  checks every byte is mapped (ROM may be written), raises :class:`isa.errors.CPUFault` subclasses with
  ``pc = pc_of()``, does not count as written; a host write to ``_CODE`` bytes calls ``host_code_written(address,
  marks)`` where ``marks`` has a 1 for each code byte of the written range.
"""

from __future__ import annotations

import ctypes
import mmap
import struct
from collections.abc import Callable
from dataclasses import dataclass

from isa.errors import AddressError, BusError, CPUFault, IsaError
from isa.semantics import M32, MASK, _Fault

__all__ = ["Memory", "MapError", "MapFacts", "Region"]

_MAPPED, _WRITABLE, _WRITTEN, _CODE = 1, 2, 4, 8
_FAST_W = _MAPPED | _WRITABLE | _WRITTEN  # a write needs no bookkeeping
_TOP = 1 << 24
_PAD = 8  # bytes past $FFFFFF, never mapped (accesses running off the top are bus errors)
_WRITTEN_TABLE = bytes((1 if b & _WRITTEN else 0) for b in range(256))
_UNMAPPED_TABLE = bytes((0 if b & _MAPPED else 1) for b in range(256))  # flag byte -> 1 if unmapped
_CODE_TABLE = bytes((1 if b & _CODE else 0) for b in range(256))  # flag byte -> 1 if it holds compiled code
_HOST_PLAIN_TABLE = bytes((0 if b & _MAPPED and not b & _CODE else 1) for b in range(256))
_ZEROS = {1: b"\0", 2: b"\0\0", 4: b"\0\0\0\0"}
_LONG = struct.Struct(">L")
_WORD = struct.Struct(">H")
#: flag byte -> 0 if a program write there needs nothing but the written mark (mapped, writable, not code)
_FIRST_WRITE_TABLE = bytes((0 if b & (_MAPPED | _WRITABLE | _CODE) == _MAPPED | _WRITABLE else 1) for b in range(256))
_FAST_BYTES = {n: bytes([_FAST_W]) * n for n in (1, 2, 4)}
_CLEAR_WRITTEN_TABLE = bytes(b & ~_WRITTEN for b in range(256))
#: mmap flags of a prefaulted anonymous map (Linux's MAP_POPULATE: the pages faulted in at mmap time, in one call);
#: 0 where the platform has no MAP_POPULATE.
_POPULATED = (mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | mmap.MAP_POPULATE) if hasattr(mmap, "MAP_POPULATE") else 0


class MapError(IsaError, ValueError):
    """A bad memory-map request (overlapping, odd or out-of-range region) or a bad host argument."""


@dataclass(frozen=True)
class Region:
    """One mapped memory region: ``[start, start + size)``, a name, and whether programs may write it."""

    start: int
    size: int
    name: str
    writable: bool


class Memory:
    """The address space of one CPU (see the module docstring)."""

    def __init__(self, pc_of: Callable[[], int], code_written: Callable[[int], None],
                 host_code_written: Callable[[int, bytes], None], prefault: bool = False) -> None:
        """``prefault``: the caller is about to map (nearly) the whole space, so the flag pages are all written
        at once: have the OS populate them when it can."""
        self.mem = mmap.mmap(-1, _TOP + _PAD)
        if prefault and _POPULATED:
            self.flags = mmap.mmap(-1, _TOP + _PAD, flags=_POPULATED)
        else:
            self.flags = mmap.mmap(-1, _TOP + _PAD)
        #: The flag bytes as native 16/32-bit words: one subscript checks 2 (4) flag bytes of an aligned word
        #: (long), e.g. ``flags32[a >> 2] == 0x07070707``: all four mapped, writable, written, no code.
        self.flags16 = memoryview(self.flags).cast("H")
        self.flags32 = memoryview(self.flags).cast("I")
        self.regions: list[Region] = []
        self._pc_of = pc_of
        self._code_written = code_written
        self._host_code_written = host_code_written
        self._build_accessors()

    # ------------------------------------------------------------------------------------------------- the map
    def map(self, start: int, size: int, name: str, writable: bool = True) -> None:
        """Map ``size`` bytes at ``start`` (both even, inside the 24-bit space, not overlapping another region).

        ``writable=False`` makes a ROM: programs writing it get a :class:`~isa.errors.BusError` (the host may still
        write it through :meth:`write`/:meth:`write_bytes`)."""
        if not isinstance(start, int) or not isinstance(size, int):
            raise MapError(f"map {name!r}: start and size must be ints, got {start!r}, {size!r}")
        if start < 0 or size <= 0 or start + size > _TOP:
            raise MapError(f"map {name!r}: region ${start:X}+${size:X} is outside the 24-bit address space")
        if start & 1 or size & 1:
            raise MapError(f"map {name!r}: start ${start:X} and size ${size:X} must be even")
        for r in self.regions:
            if start < r.start + r.size and r.start < start + size:
                raise MapError(f"map {name!r}: ${start:06X}..${start + size - 1:06X} overlaps region {r.name!r} "
                               f"${r.start:06X}..${r.start + r.size - 1:06X}")
        self.regions.append(Region(start, size, name, writable))
        self.regions.sort(key=lambda r: r.start)
        value = _MAPPED | (_WRITABLE if writable else 0)
        view = ctypes.c_char.from_buffer(self.flags)  # the mmap's address; released at once (no export kept)
        base = ctypes.addressof(view)
        del view
        ctypes.memset(base + start, value, size)  # start + size <= _TOP checked above

    def region_at(self, address: int) -> Region | None:
        """The region containing ``address`` (24-bit), or None."""
        address &= 0xFFFFFF
        for r in self.regions:
            if r.start <= address < r.start + r.size:
                return r
        return None

    # ------------------------------------------------------------------------------------------ written bytes
    @property
    def ram_written(self) -> int:
        """Number of distinct bytes written by executed instructions since the last :meth:`clear_written`."""
        fl = self.flags
        return sum(fl[r.start : r.start + r.size].translate(_WRITTEN_TABLE).count(1) for r in self.regions)

    def written_ranges(self) -> list[tuple[int, int]]:
        """The bytes counted by :attr:`ram_written`, as sorted ``(start, end_exclusive)`` address ranges."""
        out: list[tuple[int, int]] = []
        for r in self.regions:
            marks = self.flags[r.start : r.start + r.size].translate(_WRITTEN_TABLE)
            i = marks.find(1)
            while i != -1:
                j = marks.find(0, i)
                j = len(marks) if j == -1 else j
                if out and out[-1][1] == r.start + i:
                    out[-1] = (out[-1][0], r.start + j)
                else:
                    out.append((r.start + i, r.start + j))
                i = marks.find(1, j)
        return out

    def clear_written(self) -> None:
        """Forget which bytes programs wrote."""
        fl = self.flags
        for r in self.regions:
            fl[r.start : r.start + r.size] = fl[r.start : r.start + r.size].translate(_CLEAR_WRITTEN_TABLE)

    # ------------------------------------------------------------------------------------------ program access
    def _build_accessors(self) -> None:  # noqa: C901 - builds each size's fast accessor for each region kind inline (hot path)
        m = self.mem
        fl = self.flags
        f16, f32 = self.flags16, self.flags32
        slow_write = self._slow_write
        unpack_l, pack_l = _LONG.unpack_from, _LONG.pack_into
        pack_w = _WORD.pack_into

        def fault(cls: type[CPUFault], what: str, a: int) -> _Fault:
            return _Fault(cls, f"{what} ${a & 0xFFFFFF:06X}")

        def rb(a: int) -> int:
            a &= 0xFFFFFF
            if fl[a] & 1:
                return m[a]
            raise fault(BusError, "byte read of unmapped address", a)

        def rw(a: int) -> int:
            if a & 1:
                raise fault(AddressError, "word read at odd address", a)
            a &= 0xFFFFFF
            if fl[a] & 1:
                return (m[a] << 8) | m[a + 1]
            raise fault(BusError, "word read of unmapped address", a)

        def rl(a: int) -> int:
            if a & 1:
                raise fault(AddressError, "long read at odd address", a)
            a &= 0xFFFFFF
            if fl[a] & fl[a + 2] & 1:
                return unpack_l(m, a)[0]
            # The first unmapped byte: the high word's if it is unmapped, else the low word's (regions are even).
            raise fault(BusError, "long read of unmapped address", a + (2 if fl[a] & 1 else 0))

        # Flag bytes 7 = mapped | writable | written (no code): nothing to do; 3 = mapped | writable, first write
        # (mark written). Anything else: slow_write (faults, code invalidation, mixed bytes).
        def wb(a: int, v: int) -> None:
            a &= 0xFFFFFF
            f = fl[a]
            if f != 7:
                if f == 3:
                    fl[a] = 7
                else:
                    slow_write(a, 1)
            m[a] = v & 0xFF

        def ww(a: int, v: int) -> None:
            if a & 1:
                raise fault(AddressError, "word write at odd address", a)
            a &= 0xFFFFFF
            f = f16[a >> 1]
            if f != 0x0707:
                if f == 0x0303:
                    f16[a >> 1] = 0x0707
                else:
                    slow_write(a, 2)
            pack_w(m, a, v & 0xFFFF)

        def wl(a: int, v: int) -> None:
            if a & 1:
                raise fault(AddressError, "long write at odd address", a)
            a &= 0xFFFFFF
            if a & 2:
                if fl[a] != 7 or fl[a + 1] != 7 or fl[a + 2] != 7 or fl[a + 3] != 7:
                    slow_write(a, 4)
            else:
                f = f32[a >> 2]
                if f != 0x07070707:
                    if f == 0x03030303:
                        f32[a >> 2] = 0x07070707
                    else:
                        slow_write(a, 4)
            pack_l(m, a, v & M32)

        self.rd = {1: rb, 2: rw, 4: rl}
        self.wr = {1: wb, 2: ww, 4: wl}

    def _slow_write(self, a: int, n: int) -> None:
        """A program write that needs bookkeeping: bus errors, first-write marking, code invalidation."""
        fl = self.flags
        if fl[a : a + n].translate(_FIRST_WRITE_TABLE) == _ZEROS[n]:  # writable RAM, no code: mark written
            fl[a : a + n] = _FAST_BYTES[n]
            return
        for b in range(a, a + n):
            f = fl[b]
            if not f & _MAPPED:
                raise _Fault(BusError, f"write to unmapped address ${b:06X}")
            if not f & _WRITABLE:
                r = self.region_at(b)
                raise _Fault(BusError, f"write to read-only region {r.name if r else '?'!r} at ${b:06X}")
        for b in range(a, a + n):
            if fl[b] & _CODE:
                self._code_written(b)
            fl[b] |= _WRITTEN

    def fetch_word(self, a: int) -> int:
        """The instruction word at ``a`` (even) for the decoder; an unmapped address raises _Fault(BusError)."""
        if a < _TOP and self.flags[a] & _MAPPED:
            return (self.mem[a] << 8) | self.mem[a + 1]
        raise _Fault(BusError, f"instruction fetch from unmapped address ${a:06X}")

    # --------------------------------------------------------------------------------------------- host access
    def _host_fault(self, cls: type[CPUFault], message: str) -> CPUFault:
        return cls(message, pc=self._pc_of(), instruction="host access")

    def _check_host(self, address: int, n: int, write: bool) -> int:
        if not isinstance(address, int) or not isinstance(n, int) or n < 0:
            raise MapError(f"bad host access address={address!r} length={n!r}")
        a = address & 0xFFFFFF
        if a + n > _TOP:
            raise self._host_fault(BusError, f"host access ${a:06X}+{n} runs past $FFFFFF")
        i = self.flags[a : a + n].translate(_UNMAPPED_TABLE).find(1)
        if i != -1:
            raise self._host_fault(BusError, f"host {'write' if write else 'read'} of unmapped address ${a + i:06X}")
        return a

    def read(self, address: int, size: int) -> int:
        """Read an unsigned big-endian value of ``size`` bytes (1, 2, 4) at ``address`` (host access: no counters;
        unmapped -> BusError, odd word/long -> AddressError)."""
        if size not in (1, 2, 4):
            raise MapError(f"read size must be 1, 2 or 4, not {size!r}")
        if size > 1 and address & 1:
            raise self._host_fault(AddressError, f"host read of {size} bytes at odd address ${address:06X}")
        a = self._check_host(address, size, False)
        return int.from_bytes(self.mem[a : a + size], "big")

    def write(self, address: int, value: int, size: int) -> None:
        """Write ``value`` (masked to ``size`` bytes, big-endian) at ``address``. Host access: ROM regions may be
        written, unmapped ones raise BusError; not counted in :attr:`ram_written`; invalidates compiled code."""
        if size not in (1, 2, 4):
            raise MapError(f"write size must be 1, 2 or 4, not {size!r}")
        if not isinstance(value, int):
            raise MapError(f"host write value {value!r} is not an int")
        if size > 1 and address & 1:
            raise self._host_fault(AddressError, f"host write of {size} bytes at odd address ${address:06X}")
        if isinstance(address, int) and 0 <= address and address + size <= _TOP:
            # Fast path: mapped and holding no compiled code (one translate of the 1..4 flag bytes).
            if self.flags[address : address + size].translate(_HOST_PLAIN_TABLE) == _ZEROS[size]:
                self.mem[address : address + size] = (value & MASK[size]).to_bytes(size, "big")
                return
        self.write_bytes(address, (value & MASK[size]).to_bytes(size, "big"))

    def read_bytes(self, address: int, n: int) -> bytes:
        """``n`` bytes from ``address`` (host access; every byte must be mapped)."""
        a = self._check_host(address, n, False)
        return self.mem[a : a + n]

    def write_bytes(self, address: int, data: bytes) -> None:
        """Copy ``data`` to ``address`` (host access; every byte must be mapped; ROM allowed)."""
        data = bytes(data)
        a = self._check_host(address, len(data), True)
        self.mem[a : a + len(data)] = data
        marks = self.flags[a : a + len(data)].translate(_CODE_TABLE)
        if marks.find(1) != -1:
            self._host_code_written(a, marks)


class MapFacts:
    """What compiled code may assume about an address space forever: its regions (they are never removed and
    never change kind), so a constant address that is mapped (readable) or mapped and writable stays so.

    Used by the block compiler (:mod:`isa.blocks`) to access constant addresses without a per-access check and
    to know they cannot fault, and to pick :attr:`span`, the largest run of back-to-back mapped regions, for the
    one-comparison guard of register-indirect reads (any other address takes the exact accessor)."""

    def __init__(self, regions: list[Region] | tuple[Region, ...]) -> None:
        self.regions = tuple(sorted(regions, key=lambda r: r.start))
        spans: list[list[int]] = []
        for r in self.regions:
            if spans and spans[-1][1] == r.start:
                spans[-1][1] = r.start + r.size
            else:
                spans.append([r.start, r.start + r.size])
        best = max(spans, key=lambda s: s[1] - s[0]) if spans else [0, 0]
        self.span = (best[0], best[1])

    def _covered(self, a: int, n: int, write: bool) -> bool:
        end = a + n
        for r in self.regions:
            if r.start <= a < r.start + r.size:
                if write and not r.writable:
                    return False
                if end <= r.start + r.size:
                    return True
                a = r.start + r.size  # continues into the next region (back to back) or is unmapped
        return False

    def readable(self, address: int, n: int) -> bool:
        """True when an ``n``-byte program read at the constant 32-bit ``address`` can never fault."""
        if n > 1 and address & 1:
            return False
        a = address & 0xFFFFFF
        return a + n <= _TOP and self._covered(a, n, False)

    def writable(self, address: int, n: int) -> bool:
        """True when an ``n``-byte program write at the constant ``address`` can never fault."""
        if n > 1 and address & 1:
            return False
        a = address & 0xFFFFFF
        return a + n <= _TOP and self._covered(a, n, True)
