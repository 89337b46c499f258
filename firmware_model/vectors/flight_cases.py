"""Golden-vector cases from flights (docs/vectors.md, "Flight cases"): the MIT-licensed shared logs (prometheus
TeleMetrum/TeleMega, CATS hedy) and a few simulated scenarios, turned into firmware input streams exactly as the
apogee table does (:func:`firmware_model.flights.evaluation.setup.flight_inputs`, the same build fields), cut to the pad
and the flight up to 3 s after the reference apogee so the cases stay small.

Each case's ``input.provenance`` names the source (path relative to the repository's parent for logs, so
``../shared/flights/...``; the scenario for simulations), its SHA-256 (logs), format, **licence** and origin, the
sensor model, the resampling report and the cut; ``input.truth`` holds the reference apogee (truth for
simulations, the robust parabola with its uncertainty for logs) in seconds from the first sample and as a sample
index. Only logs whose licence allows redistribution are used (the 2012 AltOS logs are GPL: not included).

The logs are read from ``../shared/flights`` (``$FWEMU_SHARED_FLIGHTS``); without them these cases cannot be
generated, and :func:`flight_case_specs` raises a :class:`UserError` saying so.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.flights.evaluation.evalset import shared_dir
from firmware_model.flights.evaluation.methods import METHODS
from firmware_model.flights.evaluation.setup import FlightSpec, load_record, reference_for, sensor_config, sensors_for
from firmware_model.flights.inputs.firmware_inputs import firmware_inputs
from firmware_model.runtime import diskcache
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.hashing import sha256_file

#: Sample period of the flight cases (2^-5 s: short streams, still a realistic rate for the recursive filter).
FLIGHT_CASE_K: int = 5
#: Seconds kept after the reference apogee.
AFTER_APOGEE_S: float = 3.0

#: (stream name, source, baro preset or None, noisy, programs). Sources: a path under the shared flights folder
#: or ``sim:NAME``. Program ``recursive`` is built as the table's ``rec_quarter``.
FLIGHT_CASES: tuple[tuple[str, str, str | None, bool, tuple[str, ...]], ...] = (
    ("log_prometheus_tm", "altosui/prometheus-2022-06-24-telemetrum.csv", None, False,
     ("recursive", "kalman_baro", "kalman_accel")),
    ("log_prometheus_tmega", "altosui/prometheus-2022-06-24-telemega.csv", None, False, ("kalman_baro",)),
    ("log_hedy", "cats/hedy-baro.csv", None, False, ("kalman_baro", "kalman_accel")),
    ("sim_trans_m1670", "sim:trans-m1670-m105", "mpx4115_16bit", True, ("kalman_baro", "kalman_accel")),
    ("sim_sub_k400_spikes", "sim:sub-k400-900m-spikes", "mpx4115_12bit", True, ("recursive",)),
    # the clipped supersonic boost with a transonic pressure step (ACC_CLIP, the rate gate, apogee evidence; since
    # the clipped-accelerometer change CLIP_CLEAR, and for kalman_accel the clip lockout and the velocity re-base)
    ("sim_sup_m6400", "sim:sup-m6400-m167", "mpx4115_16bit", True, ("recursive", "kalman_accel")),
)
#: Licences that allow the vectors to carry a log's samples.
REDISTRIBUTABLE: tuple[str, ...] = ("MIT",)


def _method_for(program: str) -> Any:
    return METHODS["rec_quarter" if program == "recursive" else program]


#: Bumped when the cached form of the flight cases changes.
_CACHE_FORMAT = 1


def flight_cases_key(require_logs: bool, base: Path | None) -> str:
    """The content key of :func:`flight_case_specs`' result: the case list, ``require_logs``, the bytes of every
    log it reads (or that the log is missing), and :func:`firmware_model.runtime.diskcache.source_digest`."""
    h = hashlib.sha256(repr((_CACHE_FORMAT, FLIGHT_CASES, bool(require_logs), base is None)).encode())
    for _name, source, *_ in FLIGHT_CASES:
        if source.startswith("sim:") or base is None:
            continue
        try:
            h.update(source.encode() + b"\0" + hashlib.sha256((base / source).read_bytes()).digest())
        except OSError:
            h.update(source.encode() + b"\0missing")
    h.update(diskcache.source_digest().encode())
    return h.hexdigest()


def flight_case_specs(case_name: Any, spec_type: Any, stream_type: Any, require_logs: bool = True) -> list[Any]:
    """The flight cases as :class:`firmware_model.vectors.generate.CaseSpec` (``case_name``, ``spec_type`` and
    ``stream_type`` are vectors' ``case_name``, ``CaseSpec`` and ``Stream``, passed in to keep this module free of
    an import cycle). When the shared logs are absent: :class:`UserError` if ``require_logs``, else the simulated
    cases only.

    Reading the logs and simulating the flights takes seconds; the result is kept in the disk cache
    (:func:`firmware_model.runtime.diskcache.cache_dir`, ``cases/flights-<key>.pickle``) under :func:`flight_cases_key`,
    so a later run with the same logs and the same code loads it instead (the same specs:
    tests/vectors/test_generate.py)."""

    base = shared_dir()
    return diskcache.memo("cases", lambda: f"flights-{flight_cases_key(require_logs, base)}",
                          lambda obj: isinstance(obj, list) and all(type(x) is spec_type for x in obj),
                          lambda: _flight_case_specs(case_name, spec_type, stream_type, require_logs, base))


def _flight_case_specs(case_name: Any, spec_type: Any, stream_type: Any, require_logs: bool,
                       base: Path | None) -> list[Any]:

    specs: list[Any] = []
    for stream_name, source, baro, noisy, programs in FLIGHT_CASES:
        if source.startswith("sim:"):
            path_text, prov_extra = source, {}
            record = load_record(source)
        else:
            if base is None:
                if not require_logs:
                    continue
                raise UserError("vectors: the flight cases need the shared logs in ../shared/flights (or "
                                "$FWEMU_SHARED_FLIGHTS); they are absent")
            path = base / source
            record = load_record(str(path))
            path_text = f"../shared/flights/{source}"
            prov_extra = {"file_sha256": sha256_file(path)}
            if record.provenance.get("licence") not in REDISTRIBUTABLE:
                raise UserError(f"vectors: {path_text}: licence {record.provenance.get('licence')!r} does not allow "
                                f"golden vectors (only {', '.join(REDISTRIBUTABLE)})")
        ref = reference_for(record)
        fspec = FlightSpec(source, k=FLIGHT_CASE_K, baro=baro, accel="default" if baro else None, noise=noisy,
                           seed=0)

        b, a = sensors_for(fspec)
        inputs = firmware_inputs(record, FLIGHT_CASE_K, baro=b, accel=a, method="linear", seed=0,
                                 t_end=ref.time_s + AFTER_APOGEE_S)
        t0 = float(inputs.time_s[0])
        apogee_sample = int(np.searchsorted(inputs.time_s, ref.time_s))
        prov = {"generator": "fwemu flights (firmware_model.vectors.flight_cases)", "source": path_text,
                "format": record.provenance.get("format"), "licence": record.provenance.get("licence"),
                "origin": record.provenance.get("origin") or record.provenance.get("source"),
                **prov_extra, "scenario": record.provenance.get("scenario"),
                "baro_sensor": inputs.baro.to_dict(), "accel_sensor": inputs.accel.to_dict(),
                "noise_seed": 0 if noisy else None, "first_sample_time_s": t0,
                "cut": f"liftoff - 2 s .. reference apogee + {AFTER_APOGEE_S:g} s",
                "resampling": inputs.report.to_dict()}
        truth = {"apogee_s": round(ref.time_s - t0, 6), "apogee_sample": apogee_sample,
                 "apogee_source": ref.source,
                 "apogee_uncertainty_s": None if ref.uncertainty_s is None else round(ref.uncertainty_s, 6),
                 "apogee_altitude_m": None if ref.altitude_m is None else round(ref.altitude_m, 3),
                 "altos_apogee_s": None if not record.events.get("altos_apogee") else
                 round(record.events["altos_apogee"] - t0, 6)}
        bits = int(inputs.baro.bits)
        stream = stream_type(name=stream_name, adc=np.asarray(inputs.adc, dtype=np.int64),
                             acc=np.asarray(inputs.acc, dtype=np.int64), k=FLIGHT_CASE_K, bits=bits,
                             provenance=prov, truth=truth)
        sensor = sensor_config(inputs)
        for program in programs:
            cfg = _method_for(program).config(FLIGHT_CASE_K, sensor)
            specs.append(spec_type(case_name(program, cfg.rounding, FLIGHT_CASE_K, bits, stream_name), cfg, stream))
    return specs


__all__ = ["FLIGHT_CASE_K", "FLIGHT_CASES", "flight_case_specs"]
