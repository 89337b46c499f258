"""Per-sample outputs of a firmware run, shared by the CPU harness, the integer model and the golden vectors.

State words follow docs/firmware-spec.md §7: ``.l`` words are signed int32 values, ``.w`` words unsigned 16-bit,
all stored in int64 numpy arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: State words per program, in output order: (name, size in bytes).
STATE_WORDS: dict[str, tuple[tuple[str, int], ...]] = {
    "recursive": (("EST", 4), ("EXT", 4), ("VEL", 4), ("ACC0", 4), ("EVENTS", 2), ("ZL", 4), ("SUMA", 4),
                  ("CAL", 2), ("REJ", 2), ("NEG", 2), ("PHASE", 2), ("CST", 2), ("CLP", 2)),
    "recursive_seed_literal": (("EST", 4),),
    "kalman_baro": (("X1", 4), ("X2", 4), ("X3", 4), ("EVENTS", 2), ("APFRAC", 2), ("GND", 4), ("SUMZ", 4),
                    ("CAL", 2), ("REJ", 2), ("NEG", 2), ("PHASE", 2), ("CST", 2), ("DLY", 2), ("VB", 4),
                    ("HMAX", 4), ("HT", 2)),
    "kalman_accel": (("X1", 4), ("X2", 4), ("X3", 4), ("ACC0", 4), ("EVENTS", 2), ("APFRAC", 2), ("GND", 4),
                     ("SUMZ", 4), ("SUMA", 4), ("CAL", 2), ("REJ", 2), ("NEG", 2), ("PHASE", 2), ("CST", 2),
                     ("DLY", 2), ("VB", 4), ("LOCK", 2), ("CLP", 2), ("E0", 4), ("HMAX", 4), ("HT", 2), ("HP", 4)),
}

#: Values of the ``PHASE`` word (docs/firmware-spec.md §4a), by name.
PHASES: tuple[str, ...] = ("PAD", "BOOST", "COAST", "APOGEE", "DESCENT")

#: Event bits of the ``EVENTS`` word (docs/firmware-spec.md §4).
EVENT_BITS: dict[str, int] = {
    "LIFTOFF": 1 << 0,
    "ARMED": 1 << 1,
    "APOGEE": 1 << 2,
    "MACH_LOCKOUT": 1 << 3,
    "BARO_INVALID": 1 << 4,
    "APOGEE_PREDICTED": 1 << 5,
    "GATE_HIGH": 1 << 6,
    "BARO_REJECT": 1 << 7,
    "ACC_CLIP": 1 << 8,
    "CLIP_CLEAR": 1 << 9,
}
#: Bits that stay set once set (all but the per-sample MACH_LOCKOUT, BARO_INVALID and BARO_REJECT).
LATCHED_EVENTS: int = (EVENT_BITS["LIFTOFF"] | EVENT_BITS["ARMED"] | EVENT_BITS["APOGEE"]
                       | EVENT_BITS["APOGEE_PREDICTED"] | EVENT_BITS["GATE_HIGH"] | EVENT_BITS["ACC_CLIP"]
                       | EVENT_BITS["CLIP_CLEAR"])


def word_names(program: str) -> tuple[str, ...]:
    """Names of the state words of ``program`` in output order."""
    return tuple(name for name, _ in STATE_WORDS[program])


@dataclass
class Trace:
    """Outputs of one or many streams through one firmware build.

    * ``words``: int64 array of shape ``(n_samples, n_words)`` for one stream, or ``(n_streams, n_samples,
      n_words)`` for many; column j is ``names[j]`` after each ``step``.
    * ``init_words``: the state after ``init``, shape ``(n_words,)`` or ``(n_streams, n_words)``.
    * ``cycles``: 68000 clocks spent in each ``step`` (harness only; ``None`` for the model), same leading shape as
      ``words`` without the last axis; ``init_cycles`` likewise for ``init``.
    """

    program: str
    names: tuple[str, ...]
    words: np.ndarray
    init_words: np.ndarray
    cycles: np.ndarray | None = None
    init_cycles: int | np.ndarray | None = None

    def column(self, name: str) -> np.ndarray:
        """The per-sample values of state word ``name`` (shape ``words.shape[:-1]``)."""
        return self.words[..., self.names.index(name)]

    def first_event(self, bit: str) -> np.ndarray | int:
        """Index of the first sample whose EVENTS word has ``bit`` set, or -1 (per stream when many)."""
        events = self.column("EVENTS")
        hit = (events & EVENT_BITS[bit]) != 0
        first = np.where(hit.any(axis=-1), hit.argmax(axis=-1), -1)
        return int(first) if first.ndim == 0 else first
