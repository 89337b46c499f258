"""``fwemu compare`` (firmware_model.cli.compare): report, CSV input errors, and the model's error statistics."""

from __future__ import annotations

import argparse

import pytest

from firmware_model.cli import compare as cli_compare
from firmware_model.spec.config import BuildConfig
from firmware_model.runtime.errors import UserError
from firmware_model.model.streams import flight_params_for, synthetic_flight


def _run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="fwemu")
    cli_compare.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["compare", *argv])
    return args.func(args)


def test_compare_synthetic_report(capsys):
    assert _run(["--program", "kalman_baro", "--k", "5", "--rounding", "half_up", "--synthetic", "3"]) == 0
    out = capsys.readouterr().out
    assert "fixed-mirror  X2" in out and "apogee sample: fixed=" in out and "wrap-around: none" in out


def test_compare_csv_input(tmp_path, capsys):
    p = tmp_path / "in.csv"
    p.write_text("adc,acc\n" + "".join(f"{30000 + (i % 3)},{i % 5}\n" for i in range(200)))
    assert _run(["--program", "recursive", "--input", str(p)]) == 0
    assert "fixed-mirror  EST" in capsys.readouterr().out


@pytest.mark.parametrize("text, msg", [("", "empty file"), ("x,y\n1,2\n", ":1: header must name an 'adc' column"),
                                       ("adc\n1\nfoo\n", ":3: adc='foo' is not an integer")])
def test_compare_bad_csv(tmp_path, text, msg):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(UserError, match=msg):
        _run(["--input", str(p)])


def test_fixed_vs_mirror_stats_consistent_with_recursive_bound():
    """On the synthetic flight, the reported fixed-mirror max error respects the recursive bound 2^S - 1."""
    cfg = BuildConfig(program="recursive", rounding="floor", shift=5)
    flight = synthetic_flight(cfg.k, cfg.baro_bits, 0, flight_params_for(cfg))
    res = cli_compare.compare(cfg, flight.adc, flight.acc)
    s = res["stats"]["fixed-mirror"]["EST"]
    assert 0 < s["max"] <= 31 and s["bias"] > 0  # floor: the integer EST sits above the float one
