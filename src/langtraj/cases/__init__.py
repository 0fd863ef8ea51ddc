"""A test case of a planner, defined once below the env, the suites and the studio: `Case` and its `Criteria`,
read by `read_case` and written by `case_json` (docs/testing.md, 'Cases')."""

from langtraj.cases.case import ADVERSARY_PLACEHOLDER, EGO_PLACEHOLDER, EPISODE_STEPS, NAME, Case, Criteria
from langtraj.cases.io import CASE_KEYS, case_json, read_case

__all__ = [
    "ADVERSARY_PLACEHOLDER",
    "CASE_KEYS",
    "EGO_PLACEHOLDER",
    "EPISODE_STEPS",
    "NAME",
    "Case",
    "Criteria",
    "case_json",
    "read_case",
]
