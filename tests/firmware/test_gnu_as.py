"""The firmware programs' ROM images against GNU as: every instruction of every program, both barometer input kinds
(the 16-bit ADC word and the 32-bit pascal word, docs/firmware-spec.md §2) and both roundings, decoded from our
assembler's listing, written in GNU syntax (:func:`isa.formatter.format_gnu`, branch targets as labels so that GNU
as computes every displacement itself), data lines (vectors, the altitude table) as ``.byte``, assembled with
``m68k-linux-gnu-as -m68000`` and compared byte for byte with the build's ROM image.

An independent encoder (binutils) agreeing on every byte of the shipped programs, including the pascal kind's
``MOVE.L (BARO_PA).w``, ``CMPI.L``/``Bcc.S`` range check and its 1,025-node table.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from firmware_model.firmware.assemble import build_firmware
from firmware_model.spec.config import PROGRAMS, BuildConfig

AS = shutil.which("m68k-linux-gnu-as")
OBJCOPY = shutil.which("m68k-linux-gnu-objcopy")
pytestmark = pytest.mark.skipif(AS is None or OBJCOPY is None,
                                reason="m68k-linux-gnu-as/objcopy not installed (Debian binutils-m68k-linux-gnu)")


def _gnu_source(build) -> str:
    from isa.decoder import decode_bytes
    from isa.formatter import format_gnu

    lines = ["        .text"]
    for entry in build.program.listing:
        if entry.address is None or not entry.data:
            continue
        lines.append(f"        .org 0x{entry.address:x}")
        if entry.cycles is None:                       # data: dc.l / dc.w (vectors, the altitude table)
            lines.append("        .byte " + ",".join(str(b) for b in entry.data))
            continue
        dec = decode_bytes(entry.data, entry.address, entry.address)
        assert dec.length == len(entry.data), (entry.source, dec.length, len(entry.data))
        text = format_gnu(dec.instruction, lambda t: f"L{t:x}", entry.address)
        lines.append(f"L{entry.address:x}: {text}")
    return "\n".join(lines) + "\n"


def _gnu_bytes(src: str, work: Path) -> bytes:
    (work / "fw.s").write_text(src)
    subprocess.run([AS, "-m68000", "-o", str(work / "fw.o"), str(work / "fw.s")], check=True, capture_output=True,
                   text=True)
    subprocess.run([OBJCOPY, "-O", "binary", "-j", ".text", str(work / "fw.o"), str(work / "fw.bin")], check=True)
    return (work / "fw.bin").read_bytes()


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("kind", ["adc", "pascal"])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_rom_image_equals_gnu_as(program: str, kind: str, rounding: str, tmp_path: Path) -> None:
    extra = {"baro_kind": "pascal", "units_per_metre": 12.0} if kind == "pascal" else {"baro_min": 1,
                                                                                         "baro_max": 65534}
    build = build_firmware(BuildConfig(program=program, k=6, rounding=rounding, **extra))  # type: ignore[arg-type]  # **extra of mixed BuildConfig field types
    src = _gnu_source(build)
    gnu = _gnu_bytes(src, tmp_path)
    ours = build.rom_image
    assert len(gnu) == len(ours), (len(gnu), len(ours))
    if gnu != ours:
        i = next(j for j in range(len(ours)) if gnu[j] != ours[j])
        pytest.fail(f"{program}/{kind}/{rounding}: first differing byte at ${i:04X}: GNU {gnu[i:i + 8].hex()} ours "
                    f"{ours[i:i + 8].hex()}")
    if kind == "pascal":
        assert "move.l (-4092).w" in src          # the 32-bit pascal register BARO_PA at $FFF004 (abs.w $F004)


def test_a_wrong_byte_is_seen(tmp_path: Path) -> None:
    """The comparison has teeth: an image with one changed extension word differs from GNU's bytes."""
    build = build_firmware(BuildConfig(program="kalman_baro", k=6, baro_kind="pascal", units_per_metre=12.0))
    gnu = _gnu_bytes(_gnu_source(build), tmp_path)
    assert gnu == build.rom_image
    src = _gnu_source(build).replace("(-4092).w", "(-4096).w", 1)   # BARO_PA -> BARO_ADC: a 16-bit port's read
    assert _gnu_bytes(src, tmp_path) != build.rom_image
