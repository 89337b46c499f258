"""The test scheduling in tests/conftest.py names files that exist: a stale name would silently drop a long file
from the front of the run (issue 29: 11 of 14 names had gone stale after the package move)."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import _FIRST, _LAST, schedule_problems


def test_every_scheduled_file_exists() -> None:
    assert schedule_problems() == []
    assert len(set(_FIRST + _LAST)) == len(_FIRST + _LAST)


def test_a_stale_name_is_reported(tmp_path: Path) -> None:
    """Teeth: in a tree holding all but one of the scheduled files, exactly that one is reported."""
    names = _FIRST + _LAST
    for name in names[1:]:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    assert schedule_problems(tmp_path) == [names[0]]
