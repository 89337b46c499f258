"""Count what the ISA oracle tests draw: ``python -m tests.support.oracle_draws [--per-test] [pytest args]`` (from
the checkout's root).

Runs pytest in this process (default: ``tests/isa/test_vs_m68000py.py tests/isa/test_vs_musashi.py -n 0`` under
the profile ``HYPOTHESIS_PROFILE`` names, ``ci`` by default) with :data:`oracles.DRAWN` set, so every case
:func:`oracles.cases` builds is recorded, and prints per file: cases built, distinct CCR values, cases whose CCR
is 0 / has Z set, distinct D0-D7 patterns (all eight registers as one tuple), cases whose D0-D7 are all zero,
distinct A0-A7 patterns and distinct placed addresses (memory operands, jump and return targets); ``--per-test``
also per test function.
docs/testing.md, "Oracle tests: what the default profile draws", quotes its output."""

from __future__ import annotations

import sys
from collections import defaultdict

import pytest

from tests.support import oracles

DEFAULT = ["tests/isa/test_vs_m68000py.py", "tests/isa/test_vs_musashi.py"]


class Recorder:
    """Attributes every recorded case to the file of the test that drew it."""

    def __init__(self) -> None:
        self.by_file: dict[str, list[tuple]] = defaultdict(list)
        self.by_test: dict[str, list[tuple]] = defaultdict(list)

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_call(self, item: pytest.Item):
        oracles.DRAWN = []
        try:
            yield
        finally:
            self.by_file[item.path.name].extend(oracles.DRAWN)
            self.by_test[f"{item.path.name}::{getattr(item, 'originalname', item.name)}"].extend(oracles.DRAWN)
            oracles.DRAWN = None


def summary(name: str, drawn: list[tuple]) -> str:
    ccrs = {c[3] for c in drawn}
    dpat = {c[1] for c in drawn}
    apat = {c[2] for c in drawn}
    addresses = {t for c in drawn for t in c[4]}
    dzero = sum(1 for c in drawn if not any(c[1]))
    ccr0 = sum(1 for c in drawn if c[3] == 0)
    zset = sum(1 for c in drawn if c[3] & 0x04)
    return (f"{name}: {len(drawn)} cases; {len(ccrs)} distinct CCR values (CCR 0 in {ccr0}, Z set in {zset}); "
            f"{len(dpat)} distinct "
            f"D0-D7 patterns (all zero in {dzero}); {len(apat)} distinct A0-A7 patterns; {len(addresses)} distinct "
            f"placed addresses")


def main(argv: list[str]) -> int:
    rec = Recorder()
    argv = [a for a in argv if a != "--per-test"]
    args = argv or DEFAULT + ["-n", "0"]
    code = pytest.main(["-q", "-p", "no:cacheprovider", *args], plugins=[rec])
    everything = []
    if "--per-test" in sys.argv:
        for name in sorted(rec.by_test):
            print(summary(name, rec.by_test[name]))
    for name in sorted(rec.by_file):
        print(summary(name, rec.by_file[name]))
        everything += rec.by_file[name]
    print(summary("all", everything))
    return int(code)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
