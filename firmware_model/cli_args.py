"""Argument types shared by the ``fwemu`` subcommands: values argparse checks before a command runs, so a bad
value is the usual one-line usage error (exit 2) instead of a failure deep inside numpy."""

from __future__ import annotations

import argparse


def nonnegative_int(text: str) -> int:
    """An integer >= 0 (seeds: numpy's generators refuse negative seeds)."""
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} must be >= 0")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1 (``--jobs``)."""
    value = nonnegative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be >= 1")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (clock rates)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number > 0")
    return value
