"""The suite file: what it reads, its defaults, and one-line errors naming the file and the key."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from langtraj.cases import Criteria
from langtraj.errors import InputError
from langtraj.suites import load_suite
from langtraj.suites.config import real_data_folder
from suites.conftest import write_suite

REPO = Path(__file__).resolve().parents[2]


def _suite(tmp_path: Path, body: str) -> Path:
    (tmp_path / "scene.tfrecord").write_bytes(b"")
    path = tmp_path / "suite.yaml"
    path.write_text(textwrap.dedent(body))
    return path


def test_reads_cases_with_defaults_and_placeholders(tmp_path, monkeypatch):
    monkeypatch.setenv("SCENES", str(tmp_path))
    path = _suite(
        tmp_path,
        """
        name: smoke
        defaults:
          seeds: 2
          criteria: {min_ttc: 0.5}
          max_steps: 20
        cases:
          - name: plain
            scenario: scene.tfrecord
          - name: cut-in
            scenario: ${SCENES}/scene.tfrecord
            index: 0
            prompts: ["@adv changes lanes into @ego's lane and brakes hard"]
            adversary: 12
            target: ego
            seeds: [3, 5]
            max_steps: null
            criteria: {no_collision: true, min_progress: 0.2, terminate_on_collision: false}
        """,
    )
    suite = load_suite(path)
    assert suite.name == "smoke" and suite.episodes == 4
    plain, cut_in = suite.cases
    assert plain.scenario == tmp_path / "scene.tfrecord" and plain.seeds == (0, 1) and plain.ego is None
    assert plain.criteria == Criteria(min_ttc=0.5) and plain.max_steps == 20
    assert cut_in.prompts == ("@12 changes lanes into @ego's lane and brakes hard",)  # the env fills in @ego
    assert (cut_in.adversary, cut_in.target, cut_in.seeds, cut_in.max_steps) == (12, "ego", (3, 5), None)
    assert cut_in.criteria == Criteria(no_collision=True, min_ttc=0.5, min_progress=0.2, terminate_on_collision=False)
    assert [c.seeds for c in suite.with_seeds(3).cases] == [(0, 1, 2), (0, 1, 2)]
    (only,) = suite.only([cut_in.name]).cases
    assert only == cut_in and suite.only([cut_in.name]).source(0) == suite.source(1)
    with pytest.raises(InputError, match=r"^cases: no case nope in "):
        suite.only([cut_in.name, "nope"])


def test_the_real_data_folder_is_the_one_given_else_the_variable_else_beside_the_working_directory(
    tmp_path, monkeypatch
):
    """Never the installed package's location: an installed LangTraj has no checkout beside it."""
    monkeypatch.delenv("LANGTRAJ_REAL_DATA", raising=False)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    path = _suite(tmp_path, "name: s\ncases:\n  - {name: a, scenario: '${LANGTRAJ_REAL_DATA}/scene.tfrecord'}\n")
    missing = re.escape(str(tmp_path / "shared" / "data" / "real" / "scene.tfrecord"))
    with pytest.raises(InputError, match=rf"cases\[0\]\.scenario: no such file: {missing}"):
        load_suite(path)  # ../shared/data/real under the working directory
    assert load_suite(path, real_data=tmp_path).cases[0].scenario == tmp_path / "scene.tfrecord"
    monkeypatch.setenv("LANGTRAJ_REAL_DATA", str(tmp_path))
    assert load_suite(path).cases[0].scenario == tmp_path / "scene.tfrecord"
    assert real_data_folder(work) == work  # given beats the variable


@pytest.mark.parametrize(
    ("cases", "message"),
    [
        ("  - {name: a, scenario: scene.tfrecord, criteria: {min_ttc: -1}}", "cases[0].criteria.min_ttc: must be >= 0"),
        ("  - {name: a, scenario: scene.tfrecord, criteria: {min_ttc: fast}}", "cases[0].criteria.min_ttc: expected"),
        (
            "  - {name: a, scenario: scene.tfrecord, criteria: {no_crash: true}}",
            "cases[0].criteria: unknown keys no_crash",
        ),
        ("  - {name: a, scenario: scene.tfrecord}\n  - {name: a, scenario: scene.tfrecord}", "cases[1].name: 'a' is"),
        ("  - {name: a, scenario: missing.pkl}", "cases[0].scenario: no such file"),
        ("  - {name: a}", "cases[0]: missing scenario"),
        ("  - {name: 'a b', scenario: scene.tfrecord}", "cases[0].name: expected a name"),
        ("  - {name: a, scenario: scene.tfrecord, seeds: 0}", "cases[0].seeds: a count of seeds must be >= 1"),
        ("  - {name: a, scenario: scene.tfrecord, seeds: [1, 1]}", "cases[0].seeds: repeated seeds"),
        ("  - {name: a, scenario: scene.tfrecord, seeds: [x]}", "cases[0].seeds[0]: expected a whole number"),
        ("  - {name: a, scenario: scene.tfrecord, index: -1}", "cases[0].index: must be >= 0"),
        ("  - {name: a, scenario: scene.tfrecord, window: -2}", "cases[0].window: must be >= 0"),
        ("  - {name: a, scenario: scene.tfrecord, ego: car}", "cases[0].ego: expected a track id"),
        ("  - {name: a, scenario: scene.tfrecord, adversary: 3}", "cases[0].target: an adversary needs a target"),
        ("  - {name: a, scenario: scene.tfrecord, adversary: 3, target: 3}", "cases[0].target: the adversary and the"),
        ("  - {name: a, scenario: scene.tfrecord, target: bus, adversary: 3}", "cases[0].target: expected a track id"),
        (
            "  - {name: a, scenario: scene.tfrecord, ego: 3, adversary: 3, target: 4}",
            "cases[0].adversary: @3 is the ego",
        ),
        ("  - {name: a, scenario: scene.tfrecord, prompts: ['@adv brakes']}", "cases[0].prompts[0]: '@adv' needs"),
        ("  - {name: a, scenario: scene.tfrecord, prompts: {a: 1}}", "cases[0].prompts: expected a list"),
        ("  - {name: a, scenario: scene.tfrecord, max_steps: 81}", "cases[0].max_steps: must be at most 80"),
        ("  - {name: a, scenario: scene.tfrecord, colour: red}", "cases[0]: unknown keys colour"),
        (
            "  - {name: a, scenario: '${NO_SUCH_VARIABLE_X}/a'}",
            "cases[0].scenario: ${NO_SUCH_VARIABLE_X} is not a sweep parameter of this case (it has no sweep) nor an "
            "environment variable",
        ),
        (
            "  - {name: a, scenario: scene.tfrecord, prompts: ['@5 brakes at ${NO_SUCH_VARIABLE_X}']}",
            "cases[0].prompts[0]: ${NO_SUCH_VARIABLE_X} is not a sweep parameter",
        ),
        (
            "  - {name: a, scenario: scene.tfrecord, sweeps: {gap: [5]}}",
            "cases[0]: unknown keys sweeps (did you mean sweep?); known: scenario, index, window, ego, prompts, "
            "adversary, target, seeds, checkpoint, criteria, max_steps, name, sweep",
        ),
        ("  - 3", "cases[0]: expected a mapping"),
        ("  []", "cases: expected a non-empty list"),
    ],
)
def test_errors_name_the_file_and_key(tmp_path, cases, message):
    path = _suite(
        tmp_path, f"name: s\ncases:\n{cases}\n" if not cases.strip().startswith("[") else "name: s\ncases: []\n"
    )
    with pytest.raises(InputError) as raised:
        load_suite(path)
    text = str(raised.value)
    assert text.startswith(f"{path}: "), text
    assert message in text and "\n" not in text, text


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("cases: [{name: a, scenario: scene.tfrecord}]", "name: expected a name"),
        (
            "name: s\ndefaults: {criteria: {min_progress: -0.5}}\ncases: [{name: a, scenario: s}]",
            "defaults.criteria.min_progress: must be >= 0",
        ),
        (
            "name: s\ndefaults: {seed: 3}\ncases: [{name: a, scenario: scene.tfrecord}]",
            "defaults: unknown keys seed (did you mean seeds?); known: seeds, criteria, checkpoint, max_steps",
        ),
        (
            "name: s\ndefaults: {checkpoint: '${NO_SUCH_VARIABLE_X}/m.pt'}\ncases: [{name: a, scenario: s}]",
            "defaults.checkpoint: ${NO_SUCH_VARIABLE_X} is not an environment variable",
        ),
        ("name: s\ncolour: red\ncases: [{name: a, scenario: scene.tfrecord}]", "unknown keys colour"),
        ("name: s\ncases: [{name: a, scenario: scene.tfrecord]", "not valid YAML"),
    ],
)
def test_suite_level_errors(tmp_path, body, message):
    path = _suite(tmp_path, body)
    with pytest.raises(InputError, match="^" + re.escape(str(path)) + ": .*" + re.escape(message)):
        load_suite(path)


def test_the_example_suite_loads(monkeypatch):
    monkeypatch.delenv("LANGTRAJ_REAL_DATA", raising=False)
    monkeypatch.chdir(REPO)  # as the README's commands run
    if not (real_data_folder() / "motion_data_one_scenario.tfrecord").is_file():
        pytest.skip(f"real scenario files not found in {real_data_folder()}")
    suite = load_suite(REPO / "configs" / "suites" / "example.yaml")
    assert len(suite.cases) >= 4 and suite.episodes >= len(suite.cases)
    assert all(c.scenario.is_file() for c in suite.cases)


def test_a_case_names_a_window_of_a_longer_scene(tmp_path):
    suite = load_suite(_suite(tmp_path, "name: s\ncases:\n  - {name: a, scenario: scene.tfrecord, window: 2}\n"))
    assert suite.cases[0].window == 2
    assert (
        load_suite(_suite(tmp_path, "name: s\ncases:\n  - {name: a, scenario: scene.tfrecord}\n")).cases[0].window
        is None
    )


def test_a_sweep_expands_a_case_into_one_per_combination_of_its_parameters(tmp_path):
    (tmp_path / "scene.pkl").write_bytes(b"x")
    path = write_suite(
        tmp_path,
        [
            {
                "name": "cut-in",
                "scenario": "scene.pkl",
                "prompts": ["@52 cuts in front of @ego with a ${gap_m} m gap"],
                "criteria": {"min_ttc": "${ttc}"},
                "sweep": {"gap_m": [5, 10], "ttc": [1.0, 1.5]},
            },
            {"name": "plain", "scenario": "scene.pkl"},
        ],
    )
    cases = load_suite(path).cases
    assert [c.name for c in cases] == [
        "cut-in.gap_m-5.ttc-1.0", "cut-in.gap_m-5.ttc-1.5", "cut-in.gap_m-10.ttc-1.0", "cut-in.gap_m-10.ttc-1.5",
        "plain",
    ]  # fmt: skip
    assert cases[2].prompts == ("@52 cuts in front of @ego with a 10 m gap",) and cases[3].criteria.min_ttc == 1.5
    for sweep, message in (
        ({"gap_m": []}, "cases[0].sweep.gap_m: expected a non-empty list"),
        ({"gap-m": [1]}, "cases[0].sweep.gap-m: expected a parameter name"),
        ({"gap_m": [5, 5]}, "cases[0].sweep.gap_m: the same value twice"),
    ):
        bad = write_suite(tmp_path, [{"name": "c", "scenario": "scene.pkl", "sweep": sweep}])
        with pytest.raises(InputError, match=re.escape(message)):
            load_suite(bad)


def test_a_placeholder_neither_swept_nor_set_is_an_error_naming_the_key(tmp_path, monkeypatch):
    """A mistyped `${gapp}` would run every variant of the sweep alike, the prompt read with the text as it stands."""
    monkeypatch.delenv("gapp", raising=False)
    (tmp_path / "scene.pkl").write_bytes(b"x")
    plain = {"name": "plain", "scenario": "scene.pkl"}
    cut_in = {"name": "cut-in", "scenario": "scene.pkl", "sweep": {"gap": [5, 10]}}
    for case, message in (
        (
            {**cut_in, "prompts": ["@52 cuts in front of @ego with a ${gapp} m gap"]},
            "cases[1].prompts[0]: ${gapp} is not a sweep parameter of this case (its parameters: gap) nor an "
            "environment variable; did you mean ${gap}?",
        ),
        (
            {**cut_in, "prompts": ["@52 cuts in with a ${gap} m gap"], "criteria": {"min_ttc": "${ttc}"}},
            "cases[1].criteria.min_ttc: ${ttc} is not a sweep parameter of this case (its parameters: gap) nor an "
            "environment variable",
        ),
        ({**cut_in, "name": "cut-in-${gap m}"}, "cases[1].name: ${gap m} is not a sweep parameter"),
        ({**plain, "name": "p2", "prompts": ["@5 brakes ${gap}"]}, "cases[1].prompts[0]: ${gap} is not a sweep"),
    ):
        path = write_suite(tmp_path, [plain, case])
        with pytest.raises(InputError) as raised:
            load_suite(path)
        text = str(raised.value)
        assert text.startswith(f"{path}: {message}") and "\n" not in text, text


def test_environment_variables_are_replaced_in_every_text_and_sweep_parameters_first(tmp_path, monkeypatch):
    monkeypatch.setenv("LEAD", "@738")
    monkeypatch.setenv("gap", "99")
    monkeypatch.setenv("SCENES", str(tmp_path))
    (tmp_path / "scene.pkl").write_bytes(b"x")
    cases = [
        {"name": "a", "scenario": "${SCENES}/scene.pkl", "prompts": ["${LEAD} slows down"]},
        {"name": "b", "scenario": "scene.pkl", "prompts": ["${LEAD} keeps a ${gap} m gap"], "sweep": {"gap": [5]}},
    ]
    a, b = load_suite(write_suite(tmp_path, cases)).cases
    assert a.prompts == ("@738 slows down",) and a.scenario == tmp_path / "scene.pkl"
    assert b.prompts == ("@738 keeps a 5 m gap",) and b.name == "b.gap-5"
