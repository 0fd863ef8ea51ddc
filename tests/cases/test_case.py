"""`Case`'s one reader and one writer: every key read and checked with a one-line error naming it, defaults taken key
by key, `@adv` replaced, and what the writer writes read back to the same case."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_builders import make_scenario

from langtraj.cases import CASE_KEYS, Case, Criteria, case_json, read_case
from langtraj.cases.io import _READERS
from langtraj.errors import InputError


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "scene.tfrecord"
    path.write_bytes(b"")
    return path


def test_every_field_of_a_case_has_a_reader_and_the_writer_writes_them_in_order():
    assert set(_READERS) == set(CASE_KEYS)
    assert list(case_json(Case(scenario=Path("x")))) == list(CASE_KEYS)


def test_a_case_read_back_from_what_the_writer_wrote_is_the_same_case(scene: Path):
    case = Case(
        scenario=scene,
        index=2,
        window=1,
        ego=5,
        prompts=("@7 brakes hard",),
        adversary=7,
        target="ego",
        seeds=(0, 3),
        checkpoint=scene,
        criteria=Criteria(min_ttc=0.5, no_collision=True),
        max_steps=40,
        name="brake",
    )
    for compact in (False, True):
        assert read_case(case_json(case, compact=compact)) == case


def test_compact_leaves_out_defaults_but_keeps_what_a_suite_default_would_replace(scene: Path):
    written = case_json(Case(scenario=scene, name="a", criteria=Criteria(min_ttc=1.0)), compact=True)
    assert written == {"scenario": str(scene), "seeds": [0], "criteria": {"min_ttc": 1.0}, "name": "a"}


def test_defaults_fill_what_is_left_out_criteria_key_by_key(scene: Path, tmp_path: Path):
    given = {"seeds": 2, "criteria": {"min_ttc": 0.5}, "max_steps": 30}
    defaults = read_case(given, keys=("seeds", "criteria", "max_steps"))
    data = {"scenario": "scene.tfrecord", "criteria": {"no_collision": True}}
    case = read_case(data, defaults=defaults, base=tmp_path)
    assert case.scenario == scene and case.seeds == (0, 1) and case.max_steps == 30 and case.steps == 30
    assert (case.criteria.min_ttc, case.criteria.no_collision) == (0.5, True)
    assert read_case({"max_steps": None}, defaults=defaults).max_steps is None  # null: None where None means something
    assert read_case({"seeds": None}, defaults=defaults).seeds == (0, 1)  # null: the default elsewhere


def test_adv_in_a_prompt_is_the_adversary_and_one_text_is_one_prompt():
    case = read_case({"prompts": ["@adv cuts in front of @ego"], "adversary": 12, "target": "ego"})
    assert case.prompts == ("@12 cuts in front of @ego",)
    assert read_case({"prompts": "@3 stops"}).prompts == ("@3 stops",)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"scenario": "missing.tfrecord"}, "c.scenario: no such file"),
        ({"scenario": "${NO_SUCH_VARIABLE_Y}/a"}, "c.scenario: the environment variable NO_SUCH_VARIABLE_Y"),
        ({"index": -1}, "c.index: must be >= 0"),
        ({"window": 1.5}, "c.window: expected a whole number"),
        ({"ego": "car"}, "c.ego: expected a track id"),
        ({"target": "bus", "adversary": 1}, "c.target: expected a track id or 'ego'"),
        ({"adversary": 1}, "c.target: an adversary needs a target"),
        ({"ego": 4, "adversary": 4, "target": 5}, "c.adversary: @4 is the ego"),
        ({"prompts": ["  "]}, "c.prompts[0]: expected non-empty text"),
        ({"prompts": ["@adv stops"]}, "c.prompts[0]: '@adv' needs the case's adversary"),
        ({"seeds": [1, 1]}, "c.seeds: repeated seeds"),
        ({"seeds": 0}, "c.seeds: a count of seeds must be >= 1"),
        ({"criteria": {"min_ttc": -1}}, "c.criteria.min_ttc: must be >= 0"),
        ({"criteria": {"colour": 1}}, "c.criteria"),
        ({"max_steps": 81}, "c.max_steps: must be at most 80"),
        ({"name": "../x"}, "c.name: expected a name"),
        ({"colour": "red"}, "c: unknown keys colour"),
    ],
)
def test_each_mistake_is_one_error_naming_the_key(data, message, tmp_path: Path):
    with pytest.raises(InputError) as raised:
        read_case(data, where="c", base=tmp_path, variables={})
    assert message in str(raised.value) and "\n" not in str(raised.value)


def test_keys_and_required_keys_are_the_callers(scene: Path):
    with pytest.raises(InputError, match="options: unknown keys seeds"):
        read_case({"seeds": 2}, where="options", keys=("ego",))
    with pytest.raises(InputError, match="cases\\[0\\]: missing scenario"):
        read_case({"name": "a"}, where="cases[0]", required=("name", "scenario"))


def test_a_scene_in_memory_is_read_but_not_written():
    scenario = make_scenario()
    case = read_case({"scenario": scenario})
    assert case.scenario is scenario
    with pytest.raises(InputError, match="scenario: a case whose scene is in memory cannot be written"):
        case_json(case)
