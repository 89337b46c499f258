"""All 65,536 opcode words against m68000-python (issue 8, must-show "decoder test").

1. Decode map, exhaustive: for every first word, m68000-python's own opcode table (``_dispatch.NAMES``, built from
   the PRM's opcode map independently of ours) must name the same instruction family as our decoder, or, for a
   word we reject, an instruction outside our subset or an illegal / line-A / line-F word
   (:data:`OUTSIDE_SUBSET`, why each is outside: docs/isa-oracles.md, "Opcode sweep").
2. Execution, sampled: words we accept are run once each, with four random extension words (so random
   displacements, brief extension words with random bits 10..8, immediates, register masks, branch offsets) from a
   random state, on ours and on m68000-python, and compared as in test_isa_vs_m68000py (registers, CCR, RAM,
   cycles, fault kind). The ``ci`` profile runs a fixed sample of 4,096 of the 42,755 accepted words; ``thorough``
   runs every accepted word twice (about 90 s).
"""

from __future__ import annotations

import random

import pytest

pytest.importorskip("m68000_python", reason="m68000-python (the reference) is not installed")

from tests.support import oracles
from isa.decoder import OPCODE_MAP
from tests.support.profiles import PROFILE

#: m68000-python handler names of 68000 words that are not in our subset, and why (docs/isa-oracles.md).
OUTSIDE_SUBSET = {
    "illegal": "not a 68000 instruction (takes the illegal-instruction exception)",
    "line_a": "line A emulator trap", "line_f": "line F emulator trap",
    "abcd": "BCD", "sbcd": "BCD", "nbcd": "BCD",
    "btst": "bit operations", "bchg": "bit operations", "bclr": "bit operations", "bset": "bit operations",
    "movep": "peripheral moves", "chk": "bounds check exception", "tas": "read-modify-write cycle",
    "link": "frame pointers", "unlk": "frame pointers",
    "ori_to_ccr": "CCR/SR access", "andi_to_ccr": "CCR/SR access", "eori_to_ccr": "CCR/SR access",
    "move_to_ccr": "CCR/SR access", "move_from_sr": "CCR/SR access",
    "ori_to_sr": "supervisor", "andi_to_sr": "supervisor", "eori_to_sr": "supervisor", "move_to_sr": "supervisor",
    "move_usp": "supervisor", "reset": "supervisor", "stop": "supervisor", "rte": "supervisor",
    "rtr": "exception return", "trapv": "exception",
}  # fmt: skip

_FAMILY = {"asd": ("asr", "asl"), "lsd": ("lsr", "lsl"), "roxd": ("roxr", "roxl"), "rod": ("ror", "rol")}


def _their_handler(word: int) -> str:
    """m68000-python's handler name in our naming (shifts split by the direction bit 8)."""
    from m68000_python._dispatch import NAMES

    name = NAMES[word]
    base = name.removesuffix("_memory")
    if base in _FAMILY:
        return _FAMILY[base][word >> 8 & 1]
    return name


def test_every_opcode_word_decodes_as_m68000_python_decodes_it() -> None:
    pytest.importorskip("m68000_python._dispatch", reason="m68000-python without its opcode table")
    accepted = rejected = 0
    wrong: list[str] = []
    for word in range(0x10000):
        row = OPCODE_MAP[word]
        theirs = _their_handler(word)
        if row is None:
            rejected += 1
            if theirs not in OUTSIDE_SUBSET:
                wrong.append(f"${word:04X}: ours rejects, m68000-python decodes {theirs}")
        else:
            accepted += 1
            if row.handler != theirs:
                wrong.append(f"${word:04X}: ours {row.handler} ({row}), m68000-python {theirs}")
    assert not wrong, f"{len(wrong)} words differ, e.g. " + "; ".join(wrong[:10])
    assert accepted == 42755 and rejected == 65536 - 42755  # the subset's size (a change must be deliberate)


_TRANSFERS = ("jmp", "jsr", "rts", "bra", "bsr", "bcc", "dbcc")


def _machine(word: int, rng: random.Random) -> oracles.Machine:
    ext = [rng.getrandbits(16) for _ in range(4)]
    code = b"".join(w.to_bytes(2, "big") for w in [word, *ext])
    image = bytes(oracles.base_image(rng.getrandbits(32), [(oracles.CODE, code),
                                                           (oracles.CODE + len(code), b"\x4e\x71" * 4)]))
    d = [rng.choice(oracles.EDGE32) if rng.random() < 0.5 else rng.getrandbits(32) for _ in range(8)]
    a = [rng.randrange(oracles.DATA_LO, oracles.DATA_HI) & ~(rng.random() < 0.8) for _ in range(7)]
    a.append(rng.randrange(oracles.DATA_LO + 0x400, oracles.DATA_HI - 0x400) & ~1)
    return oracles.Machine(d, a, rng.getrandbits(5), oracles.CODE, image)


def _words() -> list[int]:
    accepted = [w for w in range(0x10000) if OPCODE_MAP[w] is not None]
    if PROFILE == "thorough":
        return accepted * 2
    return sorted(random.Random(8).sample(accepted, 4096))


def test_accepted_words_execute_as_on_m68000_python() -> None:
    ref = oracles.M68000PyRef()
    rng = random.Random(68000 if PROFILE != "thorough" else None)
    faults: dict[str | None, int] = {}
    prefetch = 0
    wrong: list[str] = []
    for word in _words():
        machine = _machine(word, rng)
        ours, theirs = oracles.ours_run(machine), ref.run(machine)
        if (OPCODE_MAP[word].handler in _TRANSFERS and ours.fault is None and theirs.fault == "bus"
                and theirs.fault_address == ours.pc):
            # The chip prefetches at a jump target inside the jump; ours fetches it as the next instruction (PC =
            # the target) and faults there. Prefetch is not modelled (docs/isa-oracles.md).
            prefetch += 1
            continue
        diffs = oracles.compare(ours, theirs, cycles=True)
        if diffs:
            code = machine.memory[oracles.CODE : oracles.CODE + 10]
            wrong.append(f"{oracles.describe(machine, ours.detail or '?', code)}\n  " + "\n  ".join(diffs))
        faults[theirs.fault] = faults.get(theirs.fault, 0) + 1
    assert not wrong, f"{len(wrong)} words differ:\n" + "\n".join(wrong[:5])
    # Not vacuous: most runs complete, and every fault kind the sample can reach is seen.
    assert faults.get(None, 0) > len(_words()) // 2 and {"address", "bus"} <= set(faults), faults
    assert prefetch < len(_words()) // 100, prefetch
