"""Markdown tables: the one renderer of the reports' tables (budget, MCU budget, apogee table, sweeps)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence


def row(cells: Iterable[object]) -> str:
    """One table row: ``| a | b |``."""
    return "| " + " | ".join(str(c) for c in cells) + " |"


def header(names: Sequence[object]) -> list[str]:
    """A table's header row and its ``|---|`` rule."""
    return [row(names), "|" + "---|" * len(names)]


def table(names: Sequence[object], rows: Iterable[Sequence[object]]) -> list[str]:
    """A whole table as lines: header, rule, one line per row."""
    return header(names) + [row(r) for r in rows]
