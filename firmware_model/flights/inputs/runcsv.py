"""The per-sample output of a firmware run in physical units, as ``fwemu run`` writes it and ``fwemu plot`` reads it.

Columns (Schultz n.d.'s rdaskal3 order first, so its gnuplot recipes work: ``using 1:3`` filtered altitude, ``1:4``
velocity, ``1:2`` raw altitude): ``time_s, raw_altitude_m, filtered_altitude_m, velocity_mps, accel_mps2``, then
``events`` (the EVENTS word), ``new_events`` (names of the bits that set at this sample, ``|``-separated),
``cycles`` (68000 clocks of this ``step``; empty when the integer model ran), ``phase`` (the PHASE word by name:
PAD, BOOST, COAST, APOGEE, DESCENT, docs/firmware-spec.md §4a; absent in CSVs written before issue 20).

Conversion of the integer state to metres (docs/evaluation.md, "fwemu run"): the raw altitude is
``altitude_of_counts(adc)``, metres above the pad through the sensor model's inverse transfer function and the
standard atmosphere (default: linear with the build's ``units_per_metre``). The field-ready Kalman programs run in
metres: filtered altitude ``(X1 - GND)/256``, velocity ``X2/256``, acceleration ``X3/256``. The recursive program's
``EST/256`` times ``BARO_SIGN`` is an ADC value (through ``altitude_of_counts``), its velocity the accelerometer
integral ``VEL x dt / accel_counts_per_mps2`` and its acceleration ``(acc - ACC0) / accel_counts_per_mps2``.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from firmware_model.model.trace import EVENT_BITS, LATCHED_EVENTS, PHASES
from firmware_model.runtime.errors import UserError

COLUMNS: tuple[str, ...] = ("time_s", "raw_altitude_m", "filtered_altitude_m", "velocity_mps", "accel_mps2",
                            "events", "new_events", "cycles", "phase")


@dataclass
class RunTable:
    """One run, per sample, in SI units (see the module docstring)."""

    time_s: np.ndarray
    raw_altitude_m: np.ndarray
    filtered_altitude_m: np.ndarray
    velocity_mps: np.ndarray
    accel_mps2: np.ndarray
    events: np.ndarray
    cycles: np.ndarray | None = None
    program: str = ""
    phase: np.ndarray | None = None

    # ------------------------------------------------------------------ events
    def event_times(self) -> dict[str, float | None]:
        """Time of the first sample with each latched bit set (None: never), plus APOGEE_PREDICTED."""
        out: dict[str, float | None] = {}
        for name, bit in EVENT_BITS.items():
            if not bit & LATCHED_EVENTS:
                continue
            hit = (self.events & bit) != 0
            out[name] = float(self.time_s[int(hit.argmax())]) if hit.any() else None
        return out

    def phase_times(self) -> dict[str, float]:
        """Time of the first sample in each PHASE after PAD that the run entered (docs/firmware-spec.md §4a)."""
        if self.phase is None:
            return {}
        out: dict[str, float] = {}
        ph = np.asarray(self.phase, dtype=np.int64)
        for j, name in enumerate(PHASES[1:], start=1):
            hit = ph == j
            if hit.any():
                out[name] = float(self.time_s[int(hit.argmax())])
        return out

    def intervals(self, name: str) -> list[tuple[float, float]]:
        """(first, last) sample times of each run of a per-sample bit (MACH_LOCKOUT, BARO_INVALID)."""
        hit = ((self.events & EVENT_BITS[name]) != 0).astype(np.int8)
        edges = np.diff(np.concatenate([[0], hit, [0]]))
        starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
        return [(float(self.time_s[a]), float(self.time_s[b])) for a, b in zip(starts, ends)]

    # ------------------------------------------------------------------ CSV
    def to_csv(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(COLUMNS)
        prev = 0
        names = list(EVENT_BITS.items())
        cyc = self.cycles
        ph = self.phase
        for i in range(self.time_s.shape[0]):
            e = int(self.events[i])
            new = "|".join(n for n, b in names if e & b and not prev & b)
            prev = e
            w.writerow([f"{self.time_s[i]:.6f}", f"{self.raw_altitude_m[i]:.3f}", f"{self.filtered_altitude_m[i]:.3f}",
                        f"{self.velocity_mps[i]:.3f}", f"{self.accel_mps2[i]:.3f}", e, new,
                        "" if cyc is None else int(cyc[i]), "" if ph is None else PHASES[int(ph[i])]])
        return buf.getvalue()

    @classmethod
    def read_csv(cls, path: str | Path) -> "RunTable":
        """Read a CSV written by :meth:`to_csv`; errors name the file and line."""
        path = Path(path)
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise UserError(f"{path}: no such file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise UserError(f"{path}: cannot read: {exc}") from None
        rows = list(csv.reader(io.StringIO(text)))
        if not rows or tuple(rows[0][:5]) != COLUMNS[:5]:
            raise UserError(f"{path}:1: not an fwemu run CSV (expected the header {','.join(COLUMNS)})")
        head = rows[0]
        idx = {name: head.index(name) for name in COLUMNS if name in head}
        data: dict[str, list[float]] = {name: [] for name in idx}
        for lineno, row in enumerate(rows[1:], start=2):
            if not row:
                continue
            for name, j in idx.items():
                if name == "new_events":
                    continue
                cell = row[j] if j < len(row) else ""
                if name == "phase":
                    if cell not in PHASES and cell != "":
                        raise UserError(f"{path}:{lineno}: column phase: {cell!r} is not one of {', '.join(PHASES)}")
                    data[name].append(float(PHASES.index(cell)) if cell else float("nan"))
                    continue
                try:
                    data[name].append(float(cell) if cell != "" else float("nan"))
                except ValueError:
                    raise UserError(f"{path}:{lineno}: column {name}: {cell!r} is not a number") from None
        if len(data["time_s"]) < 2:
            raise UserError(f"{path}: fewer than 2 samples")
        arr = {k: np.array(v) for k, v in data.items() if k != "new_events"}
        cycles = arr.get("cycles")
        if cycles is not None and np.all(np.isnan(cycles)):
            cycles = None
        phase = arr.get("phase")
        if phase is not None and np.all(np.isnan(phase)):
            phase = None
        return cls(arr["time_s"], arr["raw_altitude_m"], arr["filtered_altitude_m"], arr["velocity_mps"],
                   arr["accel_mps2"], np.nan_to_num(arr.get("events", np.zeros_like(arr["time_s"]))).astype(np.int64),
                   None if cycles is None else np.nan_to_num(cycles).astype(np.int64),
                   phase=None if phase is None else np.nan_to_num(phase).astype(np.int64))


def linear_altitude(cfg: Any, pad_counts: float) -> Callable[[np.ndarray], np.ndarray]:
    """ADC value -> metres above the pad, linear with ``cfg.units_per_metre`` (what the firmware itself assumes)."""
    sign, upm = float(cfg.baro_sign), float(cfg.units_per_metre)

    def alt(counts: np.ndarray) -> np.ndarray:
        return sign * (np.asarray(counts, dtype=np.float64) - pad_counts) / upm

    return alt


def from_trace(trace: Any, cfg: Any, time_s: np.ndarray, adc: np.ndarray, acc: np.ndarray | None,
               altitude_of_counts: Callable[[np.ndarray], np.ndarray] | None = None) -> RunTable:
    """A :class:`RunTable` from a firmware trace (emulated CPU or integer model) of ``cfg`` on ``adc``/``acc``."""
    adc = np.asarray(adc, dtype=np.float64)
    alt = altitude_of_counts or linear_altitude(cfg, float(adc[0]))
    sign = float(cfg.baro_sign)
    dt = cfg.dt
    raw = alt(adc)
    if trace.program in ("kalman_baro", "kalman_accel") and "GND" in trace.names:
        # field-ready Kalman programs (docs/firmware-spec.md §6): metres; above ground = X1 - GND
        filt = (trace.column("X1") - trace.column("GND")) / 256.0
        vel = trace.column("X2") / 256.0
        accel = trace.column("X3") / 256.0
    elif trace.program in ("kalman_baro", "kalman_accel"):
        c1 = trace.column("X1") / 256.0 * sign          # ADC value of the filtered altitude
        filt = alt(c1)
        m_per_count = (alt(c1 + 0.5) - alt(c1 - 0.5))  # metres per ADC count at the filtered altitude (signed)
        vel = trace.column("X2") / 256.0 * sign * m_per_count
        accel = trace.column("X3") / 256.0 * sign * m_per_count
    elif trace.program == "recursive":
        filt = alt(trace.column("EST") / 256.0 * sign)
        cpm = float(cfg.accel_counts_per_mps2)
        vel = trace.column("VEL") * dt / cpm
        a = np.zeros_like(adc) if acc is None else np.asarray(acc, dtype=np.float64)
        accel = (a - trace.column("ACC0")) / cpm
    else:
        raise UserError(f"run table: program {trace.program!r} has no apogee logic to report")
    cycles = None if trace.cycles is None else np.asarray(trace.cycles)
    phase = np.asarray(trace.column("PHASE"), dtype=np.int64) if "PHASE" in trace.names else None
    return RunTable(np.asarray(time_s, dtype=np.float64), raw, filt, vel, accel,
                    np.asarray(trace.column("EVENTS"), dtype=np.int64), cycles, trace.program, phase)


__all__ = ["COLUMNS", "RunTable", "linear_altitude", "from_trace"]
