"""Log plausibility at the readers' door (issue 33): an altitude of 1e308 ft, a pressure of 1e308 hPa or Pa, an RRC3
log whose times are negated, a folder or a FIFO given as a flight file and a missing ``--columns`` map file are each
one clean error naming the file (and line and column where there is one), never a traceback, a block or a silent
repair."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from firmware_model.flights.readers import read_flight
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError

RRC3 = "time,altitude,pressure,velocity,temperature,events,voltages\n"


def rrc3_rows(n: int = 60, neg: bool = False, bad_hpa: str | None = None) -> str:
    rows = []
    for i in range(n):
        t = i * 0.05
        hpa = f"{1000.0 - i * 0.5:.2f}" if bad_hpa is None or i != 30 else bad_hpa
        rows.append(f"{-t if neg and t else t:.2f},{i},{hpa},0,20, -,3.8")
    return RRC3 + "\n".join(rows) + "\n"


def test_rrc3_negated_times_are_an_error_not_a_sort(tmp_path: Path) -> None:
    p = tmp_path / "neg.csv"
    p.write_text(rrc3_rows(neg=True))
    with pytest.raises(UserError, match=rf"^{p}:3: time does not increase \(0 -> -0\.05\)"):
        read_flight(p)


def test_rrc3_pressure_1e308_hpa_names_line_and_column(tmp_path: Path) -> None:
    p = tmp_path / "p.csv"
    p.write_text(rrc3_rows(bad_hpa="1e308"))
    with pytest.raises(UserError, match=rf"^{p}:32: pressure: 1e308 hPa is out of range; allowed: at most 2,000 hPa"):
        read_flight(p)


def test_eggtimer_altitude_1e308_ft_names_line_and_column(tmp_path: Path) -> None:
    rows = [f"{i * 50};{100 + i};0;0;0;0;0;{1 if i == 20 else 0};0;0;0" for i in range(40)]
    rows[10] = "500;1e308;0;0;0;0;0;0;0;0;0"
    p = tmp_path / "egg.csv"
    p.write_text("T;Alt;Veloc;Filt_Alt;FVeloc;LDA;LowV;Apogee;N-O;Drogue;Main\n" + "\n".join(rows) + "\n")
    with pytest.raises(UserError, match=rf"^{p}:12: Alt: 1e\+308 ft is out of range; allowed: -3281\.\.328084 ft"):
        read_flight(p)


def test_generic_pressure_1e308_pa_names_the_line(tmp_path: Path) -> None:
    rows = [f"{i * 0.01:.2f},{100000 - i}" for i in range(40)]
    rows[5] = "0.05,1e308"
    p = tmp_path / "g.csv"
    p.write_text("time_s,pressure_pa\n" + "\n".join(rows) + "\n")
    with pytest.raises(UserError, match=rf"^{p}:7: pressure: 1e\+308 Pa is out of range; allowed: more than 0 and "
                                        r"at most 200,000 Pa"):
        read_flight(p)


def test_a_record_without_lines_names_the_row() -> None:
    with pytest.raises(UserError, match=r"^sim: row 1: pressure: -5 Pa is out of range"):
        FlightRecord(name="x", time_s=[0.0, 0.1, 0.2], pressure_pa=[1e5, -5.0, 1e5], provenance={"source": "sim"})


def test_folder_and_fifo_are_clear_errors_never_a_block(tmp_path: Path) -> None:
    d = tmp_path / "logs"
    d.mkdir()
    with pytest.raises(UserError, match=rf"^{d}: is a directory, not a flight log$"):
        read_flight(d)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(UserError, match=rf"^{fifo}: is a FIFO, not a flight log file"):
        read_flight(fifo)                         # returns at once: the FIFO is never opened


def test_missing_column_map_file_says_so(tmp_path: Path) -> None:
    p = tmp_path / "g.csv"
    p.write_text("a,b\n0,100000\n0.1,99990\n")
    with pytest.raises(UserError, match=r"nomap\.txt: no such column map file"):
        read_flight(p, columns=str(tmp_path / "nomap.txt"))
