"""Scenario suites: YAML lists of test cases (scene, ego, prompts for the other agents, seeds, pass criteria) a
planner drives through in the LangTraj environment, with results, a Markdown report and JUnit XML for CI
(`langtraj test`; docs/testing.md, 'Scenario suites'). A case is a `langtraj.cases.Case`."""

from langtraj.suites.config import Suite, load_suite
from langtraj.suites.episode import EpisodeResult, EpisodeTask, run_episode
from langtraj.suites.runner import RunOptions, check_run, run_suite

__all__ = [
    "EpisodeResult",
    "EpisodeTask",
    "RunOptions",
    "Suite",
    "check_run",
    "load_suite",
    "run_episode",
    "run_suite",
]
