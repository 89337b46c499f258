"""The case matrix of the golden vectors (docs/vectors.md): which programs, roundings, k, ADC widths and streams
make the committed set, the build of each case, and the constants every output format shares."""

from __future__ import annotations

from dataclasses import dataclass

from firmware_model.model.streams import (
    EDGE_KINDS,
    FlightParams,
    Stream,
    edge_stream,
    flight_params_for,
    pascal_edge_stream,
    supersonic_params_for,
    synthetic_flight,
    synthetic_pascal_flight,
)
from firmware_model.spec.atmosphere import pressure_pa
from firmware_model.spec.config import PROGRAMS, ROUNDINGS, BuildConfig
from firmware_model.vectors.flight_cases import flight_case_specs

#: Version of the case JSON layout (bump on any incompatible change; schema.json says the same).
SCHEMA_VERSION: int = 1
#: Program ids of vectors/c/fw.h (fw_program).
PROGRAM_IDS: dict[str, int] = {"recursive": 0, "kalman_baro": 1, "kalman_accel": 2, "recursive_seed_literal": 3}
C_PROGRAM_ENUM: dict[str, str] = {"recursive": "FW_RECURSIVE", "kalman_baro": "FW_KALMAN_BARO",
                                  "kalman_accel": "FW_KALMAN_ACCEL",
                                  "recursive_seed_literal": "FW_RECURSIVE_SEED_LITERAL"}
#: Gains in fw_consts order (vectors/c/fw.h).
GAIN_NAMES: tuple[str, ...] = ("G11", "G21", "G31", "G12", "G22", "G32", "ACC_G", "G11T", "G21T", "G31T")
#: Scalar constants in fw_consts order.
SCALAR_CONSTANTS: tuple[str, ...] = ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO",
                                     "MACH_VHI", "MACH_E", "BARO_MIN", "BARO_MAX", "ALT_SHIFT", "ALT_N", "CAL_P",
                                     "E_GATE", "GATE_N", "APO_N", "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N",
                                     "V_DESC", "DU", "A_DRAG", "CLIP_N", "GUARDS", "DG", "V_FALL", "H_FLOOR",
                                     "DESC_N", "H_STEP")

# ------------------------------------------------------------------------------------------- the case matrix
#: k values (sample period 2^-k s) of the committed set.
MATRIX_K: tuple[int, ...] = (4, 5, 6, 7, 8)
#: Barometer ADC widths of the committed set.
MATRIX_BITS: tuple[int, ...] = (12, 16)
#: Samples per edge stream.
EDGE_SAMPLES: int = 32
#: Seed of the synthetic flight of the committed set (one flight profile, sampled at every k).
FLIGHT_SEED: int = 20240601
#: Programs that get the synthetic flight (the literal Schultz 2002 listing diverges; it gets the edge streams only).
FLIGHT_PROGRAMS: tuple[str, ...] = ("recursive", "kalman_baro", "kalman_accel")
#: The fast (transonic) flight: Kalman programs only, 16-bit barometer, these k (it is long: ~20 s).
FAST_FLIGHT_PROGRAMS: tuple[str, ...] = ("kalman_baro", "kalman_accel")
FAST_FLIGHT_K: tuple[int, ...] = (4, 5)
FAST_FLIGHT_BITS: int = 16
#: The supersonic flight with a transonic dip (issue 20; :func:`firmware_model.model.streams.supersonic_params_for`):
#: every flight program, both roundings, at these k, 16-bit barometer.
SUPERSONIC_K: tuple[int, ...] = (5,)
FAST_FLIGHT_SEED: int = 20240602

Q_FORMATS: dict[str, dict[str, str]] = {
    "recursive": {"EST": "Q24.8 barometer units (z = BARO_SIGN*adc)", "EXT": "Q24.8 barometer units",
                  "VEL": "Q32.0 accelerometer counts x samples", "ACC0": "Q32.0 accelerometer counts",
                  "EVENTS": "uint16 event bits", "ZL": "Q32.0 barometer units (last sample used)",
                  "SUMA": "Q32.0 accelerometer counts (sum of pad readings)", "CAL": "uint16 pad samples",
                  "REJ": "uint16 rejected barometer samples in a row",
                  "NEG": "uint16 apogee evidence samples in a row",
                  "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                  "CST": "uint16 coast samples in a row",
                  "CLP": "uint16 clip counter (boost: rail samples in a row; after ACC_CLIP: drag-low coast samples "
                         "in a row)"},
    "recursive_seed_literal": {"EST": "Q24.8 barometer units (z = BARO_SIGN*adc)"},
    "kalman_baro": {"X1": "Q24.8 m (table altitude)", "X2": "Q24.8 m/s", "X3": "Q24.8 m/s^2",
                    "EVENTS": "uint16 event bits", "APFRAC": "UQ0.16 fraction of a sample period",
                    "GND": "Q24.8 m (pad average)", "SUMZ": "Q24.8 m (sum of pad altitudes)",
                    "CAL": "uint16 pad samples", "REJ": "uint16 gated samples in a row",
                    "NEG": "uint16 apogee evidence samples in a row",
                    "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                    "CST": "uint16 coast samples in a row", "DLY": "uint16 Mach-delay samples left",
                    "VB": "Q24.8 m/s (plausibility bound)",
                    "HMAX": "Q24.8 m (highest valid barometric altitude)",
                    "HT": "uint16 valid samples since HMAX last rose"},
    "kalman_accel": {"X1": "Q24.8 m (table altitude)", "X2": "Q24.8 m/s", "X3": "Q24.8 m/s^2",
                     "ACC0": "Q32.0 accelerometer counts (pad average)", "EVENTS": "uint16 event bits",
                     "APFRAC": "UQ0.16 fraction of a sample period", "GND": "Q24.8 m (pad average)",
                     "SUMZ": "Q24.8 m (sum of pad altitudes)", "SUMA": "Q32.0 sum of pad accelerometer counts",
                     "CAL": "uint16 pad samples", "REJ": "uint16 gated samples in a row",
                     "NEG": "uint16 apogee evidence samples in a row",
                     "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                     "CST": "uint16 coast samples in a row", "DLY": "uint16 Mach-delay samples left",
                     "VB": "Q24.8 m/s (plausibility bound)",
                     "LOCK": "uint16 Mach lockout samples left (0: barometer in use)",
                     "CLP": "uint16 clip counter (boost: rail samples in a row; after ACC_CLIP: samples of the "
                            "re-base window so far)",
                     "E0": "Q24.8 m (re-base window: sum of the second half's innovations minus the first's)",
                     "HMAX": "Q24.8 m (highest valid barometric altitude)",
                     "HT": "uint16 valid samples since HMAX last rose",
                     "HP": "Q24.8 m (the last valid barometric altitude)"},
}


def units_per_metre_for(bits: int) -> float:
    """Barometer counts per metre used for a ``bits``-bit ADC in the committed set: 3.5 counts/m at 16 bits,
    scaled by 2^(bits-16) (the same pressure sensor read with fewer bits)."""
    return 3.5 * 2.0 ** (bits - 16)


def baro_sigma_for(bits: int) -> float:
    """Barometer noise (counts rms) of the committed set: 2 counts at 16 bits, scaled like the counts, but not
    below 0.5 count (quantization noise)."""
    return max(0.5, 2.0 * 2.0 ** (bits - 16))


def case_config(program: str, rounding: str, k: int, bits: int) -> BuildConfig:
    """The build config of one committed case: defaults of :class:`BuildConfig` except the ADC width, its counts
    per metre and noise, and a valid barometer range that excludes the two rail codes (0 and 2^bits-1: a saturated
    reading is invalid), so that the adc_min / adc_max / alternating streams exercise BARO_INVALID. The Mach delay
    is 0 for every program (kalman_baro's default since issue 30 is 8 s, longer than these flights' climbs of 5-8 s:
    it would hold off every apogee the cases test)."""
    pa_per_count, pa_at_zero = _flight_sensor(bits)
    return BuildConfig(program=program, rounding=rounding, k=k, baro_bits=bits,
                       units_per_metre=units_per_metre_for(bits), baro_sigma=baro_sigma_for(bits),
                       baro_min=1, baro_max=(1 << bits) - 2, baro_pa_per_count=pa_per_count,
                       baro_pa_at_zero=pa_at_zero, mach_delay_s=0.0)


def _flight_sensor(bits: int) -> tuple[float, float]:
    """The linear barometer transfer (Pa per count, Pa at count 0) of
    :func:`firmware_model.model.streams.synthetic_flight` for a ``bits``-bit ADC with the default pad (altitude,
    fraction of full scale): the altitude table of the committed Kalman cases matches the synthetic flights' sensor
    (field-ready firmware, docs/firmware-spec.md §2a). Counts below about 26,000 (16-bit) map to pressures under the
    table's floor (above ~31 km)."""

    p = FlightParams()
    p_pad = float(pressure_pa(p.pad_altitude_m))
    a = (p_pad - float(pressure_pa(p.pad_altitude_m + 1.0))) / units_per_metre_for(bits)
    return a, p_pad - a * p.pad_fraction * ((1 << bits) - 1)


@dataclass(frozen=True)
class CaseSpec:
    """One golden-vector case: a build config and an input stream."""

    name: str
    cfg: BuildConfig
    stream: Stream


def case_name(program: str, rounding: str, k: int, bits: int, stream: str) -> str:
    """``<program>_<rounding>_k<k>_b<bits>_<stream>`` (a C identifier); ``bits`` = 32, the pascal kind's word:
    ``<program>_<rounding>_k<k>_pa_<stream>``."""
    return f"{program}_{rounding}_k{k}_{'pa' if bits == 32 else f'b{bits}'}_{stream}"


#: Pascal cases of the committed set (docs/vectors.md, "Pascal cases"): every program and rounding at this k, the
#: pascal edge streams of these kinds, and the pascal synthetic flight for (program, rounding) in
#: :data:`PASCAL_FLIGHTS`. Kept small: the whole set must stay under 20 MB.
PASCAL_K: int = 4
PASCAL_EDGE_KINDS: tuple[str, ...] = ("adc_min", "alternating", "ties", "ramp")
PASCAL_FLIGHTS: tuple[tuple[str, str], ...] = (("recursive", "floor"), ("kalman_baro", "half_up"),
                                               ("kalman_accel", "floor"))
#: Pascals per metre of the pascal cases' builds (rho g at sea level) and their barometer noise (Pa rms).
PASCAL_PA_PER_M: float = 12.0
PASCAL_SIGMA_PA: float = 3.0


def pascal_case_config(program: str, rounding: str, k: int) -> BuildConfig:
    """The build of a pascal case: ``baro_kind`` pascal (MS5607 range 1,000..120,000 Pa, the default table),
    12 Pa/m, 3 Pa noise, a Mach delay of 0 (as :func:`case_config`), otherwise the defaults."""
    return BuildConfig(program=program, rounding=rounding, k=k, baro_kind="pascal", units_per_metre=PASCAL_PA_PER_M,
                       baro_sigma=PASCAL_SIGMA_PA, mach_delay_s=0.0)


def pascal_case_specs() -> list[CaseSpec]:
    """The pascal cases (:data:`PASCAL_K`, :data:`PASCAL_EDGE_KINDS`, :data:`PASCAL_FLIGHTS`), in a fixed order."""

    specs: list[CaseSpec] = []
    flight = synthetic_pascal_flight(PASCAL_K, seed=FLIGHT_SEED, noise_pa=PASCAL_SIGMA_PA)
    for program in PROGRAMS:
        for rounding in ROUNDINGS:
            cfg = pascal_case_config(program, rounding, PASCAL_K)
            for kind in PASCAL_EDGE_KINDS:
                stream = pascal_edge_stream(kind, EDGE_SAMPLES, PASCAL_K)
                specs.append(CaseSpec(case_name(program, rounding, PASCAL_K, 32, stream.name), cfg, stream))
            if (program, rounding) in PASCAL_FLIGHTS:
                specs.append(CaseSpec(case_name(program, rounding, PASCAL_K, 32, flight.name), cfg, flight))
    return specs


def case_matrix(require_logs: bool = True) -> list[CaseSpec]:
    """Every case of the committed set, in a fixed order (documented in docs/vectors.md):
    programs x roundings x k in :data:`MATRIX_K` x ADC bits in :data:`MATRIX_BITS` x (the
    :data:`~firmware_model.model.streams.EDGE_KINDS` edge streams of :data:`EDGE_SAMPLES` samples, plus the synthetic
    flight for :data:`FLIGHT_PROGRAMS`), then the flight cases of
    :data:`firmware_model.vectors.flight_cases.FLIGHT_CASES` (the real-log cases need ../shared/flights: without
    it a :class:`UserError`, or with ``require_logs=False`` the set without them)."""
    return grid_case_specs() + tail_case_specs(require_logs)


def grid_case_specs() -> list[CaseSpec]:
    """The first part of :func:`case_matrix`: programs x roundings x k x ADC bits (edge streams and synthetic
    flights). Cheap to build (no log, no simulation): ``--jobs`` starts running it while :func:`tail_case_specs`
    is built."""
    specs: list[CaseSpec] = []
    flights: dict[tuple[int, int], Stream] = {}
    for program in PROGRAMS:
        for rounding in ROUNDINGS:
            for k in MATRIX_K:
                for bits in MATRIX_BITS:
                    cfg = case_config(program, rounding, k, bits)
                    for kind in EDGE_KINDS:
                        stream = edge_stream(kind, EDGE_SAMPLES, bits, k)
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FLIGHT_PROGRAMS:
                        key = (k, bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FLIGHT_SEED, flight_params_for(cfg))
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FAST_FLIGHT_PROGRAMS and k in FAST_FLIGHT_K and bits == FAST_FLIGHT_BITS:
                        key = (k, -bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FAST_FLIGHT_SEED, flight_params_for(cfg, True),
                                                            name="flight_fast")
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FLIGHT_PROGRAMS and k in SUPERSONIC_K and bits == FAST_FLIGHT_BITS:
                        key = (k, -1000 - bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FAST_FLIGHT_SEED, supersonic_params_for(cfg),
                                                            name="flight_supersonic")
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
    return specs


def tail_case_specs(require_logs: bool = True) -> list[CaseSpec]:
    """The rest of :func:`case_matrix`, in order: the flight cases, then the pascal cases. The flight cases read
    the shared logs and simulate flights (seconds of work; :class:`UserError` when the logs are absent and
    ``require_logs``)."""
    # Flight cases (docs/vectors.md, "Flight cases"): MIT-licensed shared logs and simulated flights, floor, k = 5,
    # built as the apogee table builds them; provenance and licence in each case's input.provenance.

    return flight_case_specs(case_name, CaseSpec, Stream, require_logs) + pascal_case_specs()


#: The subset run on the ATmega2560 under simavr (must fit 64 KiB of program-memory data: the Kalman cases carry
#: 14-17 words per sample and a 2 KiB altitude table since issue 20, so one flight per program family runs:
#: kalman_accel's, whose C path (step_kalman with the accelerometer) is a superset of kalman_baro's, and the
#: recursive one in floor rounding; the long transonic and the supersonic flights are left to the host). Since the
#: clipped-accelerometer change (CLP in recursive, CLP and E0 in kalman_accel: 13 and 19 words a sample) the
#: recursive half_up edge_step case (1.8 KB) is left out: with it the data ran 220 bytes past 64 KiB (the recursive
#: flight's adc array read wrong through pgm_read_word); recursive half_up keeps edge_ties, recursive edge_step keeps
#: floor. The Schultz 2002 listing's pascal edge_ties (0.4 KB) takes its place: the pascal word on the AVR for the
#: third program family, and the subset stays at 20 cases. Since issue 30's descent guard (HMAX and HT: 16 and 21
#: words a Kalman sample) the data ran 2.3 KB past 64 KiB again: the two Kalman programs' half_up edge_step cases
#: (2.2 and 2.8 KB) are left out as recursive's was (each program and rounding keeps edge_ties; edge_step keeps
#: floor), 18 cases.
_AVR_LEFT_OUT: frozenset[tuple[str, str, str]] = frozenset({("recursive", "half_up", "step"),
                                                            ("kalman_baro", "half_up", "step"),
                                                            ("kalman_accel", "half_up", "step")})
AVR_CASES: tuple[str, ...] = tuple(
    [case_name("recursive", "floor", 4, 16, "flight")]
    + [case_name(p, "floor", PASCAL_K, 32, "edge_ties")
       for p in ("recursive", "kalman_accel", "recursive_seed_literal")]
    + [case_name("kalman_accel", "half_up", 4, 16, "flight")]
    + [case_name(p, r, 4, 16, "edge_" + kind) for p in PROGRAMS for r in ROUNDINGS for kind in ("ties", "step")
       if (p, r, kind) not in _AVR_LEFT_OUT]
)
