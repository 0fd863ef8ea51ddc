"""Near-misses of the reader's words (interdrive.reader.spelling): a typo gets its correction, only where the
corrected clause reads; words the reader knows, and words it never knew, get none."""

from __future__ import annotations

import pytest

from langtraj.interdrive.reader.spelling import did_you_mean, near_misses


@pytest.mark.parametrize(
    ("clause", "fixed"),
    [
        ("@2651 yeilds to @7", "@2651 yields to @7"),
        ("@3 trun left", "@3 turn left"),
        ("@3 stpos", "@3 stops"),
        ("@3 tailgaets @4", "@3 tailgates @4"),
        ("@9 bakes hard", "@9 brakes hard"),
    ],
)
def test_a_typo_gets_the_clause_that_reads(clause: str, fixed: str) -> None:
    found = did_you_mean(clause)
    assert found is not None and found[0] == fixed


@pytest.mark.parametrize(
    "clause", ["@9 slows down", "@3 honks at @4", "@5 drives aggressively", "@5 hesitates at the junction"]
)
def test_no_correction_for_read_clauses_or_words_the_reader_never_knew(clause: str) -> None:
    assert did_you_mean(clause) is None


def test_short_words_and_other_first_letters_are_never_typos() -> None:
    assert near_misses("@3 trun left") == [("trun", "turn")]  # not "outrun": another first letter
    assert near_misses("@3 at to the") == []
