"""Damage to a text file, drawn by hypothesis: the fuzz tests of the readers share it (tests/flights/
test_formats.py, test_hobby_formats.py, test_altos_eeprom.py)."""

from __future__ import annotations

from hypothesis import strategies as st


def damaged(data: st.DataObject, text: str, replace_chars: str, insert_alphabet: str) -> str:
    """``text`` after 1-4 drawn edits: a character replaced (by one of ``replace_chars``), up to 6 characters of
    ``insert_alphabet`` inserted, 1-30 characters deleted, the text cut, or a line duplicated."""
    for _ in range(data.draw(st.integers(1, 4))):
        op = data.draw(st.sampled_from(["replace", "insert", "delete", "cut", "dup"]))
        i = data.draw(st.integers(0, max(0, len(text) - 1)))
        if op == "replace":
            text = text[:i] + data.draw(st.sampled_from(list(replace_chars))) + text[i + 1:]
        elif op == "insert":
            text = text[:i] + data.draw(st.text(insert_alphabet, max_size=6)) + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + data.draw(st.integers(1, 30)):]
        elif op == "cut":
            text = text[:i]
        else:
            lines = text.splitlines(keepends=True)
            j = data.draw(st.integers(0, max(0, len(lines) - 1)))
            text = "".join(lines[:j + 1] + lines[j:])
    return text
