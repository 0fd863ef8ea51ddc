"""InterDrive prompts: template grammar, phrase tables over the whole taxonomy, compositional prompts,
role rephrasing, user prompt validation, prompt pools and the LLM backend against a fake local server."""

from __future__ import annotations

import json
import re
import socket
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np
import pytest

from langtraj.errors import InputError, LangTrajError
from langtraj.interdrive.labels import AgentLabel, InteractionLabel, LabelSource, WindowLabels
from langtraj.interdrive.prompts import (
    CANONICAL,
    LLMConfig,
    LLMError,
    LLMRephraser,
    Prompt,
    build_prompt_pool,
    compose_prompt,
    expand,
    interaction_phrases,
    label_phrases,
    label_variants,
    parse_user_prompt,
    phrase_key,
    role_rephrase,
    sample,
)
from langtraj.interdrive.taxonomy import (
    ADDED_SUBTYPES,
    LANE_POSITIONS,
    SINGLE_AGENT_LABELS,
    SUBTYPES,
    SUBTYPES_BY_ID,
    InteractionType,
)

MIN_PHRASES = 20

# ---------------------------------------------------------------- grammar


def test_expand_alternatives_optional_nesting_and_slots() -> None:
    assert expand("{speeds up|accelerates}[ {gradually|steadily}]") == [
        "speeds up",
        "speeds up gradually",
        "speeds up steadily",
        "accelerates",
        "accelerates gradually",
        "accelerates steadily",
    ]
    assert expand("yields to <other> at the {intersection|junction}") == [
        "yields to <other> at the intersection",
        "yields to <other> at the junction",
    ]
    assert expand("{a|{b|c [d]}}") == ["a", "b", "c", "c d"]


def test_expand_dedupes_normalises_whitespace_and_escapes() -> None:
    assert expand("  {go|go}   [ ] on ,{| x}") == ["go on,", "go on, x"]
    assert expand("{a|}") == ["a"]  # empty expansions are dropped
    assert expand(r"\{x\|y\} \<z\> \\") == ["{x|y} <z> \\"]


@pytest.mark.parametrize(
    ("template", "message"),
    [
        ("{a|b", "unclosed '{' at position 0"),
        ("ab [c", "unclosed '[' at position 3"),
        ("a]", "unexpected ']' at position 1"),
        ("a}", "unexpected '}' at position 1"),
        ("a|b", "unexpected '|' at position 1"),
        ("[a|b]", "unexpected '|' at position 2"),
        ("{a]}", "unexpected ']' at position 2"),
        ("to <1x> now", "bad slot name '1x' at position 3"),
        ("to <other", "unclosed '<' at position 3"),
        ("a > b", "unexpected '>' outside a slot at position 2"),
        ("a\\", "dangling escape"),
    ],
)
def test_parse_errors_name_template_and_position(template: str, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)) as info:
        expand(template)
    assert repr(template) in str(info.value)


def test_expansion_limit() -> None:
    with pytest.raises(ValueError, match="limit"):
        expand("{a|b}" * 17)


def test_sample_is_deterministic_and_covers_every_expansion() -> None:
    template = "{slows|speeds} {up|down}[ now]"
    draws = [sample(template, np.random.default_rng(3)) for _ in range(3)]
    assert len(set(draws)) == 1
    rng = np.random.default_rng(0)
    seen = {sample(template, rng) for _ in range(400)}
    assert seen == set(expand(template))


# ---------------------------------------------------------------- phrase tables


def _label_cases() -> list[tuple[str, dict[str, str]]]:
    """Every label and parameter value, from the taxonomy (a new parameterised label fails here)."""
    cases: list[tuple[str, dict[str, str]]] = []
    lanes = [p for p in LANE_POSITIONS if p != "single"]
    for definition in SINGLE_AGENT_LABELS:
        if not definition.params:
            cases.append((definition.key, {}))
        elif definition.key == "lane_position":
            cases += [(definition.key, {"position": p}) for p in LANE_POSITIONS]
        elif definition.key == "changing_lanes":
            cases += [(definition.key, {"from": a, "to": b}) for a in lanes for b in lanes if a != b]
        else:
            pytest.fail(f"no phrase test for parameterised label {definition.key!r}")
    return cases


def _check_phrase_shape(phrase: str) -> None:
    assert phrase == phrase.strip() and "  " not in phrase
    assert phrase[0].islower(), phrase
    assert ", then" not in phrase and "@" not in phrase
    assert not re.search(r"\ban [^aeiou\W]|\ba [aei]", phrase), phrase  # "an junction", "a intersection"


@pytest.mark.parametrize(("key", "params"), _label_cases(), ids=lambda v: str(v))
def test_every_label_has_enough_rephrasings(key: str, params: dict[str, str]) -> None:
    phrases = label_phrases(key, params)
    assert len(set(phrases)) == len(phrases) >= MIN_PHRASES
    for phrase in phrases:
        _check_phrase_shape(phrase)
        assert "<" not in phrase
    assert CANONICAL[phrase_key(key, params)] == phrases[0]


@pytest.mark.parametrize("subtype_id", [s.id for s in SUBTYPES])
def test_every_subtype_has_enough_rephrasings(subtype_id: str) -> None:
    phrases = interaction_phrases(subtype_id)
    assert len(set(phrases)) == len(phrases) >= MIN_PHRASES
    alone = subtype_id in ("other/no_interaction", "other/unknown")
    for phrase in phrases:
        _check_phrase_shape(phrase)
        assert set(re.findall(r"<[^>]*>", phrase)) == (set() if alone else {"<other>"}), phrase
    assert CANONICAL[subtype_id] == phrases[0]


def test_label_variants_cover_the_taxonomy() -> None:
    assert [(k, dict(p)) for k, p in label_variants()] == _label_cases()


def test_lane_change_phrases_name_the_lanes() -> None:
    phrases = label_phrases("changing_lanes", {"from": "middle", "to": "rightmost"})
    assert "changes lanes from the middle to the rightmost lane" in phrases
    assert all("right" in p for p in phrases)
    assert not any("left" in p for p in phrases)
    generic = label_phrases("changing_lanes", {"from": "single", "to": "middle"})  # no direction: plain lane change
    assert generic[0] == CANONICAL["changing_lanes"] == "changes lanes"


def test_pulling_over_renders_with_its_phrases_and_reads_back() -> None:
    from langtraj.interdrive.prompts.user import recognize_prompt

    phrases = label_phrases("pulling_over")
    assert phrases[0] == CANONICAL["pulling_over"] == "pulls over and stops"
    assert {"pulls over to the curb and stops", "is pulling over to stop"} <= set(phrases)
    assert all("pull" in p or (("stop" in p or "halt" in p) and ("curb" in p or "side" in p)) for p in phrases)
    labels = [AgentLabel(12, "slowing_down", 10, 50), AgentLabel(12, "pulling_over", 60, 91)]
    for seed in range(6):
        prompt = compose_prompt(12, None, labels, np.random.default_rng(seed))
        assert prompt.label_keys == ("slowing_down", "pulling_over")
        first, second = _split(prompt.text, ", then ")
        assert first[4:] in label_phrases("slowing_down") and second in phrases
        assert not second.startswith("is ")  # "then pulls over", not "then is pulling over"
        assert set(recognize_prompt(Prompt(prompt.text, (12,))).label_keys) == {"slowing_down", "pulling_over"}
    alone = compose_prompt(12, None, labels[1:], np.random.default_rng(0))
    assert alone.text[4:] in phrases and alone.label_keys == ("pulling_over",)
    user = parse_user_prompt("@12 pulls over and stops", [7, 12])
    assert recognize_prompt(user).label_keys == ("pulling_over",)


def test_unknown_keys_raise_input_error_listing_known() -> None:
    with pytest.raises(InputError, match="unknown single-agent label 'flying'; known: parked, "):
        label_phrases("flying")
    with pytest.raises(InputError, match="unknown interaction subtype 'yielding/nope'; known: lane_change/"):
        interaction_phrases("yielding/nope")
    with pytest.raises(InputError, match="position must be one of"):
        label_phrases("lane_position", {"position": "up"})
    with pytest.raises(InputError, match="takes parameters"):
        label_phrases("changing_lanes", {"from": "middle"})


# ---------------------------------------------------------------- composition


def _interaction(sub: str, track: int = 12, other: int = 7, start: int = 0, end: int = 20) -> InteractionLabel:
    return InteractionLabel(track, other, SUBTYPES_BY_ID[sub], LabelSource.DETECTOR, start, end)


def _split(text: str, *seps: str) -> list[str]:
    parts = [text]
    for sep in seps:
        head, _, tail = parts.pop().partition(sep)
        assert tail, f"{sep!r} not in {text!r}"
        parts += [head, tail]
    return parts


@pytest.mark.parametrize("seed", range(8))
def test_compose_orders_by_start_and_joins_with_then_and_and(seed: int) -> None:
    labels = [AgentLabel(12, "turning_left", 30, 40), AgentLabel(12, "speeding_up", 25, 40)]
    prompt = compose_prompt(12, _interaction("yielding/intersection"), labels, np.random.default_rng(seed))
    assert prompt.mentions == (12, 7)
    assert prompt.subtype_id == "yielding/intersection" and prompt.source == "detector"
    assert prompt.label_keys == ("speeding_up", "turning_left")
    head, second, third = _split(prompt.text, ", then ", " and ")
    assert head.startswith("@12 ")
    assert head[4:] in {p.replace("<other>", "@7") for p in interaction_phrases("yielding/intersection")}
    assert second in label_phrases("speeding_up") and not second.startswith("is ")  # no "then is speeding up"
    assert third in label_phrases("turning_left")


def test_compose_labels_only_and_overlaps() -> None:
    labels = [
        AgentLabel(12, "changing_lanes", 10, 30, {"from": "middle", "to": "rightmost"}),
        AgentLabel(12, "slowing_down", 0, 20),
        AgentLabel(12, "going_straight", 40, 60),
        AgentLabel(12, "constant_speed", 45, 60),
        AgentLabel(12, "static", 70, 80),
    ]
    prompt = compose_prompt(12, None, labels, np.random.default_rng(1), max_labels=5)
    assert prompt.mentions == (12,) and prompt.subtype_id is None and prompt.source == "heuristic"
    assert prompt.label_keys == ("slowing_down", "changing_lanes", "going_straight", "constant_speed", "static")
    first, second, third = prompt.text.split(", then ")
    assert first.count(" and ") == 1 and second.count(" and ") == 1 and " and " not in third


def test_compose_max_labels_picks_a_subset_in_start_order() -> None:
    keys = ["parked", "static", "off_main_road", "lane_position", "moving_slowly"]
    labels = [
        AgentLabel(3, k, 50 - 10 * i, 60, {"position": "single"} if k == "lane_position" else {})
        for i, k in enumerate(keys)
    ]
    for seed in range(5):
        prompt = compose_prompt(3, None, labels, np.random.default_rng(seed))
        assert len(prompt.label_keys) == 3
        starts = [next(lab.start for lab in labels if lab.key == k) for k in prompt.label_keys]
        assert starts == sorted(starts)


def test_compose_without_other_agent_and_no_interaction() -> None:
    rng = np.random.default_rng(0)
    solo = compose_prompt(12, _interaction("lane_change/for_turn_or_exit", other=-1), [], rng)
    assert "another road user" in solo.text and solo.mentions == (12,)
    none = compose_prompt(12, _interaction("other/no_interaction", other=-1), [AgentLabel(12, "parked", 0, 5)], rng)
    assert none.subtype_id == "other/no_interaction" and none.label_keys == ("parked",)


def test_compose_errors() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="nothing to describe for track 12"):
        compose_prompt(12, None, [], rng)
    with pytest.raises(InputError, match="label 'parked' of track 3 given for track 12"):
        compose_prompt(12, None, [AgentLabel(3, "parked", 0, 5)], rng)
    with pytest.raises(InputError, match="interaction of track 12 given for track 7"):
        compose_prompt(7, _interaction("yielding/intersection"), [], rng)


def test_prompt_mentions_must_match_text() -> None:
    with pytest.raises(ValueError, match="do not match"):
        Prompt("@12 yields to @7", (7, 12))


def test_role_rephrase_one_agent() -> None:
    assert role_rephrase(Prompt("@12 slows down and turns left", (12,))) == {
        12: "the target agent slows down and turns left"
    }


def test_role_rephrase_two_agents() -> None:
    prompt = Prompt("@12 yields to @7 at the intersection, then speeds up and turns left", (12, 7))
    assert role_rephrase(prompt) == {
        12: "the target agent yields to other agent1 at the intersection, then speeds up and turns left",
        7: "other agent1 yields to the target agent at the intersection, then speeds up and turns left",
    }


def test_role_rephrase_three_agents() -> None:
    prompt = Prompt("@12 yields to @7 at the junction, then follows @3 while @7 waits for @12", (12, 7, 3))
    assert role_rephrase(prompt) == {
        12: "the target agent yields to other agent1 at the junction, then follows other agent2 while other agent1"
        " waits for the target agent",
        7: "other agent1 yields to the target agent at the junction, then follows other agent2 while the target agent"
        " waits for other agent1",
        3: "other agent1 yields to other agent2 at the junction, then follows the target agent while other agent2"
        " waits for other agent1",
    }


def test_role_rephrase_of_a_composed_prompt() -> None:
    prompt = compose_prompt(1, _interaction("following/tailgating", 1, 10), [], np.random.default_rng(0))
    sentences = role_rephrase(prompt)
    assert list(sentences) == [1, 10]
    assert sentences[1].startswith("the target agent ") and "other agent1" in sentences[1]
    assert sentences[10].startswith("other agent1 ") and "the target agent" in sentences[10]


# ---------------------------------------------------------------- user prompts

IDS = [3, 7, 12]


def test_user_prompt_ok() -> None:
    prompt = parse_user_prompt("  @12  yields to\n@007 at the junction ", IDS)
    assert prompt == Prompt("@12 yields to @7 at the junction", (12, 7), source="user")
    assert role_rephrase(prompt)[7] == "other agent1 yields to the target agent at the junction"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty prompt"),
        (" \n\t ", "empty prompt"),
        ("@12 " + "a" * 297, "prompt is 301 characters long; the limit is 300"),
        ("the car yields", "prompt mentions no agent"),
        ("NaN", "prompt mentions no agent"),
        ("@12", "describes no behaviour"),
        ("@12 nan", "describes no behaviour"),
        ("@12 None, @7 null", "describes no behaviour"),
        ("@ stops", "malformed agent mention '@' at position 0"),
        ("@12 follows @x1", "malformed agent mention '@x1' at position 12"),
        ("@12abc stops", "malformed agent mention '@12abc'"),
        ("car@12 stops", "malformed agent mention"),
        ("@12 stops\x00", "control or invisible character '\\x00' at position 9"),
        ("@12 st\u200bops", "control or invisible character"),
        ("@99 yields to @12", "unknown agent @99; the scene has agents 3, 7, 12"),
        ("@99 yields to @98", "unknown agents @99, @98; the scene has agents 3, 7, 12"),
    ],
)
def test_user_prompt_errors(text: str, message: str) -> None:
    with pytest.raises(InputError, match=re.escape(message)):
        parse_user_prompt(text, IDS)


def test_user_prompt_unknown_id_abbreviates_many_ids() -> None:
    with pytest.raises(
        InputError, match=re.escape("the scene has agents 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, ... (250 in all)")
    ):
        parse_user_prompt("@999 stops", range(250))
    with pytest.raises(InputError, match="the scene has no agents"):
        parse_user_prompt("@1 stops", [])


def test_user_prompt_custom_limit() -> None:
    with pytest.raises(InputError, match="12 characters long; the limit is 10"):
        parse_user_prompt("@12 stops no", IDS, max_chars=10)


# ---------------------------------------------------------------- pools


def _window() -> WindowLabels:
    return WindowLabels(
        "scene-1",
        agent_labels=(
            AgentLabel(12, "slowing_down", 0, 10),
            AgentLabel(12, "changing_lanes", 5, 20, {"from": "middle", "to": "rightmost"}),
            AgentLabel(12, "turning_left", 25, 40),
            AgentLabel(12, "lane_position", 0, 40, {"position": "rightmost"}),
            AgentLabel(3, "static", 0, 90),
            AgentLabel(7, "going_straight", 0, 90),
        ),
        interactions=(
            _interaction("yielding/intersection"),
            InteractionLabel(
                7, 12, SUBTYPES_BY_ID["passing/intersection_with_yielding"], LabelSource.GROUND_TRUTH, 0, 20
            ),
            InteractionLabel(5, 3, SUBTYPES_BY_ID["other/unknown"], LabelSource.HUMAN, 0, 20),
            InteractionLabel(3, 5, SUBTYPES_BY_ID["other/unknown"], LabelSource.HUMAN, 0, 20),
        ),
    )


def test_pool_is_deterministic_and_seeded() -> None:
    first = build_prompt_pool(_window(), seed=1)
    assert first == build_prompt_pool(_window(), seed=1)
    assert [p.text for p in first] != [p.text for p in build_prompt_pool(_window(), seed=2)]


def test_pool_contents() -> None:
    pool = build_prompt_pool(_window(), seed=0, per_agent=4)
    by_agent: dict[int, list[Prompt]] = {}
    for prompt in pool:
        by_agent.setdefault(prompt.mentions[0], []).append(prompt)
    assert list(by_agent) == [3, 7, 12]  # agent 5 has only an unknown interaction and no labels
    for prompts in by_agent.values():
        assert len(prompts) == 4 and len({p.text for p in prompts}) == 4
    assert all(p.subtype_id is None and p.source == "heuristic" and p.label_keys == ("static",) for p in by_agent[3])
    assert all(p.subtype_id == "passing/intersection_with_yielding" for p in by_agent[7])
    assert all(p.source == "ground_truth" and p.mentions == (7, 12) for p in by_agent[7])
    assert all(p.subtype_id == "yielding/intersection" and p.source == "detector" for p in by_agent[12])
    assert all(len(p.label_keys) <= 3 for p in pool)
    assert not any(p.subtype_id == "other/unknown" for p in pool)


def test_pool_uses_every_interaction_of_an_agent() -> None:
    window = WindowLabels(
        "scene-2",
        interactions=(
            _interaction("yielding/intersection"),
            _interaction("following/with_lead", other=3, start=20, end=40),
        ),
    )
    pool = build_prompt_pool(window, seed=5, per_agent=2)
    assert {p.subtype_id for p in pool} == {"yielding/intersection", "following/with_lead"}
    with pytest.raises(InputError, match="per_agent"):
        build_prompt_pool(window, seed=5, per_agent=0)


# ---------------------------------------------------------------- LLM backend


class _FakeLLM:
    """A local OpenAI-compatible chat endpoint: records requests, answers `content` (or `status`/`payload`)."""

    def __init__(self) -> None:
        self.requests: list[dict[str, Any]] = []
        self.content = ""
        self.status = 200
        self.payload: Any = None
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                length = int(self.headers["Content-Length"])
                body = json.loads(self.rfile.read(length))
                fake.requests.append({"path": self.path, "headers": dict(self.headers), "body": body})
                payload = fake.payload or {"choices": [{"message": {"role": "assistant", "content": fake.content}}]}
                data = json.dumps(payload).encode()
                self.send_response(fake.status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def fake_llm(monkeypatch: pytest.MonkeyPatch) -> Iterator[_FakeLLM]:
    monkeypatch.setenv("no_proxy", "*")
    monkeypatch.setenv("NO_PROXY", "*")
    fake = _FakeLLM()
    yield fake
    fake.close()


PHRASE = "yields to <other> at the intersection"
ANSWER = "\n".join(
    [
        "1. gives way to <other> at the junction",
        "- lets <other> go first at the crossing",
        "",
        "yields at the intersection",  # lost the placeholder
        "waits for <other> and <other>",  # added one
        "stops for <other> near <b>",  # invented another
        "waits for <other> " + "x" * 250,  # overlong
        '"holds back for <other> at the intersection."',
        "yields to <other> at the intersection",  # the phrase itself
        "Gives way to <other> at the junction",  # a repeat
    ]
)
EXPECTED = (
    "gives way to <other> at the junction",
    "lets <other> go first at the crossing",
    "holds back for <other> at the intersection",
)


def test_llm_rephrases_validates_and_caches(fake_llm: _FakeLLM, tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TEST_LLM_KEY", "sk-test")
    fake_llm.content = ANSWER
    rephraser = LLMRephraser(LLMConfig(url=fake_llm.url, model="tiny", api_key_env="TEST_LLM_KEY", cache_dir=tmp_path))
    assert rephraser.rephrase(PHRASE, 5) == EXPECTED
    assert len(fake_llm.requests) == 1
    request = fake_llm.requests[0]
    assert request["path"] == "/v1/chat/completions"
    assert request["headers"]["Authorization"] == "Bearer sk-test"
    assert request["body"]["model"] == "tiny"
    assert request["body"]["messages"][-1] == {"role": "user", "content": PHRASE}
    assert "5 different rephrasings" in request["body"]["messages"][0]["content"]

    fake_llm.content = "something else entirely <other>"
    assert rephraser.rephrase(PHRASE, 5) == EXPECTED  # cache hit: no second request
    assert len(fake_llm.requests) == 1
    (cached,) = tmp_path.glob("*.json")
    assert json.loads(cached.read_text())["rephrasings"] == list(EXPECTED)

    assert rephraser.rephrase(PHRASE, 2) == ("something else entirely <other>",)  # another n: another key
    assert len(fake_llm.requests) == 2


def test_llm_trims_to_n_and_works_without_a_key(fake_llm: _FakeLLM, tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    fake_llm.content = ANSWER
    rephraser = LLMRephraser(LLMConfig(url=fake_llm.url, cache_dir=tmp_path))
    assert rephraser.rephrase(PHRASE, 2) == EXPECTED[:2]
    assert "Authorization" not in fake_llm.requests[0]["headers"]


def test_llm_errors(fake_llm: _FakeLLM, tmp_path) -> None:
    assert LLMConfig().url is None  # off by default
    with pytest.raises(LLMError, match="off"):
        LLMRephraser(LLMConfig(cache_dir=tmp_path)).rephrase(PHRASE, 3)
    assert issubclass(LLMError, LangTrajError)

    fake_llm.status = 500
    with pytest.raises(LLMError, match=re.escape(f"LLM request to {fake_llm.url}/chat/completions failed: HTTP 500")):
        LLMRephraser(LLMConfig(url=fake_llm.url, cache_dir=tmp_path)).rephrase(PHRASE, 3)

    fake_llm.status, fake_llm.payload = 200, {"error": "nope"}
    with pytest.raises(LLMError, match="is not a chat completion"):
        LLMRephraser(LLMConfig(url=fake_llm.url, cache_dir=tmp_path)).rephrase(PHRASE, 3)
    assert not list(tmp_path.glob("*.json"))  # failures are not cached

    with socket.socket() as sock:  # a port nobody listens on
        sock.bind(("127.0.0.1", 0))
        dead = f"http://127.0.0.1:{sock.getsockname()[1]}"
    with pytest.raises(LLMError, match=re.escape(f"LLM request to {dead}/chat/completions failed")):
        LLMRephraser(LLMConfig(url=dead, cache_dir=tmp_path, timeout_s=5)).rephrase(PHRASE, 3)


def test_interaction_types_all_have_subtypes_with_phrases() -> None:
    for kind in InteractionType:
        assert any(s.type is kind for s in SUBTYPES), kind


class _FakeRephraser:
    """Answers every phrase with two rephrasings of its own, counting the calls."""

    def __init__(self):
        self.calls = 0

    def rephrase(self, phrase, n=None):
        self.calls += 1
        return (f"{phrase} (version one)", f"{phrase} (version two)")


def test_an_llm_phrase_bank_extends_every_table_and_feeds_the_prompts():
    from langtraj.interdrive.labels import AgentLabel, WindowLabels
    from langtraj.interdrive.prompts import build_prompt_pool, llm_phrase_bank, phrase_tables

    fake = _FakeRephraser()
    bank = llm_phrase_bank(fake)
    tables = phrase_tables()
    assert fake.calls == len(tables)
    assert bank.labels("speeding_up")[-1] == "speeds up (version two)"
    assert bank.interactions("yielding/intersection")[-2:] == (
        "yields to <other> at the intersection (version one)",
        "yields to <other> at the intersection (version two)",
    )
    labels = WindowLabels("w", (AgentLabel(3, "speeding_up", 20, 40),))
    texts = {p.text for seed in range(60) for p in build_prompt_pool(labels, seed, per_agent=1, bank=bank)}
    assert "@3 speeds up (version one)" in texts


def test_langtrajs_added_subtypes_are_those_whose_definition_says_so() -> None:
    assert {s.id for s in SUBTYPES if "LangTraj's addition" in s.definition} == ADDED_SUBTYPES
    assert all(SUBTYPES_BY_ID[i].added for i in ADDED_SUBTYPES) and not SUBTYPES_BY_ID["yielding/intersection"].added
