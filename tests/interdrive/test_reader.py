"""The prompt reader (`interdrive/reader`): which behaviour kind a typed prompt asks of which agent, read from
everyday words; a negated, mixed or unknown prompt reads as nothing, with a reason."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.interdrive.adherence import lane_change_side
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.prompts.phrases import OTHER_SLOT, interaction_phrases, label_phrases, label_variants
from langtraj.interdrive.reader import PromptReading, file_figures, main, read_clauses, read_prompt
from langtraj.interdrive.triggers import AfterDone

DATA = Path(__file__).resolve().parents[1] / "data"
FREE_TEXT = DATA / "free_text_prompts.yaml"
PARAPHRASES = DATA / "prompt_paraphrases.yaml"
B = Behaviour


def reads(text: str) -> tuple[Behaviour | None, int | None, int | None]:
    r = read_prompt(text)
    return r.behaviour, r.agent, r.other


@pytest.mark.parametrize("behaviour", list(Behaviour))
def test_every_template_reads_as_its_behaviour(behaviour):
    spec = BEHAVIOURS[behaviour]
    other = 7 if spec.is_pair else None
    reading = read_prompt(spec.text(12, other))
    assert (reading.behaviour, reading.agent, reading.other) == (behaviour, 12, other)
    assert reading.words and reading.reason == ""


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("@1220 changes lanes to the left", (B.LANE_CHANGE_LEFT, 1220, None)),
        ("@1220 stops", (B.STOP, 1220, None)),
        ("@1220 makes a left lane change", (B.LANE_CHANGE_LEFT, 1220, None)),  # not a left turn
        ("@625 comes to a full stop and waits", (B.STOP, 625, None)),
        ("@20 pulls over and comes to a stop", (B.PULL_OVER, 20, None)),  # pulling over includes the stop
        ("@12 yields to @7 at the intersection", (B.YIELD, 12, 7)),
    ],
)
def test_the_issue_cases(text, expected):
    assert reads(text) == expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        # turns, and side words that name no turn
        ("@3 hang a left at the lights", (B.TURN_LEFT, 3, None)),
        ("@3 takes the next right", (B.TURN_RIGHT, 3, None)),
        ("@3 should head left at the lights", (B.TURN_LEFT, 3, None)),
        ("@3 turns right into the left lane", (B.TURN_RIGHT, 3, None)),
        ("@3 goes right ahead", (None, 3, None)),
        ("@3 moves into the left-turn lane", (None, 3, None)),
        # going straight
        ("@3 carries on straight", (B.GO_STRAIGHT, 3, None)),
        ("@3 drives through the junction without turning", (B.GO_STRAIGHT, 3, None)),
        # lane changes in many forms: not a pull-over, not a turn
        ("@3 pull into the left lane", (B.LANE_CHANGE_LEFT, 3, None)),
        ("@3 switches to the right lane", (B.LANE_CHANGE_RIGHT, 3, None)),
        ("@3 moves over a lane to the right", (B.LANE_CHANGE_RIGHT, 3, None)),
        ("@3 merges into the lane on its left", (B.LANE_CHANGE_LEFT, 3, None)),
        ("@3 moves from the leftmost lane to the middle lane", (B.LANE_CHANGE_RIGHT, 3, None)),
        ("@3 moves over a lane", (None, 3, None)),  # no side
        # stopping and pulling over
        ("@3 halts", (B.STOP, 3, None)),
        ("@3 stays put", (B.STOP, 3, None)),
        ("@3 is at a standstill", (B.STOP, 3, None)),
        ("@3 brakes to a stop", (B.STOP, 3, None)),
        ("@3 parks at the kerb", (B.PULL_OVER, 3, None)),
        ("@3 stops at the side of the road", (B.PULL_OVER, 3, None)),
        ("@3 moves onto the shoulder", (B.PULL_OVER, 3, None)),
        ("@3 pulls over to the right", (B.PULL_OVER, 3, None)),
        # speed
        ("@3 accelerates", (B.SPEED_UP, 3, None)),
        ("@3 picks up speed", (B.SPEED_UP, 3, None)),
        ("@3 eases off", (B.SLOW_DOWN, 3, None)),
        ("@3 decelerates", (B.SLOW_DOWN, 3, None)),
        ("@3 brakes", (B.SLOW_DOWN, 3, None)),
        # pairs
        ("@3 goes before @4", (B.GO_FIRST, 3, 4)),
        ("@3 takes the right of way over @4", (B.GO_FIRST, 3, 4)),
        ("@3 doesn't wait for @4", (B.GO_FIRST, 3, 4)),
        ("@3 cuts in front of @4", (B.CUT_IN, 3, 4)),  # issue 47: a cut-in, no longer going first
        ("@3 goes first, @4 waits", (B.GO_FIRST, 3, 4)),
        ("@3 gives way to @4", (B.YIELD, 3, 4)),
        ("@3 lets @4 go first", (B.YIELD, 3, 4)),  # "go first" is @4's, the yield @3's
        ("@3 lets @4 pass", (B.YIELD, 3, 4)),
        ("@3 waits for @4", (B.YIELD, 3, 4)),
        ("@3 stops to let @4 go first", (B.YIELD, 3, 4)),
        ("@3 hangs back so @4 can cross first", (B.YIELD, 3, 4)),
        ("@3 follows @4", (B.FOLLOW, 3, 4)),
        ("@3 stays behind @4", (B.FOLLOW, 3, 4)),
        ("@3 trails @4", (B.FOLLOW, 3, 4)),
        ("@3 tails @4", (B.FOLLOW, 3, 4)),
        ("@3 follows the lorry, @4", (B.FOLLOW, 3, 4)),  # "the lorry, @4" names @4, it does not address it
    ],
)
def test_everyday_phrasings(text, expected):
    assert reads(text) == expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("@7, take the next left", (B.TURN_LEFT, 7, None)),  # addressed
        ("@7: hang a right", (B.TURN_RIGHT, 7, None)),
        ("Have @7 turn left", (B.TURN_LEFT, 7, None)),  # the one a request names
        ("I want @12 to yield to @7", (B.YIELD, 12, 7)),
        ("Please move @12 one lane to the left", (B.LANE_CHANGE_LEFT, 12, None)),  # object of the request
        ("Let @7 turn left", (B.TURN_LEFT, 7, None)),  # a request to @7, not a yield to it
        ("Let @7 go first, @12", (B.YIELD, 12, 7)),  # @12 addressed, letting @7 go first: @12 yields
        ("@12, let @7 go first", (B.YIELD, 12, 7)),
        ("Let @7 go first", (None, 7, None)),  # nobody else named: who yields?
        ("After @7 turns left, @12 goes straight", (B.GO_STRAIGHT, 12, None)),  # subordinate clause is @7's
        ("If @7 turns left, @12 should stop", (B.STOP, 12, None)),
        ("@12 waits for @7 to turn left", (B.YIELD, 12, 7)),  # @7 turns, @12 waits
        ("@12 has priority over @7, so it goes first", (B.GO_FIRST, 12, 7)),
        ("@12 goes first instead of yielding to @7", (B.GO_FIRST, 12, 7)),  # 'instead of' drops what follows
        ("@12 goes first", (None, 12, None)),  # going first needs another agent
        ("@12 turns left, @7 goes straight", (B.TURN_LEFT, 12, None)),  # the first subject's; @7's is not read
        ("@12 and @7 stop", (None, None, None)),  # two agents asked the same
        ("@7 is followed by @12", (None, 7, None)),  # passive: not read
        ("@007 stops", (B.STOP, 7, None)),
    ],
)
def test_who_is_asked(text, expected):
    behaviour, agent, other = reads(text)
    assert (behaviour, other) == expected[::2]
    if expected[1] is not None:
        assert agent == expected[1]


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("@7 does not turn left", "negated"),
        ("@7 never stops", "negated"),
        ("@7 goes through the junction without stopping", "negated"),
        ("Make sure @7 doesn't change lanes", "negated"),
        ("@7 dances a jig", "no behaviour phrase"),
        ("@7 changes lanes", "no behaviour phrase"),  # no side
        ("@7 speeds up and changes lanes to the left", "more than one behaviour"),
        ("@7 turns left and changes lanes to the right", "only a turn or a lane change and then a stop is read"),
        ("@7 stops and then turns left", "asks stop before turn_left"),
        ("@7 waits for @12 then turns left", "more than one behaviour"),
        ("@7 yields", "needs exactly one other agent"),
        ("turn left", "names no agent"),
    ],
)
def test_negated_mixed_and_unknown_prompts_read_as_nothing_with_a_reason(text, reason):
    reading = read_prompt(text)
    assert reading.behaviour is None and reading.other is None and reading.words == ""
    assert reason in reading.reason
    assert reading.describe() == f"not read: {reading.reason}; the prompt steers by text alone"


def test_describe_to_json_and_the_words_of_the_typed_text():
    reading = read_prompt("@12,   Hang A Left at the lights")
    assert reading == PromptReading(B.TURN_LEFT, 12, None, "Hang A Left", "")
    assert reading.describe() == 'read as: @12 turn_left ("Hang A Left")'
    pair = read_prompt("@12 gives way to @7")
    assert pair.describe() == 'read as: @12 yield @7 ("gives way to @7")'
    assert pair.to_json() == {
        "behaviour": "yield", "agent": 12, "other": 7, "words": "gives way to @7", "reason": "", "also": [],
        "then": None, "clause": "", "metres": None, "deceleration": None, "condition": "", "trigger": None,
    }  # fmt: skip
    assert read_prompt("@12 hums").to_json() == {
        "behaviour": None,
        "agent": 12,
        "other": None,
        "words": "",
        "reason": "no behaviour phrase found",
        "also": [],
        "then": None,
        "clause": "",
        "metres": None,
        "deceleration": None,
        "condition": "",
        "trigger": None,
    }
    assert read_prompt("@12 hums").describe() == (
        "not read: no behaviour phrase found; the prompt steers by text alone"
    )


def _label_behaviours() -> list[tuple[str, dict[str, str], Behaviour]]:
    """(label key, params, behaviour) for every label variant a single-agent behaviour is judged by."""
    by_label = {(spec.label, spec.side): b for b, spec in BEHAVIOURS.items() if spec.label is not None}
    out = []
    for key, params in label_variants():
        side = lane_change_side(params) if key == "changing_lanes" else None
        if (key, side) in by_label:
            out.append((key, dict(params), by_label[key, side]))
    return out


@pytest.mark.parametrize(("key", "params", "behaviour"), _label_behaviours())
def test_every_phrase_of_a_behaviours_label_reads_as_it(key, params, behaviour):
    """The training prompts' phrases ("@5 <phrase>", as `compose_prompt` writes them) of the labels judging each
    single-agent kind: turning_left/right, going_straight, static, speeding_up, slowing_down, pulling_over and each
    changing_lanes pair with a side. None is skipped as ambiguous: every one of them reads as its kind."""
    phrases = label_phrases(key, params)
    wrong = [(p, read_prompt(f"@5 {p}").describe()) for p in phrases if reads(f"@5 {p}") != (behaviour, 5, None)]
    assert not wrong, wrong


@pytest.mark.parametrize(
    ("subtype", "behaviour"),
    [
        ("yielding/intersection", B.YIELD),
        ("passing/intersection_with_yielding", B.GO_FIRST),
        ("following/with_lead", B.FOLLOW),
    ],
)
def test_the_phrases_of_the_subtypes_judging_pair_kinds_read_as_them(subtype, behaviour):
    texts = [f"@5 {p.replace(OTHER_SLOT, '@9')}" for p in interaction_phrases(subtype)]
    wrong = [(t, read_prompt(t).describe()) for t in texts if reads(t) != (behaviour, 5, 9)]
    assert not wrong, wrong


def test_the_fifty_hand_written_prompts_read_as_their_behaviour():
    figures = file_figures(str(FREE_TEXT))
    print(f"\n{FREE_TEXT.name}: {figures.summary()}")
    assert figures.total == 50
    assert not figures.misread and not figures.unread, figures.misread + figures.unread


def test_the_paraphrase_set_reads_as_its_behaviours():
    """tests/data/prompt_paraphrases.yaml was written apart from the reader, as a held-out check; at least 95 % must
    read right and none as another behaviour. Run with -s to see the figures."""
    figures = file_figures(str(PARAPHRASES))
    print(f"\n{PARAPHRASES.name}: {figures.summary()}")
    for text, reading in figures.unread:
        print(f"  unread: {text!r}: {reading.reason}")
    assert not figures.misread, [(t, r.describe()) for t, r in figures.misread]
    assert figures.share_right >= 0.95


def test_the_command_prints_the_figures_of_each_file(capsys):
    assert main([str(FREE_TEXT), "-v"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(
        f"{FREE_TEXT}: 50 prompts: 50 read right (100.0 %), 0 misread (another behaviour or agent), 0 unread"
    )


def test_the_command_names_a_bad_file_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("prompts: [{text: '{agent} flies', behaviour: fly}]")
    assert main([str(bad)]) == 2
    assert "unknown behaviour 'fly'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("@693 slows down. @625 turns left.",
         [(693, B.SLOW_DOWN, "@693 slows down"), (625, B.TURN_LEFT, "@625 turns left")]),
        ("@693 @625 @635 stop", [(693, B.STOP, "@693 stop"), (625, B.STOP, "@625 stop"), (635, B.STOP, "@635 stop")]),
        ("@12 and @7 yield to @3", [(12, B.YIELD, "@12 yield to @3"), (7, B.YIELD, "@7 yield to @3")]),
        ("@12 turns left, @7 yields to @12", [(12, B.TURN_LEFT, "@12 turns left"), (7, B.YIELD, "@7 yields to @12")]),
        ("@12 turns left and @7 goes straight",
         [(12, B.TURN_LEFT, "@12 turns left"), (7, B.GO_STRAIGHT, "@7 goes straight")]),
        # one clause: a subordinate clause stays with its main one, a bare "and" after a mention joins objects
        ("after @7 turns left, @12 goes straight", [(12, B.GO_STRAIGHT, "after @7 turns left, @12 goes straight")]),
        ("@12 yields to @7 while @7 turns left", [(12, B.YIELD, "@12 yields to @7 while @7 turns left")]),
        ("@12 slows to 10.5 m/s.", [(12, B.SLOW_DOWN, "@12 slows to 10.5 m/s.")]),
        ("@20 pulls over and comes to a stop", [(20, B.PULL_OVER, "@20 pulls over and comes to a stop")]),
    ],
)  # fmt: skip
def test_a_prompt_is_read_clause_by_clause(text, expected):
    readings = read_clauses(text)
    assert [(r.agent, r.behaviour, r.clause) for r in readings] == expected
    assert all(r.describe().startswith("read as:") for r in readings)


def test_a_kind_asked_with_the_one_read_is_kept_as_its_fallback():
    assert read_prompt("@20 pulls over and comes to a stop").also == (B.STOP,)
    assert read_prompt("@20 slows down and pulls over").also == (B.SLOW_DOWN,)
    assert read_prompt("@20 pulls over").also == ()
    assert read_clauses("@12 lets @7 and @9 go first")[0].clause == "@12 lets @7 and @9 go first"  # one clause


@pytest.mark.parametrize(
    "text",
    ["@52 cuts in front of @56", "@52 cuts in ahead of @56 with a 10 m gap", "@52 cuts @56 off", "@52 cuts off @56",
     "@52 merges in front of @56", "@52 changes lanes right in front of @56",
     "@52 moves into @56's lane in front of it"],
)  # fmt: skip
def test_the_cut_in_vocabulary_reads_as_a_cut_in(text):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.CUT_IN, 52, 56)
    assert reading.metres == (10.0 if "10 m" in text else None)
    assert read_prompt("@52 pulls out in front of @56").behaviour is B.PULL_OUT  # from a side road, not a lane beside
    assert read_prompt("@52 cuts in front of @56 at 10 m/s").metres is None  # a speed is no gap


@pytest.mark.parametrize(
    ("text", "deceleration"),
    [("@52 brakes hard in front of @56", None), ("@52 slams on the brakes in front of @56", None),
     ("@52 brakes suddenly right ahead of @56", None), ("@52 does an emergency stop in front of @56", None),
     ("@52 brake-checks @56", None), ("@52 forces @56 to brake", None),
     ("@52 brakes hard at 6 m/s2 in front of @56", 6.0), ("@52 brakes at 0.5 g in front of @56", 0.5 * 9.80665)],
)  # fmt: skip
def test_the_braking_lead_vocabulary_reads_as_braking_hard_in_front(text, deceleration):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.BRAKE_HARD, 52, 56)
    assert reading.deceleration == (None if deceleration is None else pytest.approx(deceleration))
    assert read_prompt("@52 brakes hard").behaviour is B.SLOW_DOWN  # nobody behind named: slowing down


@pytest.mark.parametrize(
    "text",
    ["@52 tailgates @56", "@52 follows @56 too closely", "@52 drives dangerously close behind @56",
     "@52 rides @56's bumper", "@52 sits on the bumper of @56"],
)  # fmt: skip
def test_the_tailgating_vocabulary_reads_as_tailgating(text):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.TAILGATE, 52, 56)
    assert read_prompt("@52 follows closely behind @56").behaviour is B.FOLLOW  # close, not too close


@pytest.mark.parametrize(
    "text",
    ["@52 overtakes @56 and cuts in front of it", "@52 passes @56 and cuts in", "@52 overtakes @56 and cuts it off",
     "@52 passes @56, then pulls in ahead of it with a 6 m gap", "@52 overtakes and cuts in front of @56",
     "@52 cuts in front of @56 after overtaking it", "@52 goes past @56 and moves back into its lane",
     "@52 races past @56 and swerves back in front of it"],
)  # fmt: skip
def test_the_overtake_and_cut_in_vocabulary_reads_as_one_kind(text):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.OVERTAKE_CUT_IN, 52, 56)
    assert reading.metres == (6.0 if "6 m" in text else None)
    # a cut-in in front of another agent than the one passed is that cut-in, not an overtake of either
    assert read_prompt("@52 overtakes @56 and cuts in front of @9").behaviour is B.CUT_IN
    assert read_prompt("@52 overtakes @56").behaviour is None  # an overtake alone is not in the vocabulary


@pytest.mark.parametrize(
    "text",
    ["@52 runs the red light across @56's path", "@52 runs a red light in front of @56",
     "@52 jumps the red in front of @56", "@52 crosses the junction on red in front of @56",
     "@52 cuts across the path of @56 on a red light", "@52 ignores the red light and goes in front of @56"],
)  # fmt: skip
def test_the_red_light_vocabulary_reads_as_running_it_across_the_other(text):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.RUN_RED_LIGHT, 52, 56)
    assert read_prompt("@52 runs the red light").reason == "run_red_light needs exactly one other agent"
    assert read_prompt("@52 goes first before @56").behaviour is B.GO_FIRST


@pytest.mark.parametrize(
    "text",
    ["@52 pulls out in front of @56", "@52 pulls out of the side road into the path of @56",
     "@52 noses out of a driveway into @56's lane", "@52 emerges from the junction right in front of @56",
     "@52 turns left out of the side road in front of @56", "@52 pulls out suddenly in front of @56 from a side road",
     "@52 comes out of a driveway just ahead of @56", "@52 pulls out from the kerb into the road ahead of @56"],
)  # fmt: skip
def test_the_pull_out_vocabulary_reads_as_pulling_out_in_front_of_the_other(text):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == (B.PULL_OUT, 52, 56)
    assert read_prompt("@52 crosses in front of @56").behaviour is B.GO_FIRST  # no pulling out: going first
    assert read_prompt("@52 pulls out").behaviour is not B.PULL_OUT  # in front of nobody


@pytest.mark.parametrize(
    ("text", "first", "words"),
    [
        ("@7 turns left and then stops", B.TURN_LEFT, "turns left and then stops"),
        ("@7 turns right, then comes to a stop", B.TURN_RIGHT, "turns right, then comes to a stop"),
        ("@7 goes straight through the junction and stops", B.GO_STRAIGHT, None),
        ("@7 changes to the left lane and stops", B.LANE_CHANGE_LEFT, "changes to the left lane and stops"),
        ("@7 moves over a lane to the right, then halts", B.LANE_CHANGE_RIGHT, None),
    ],
)
def test_a_manoeuvre_and_then_a_stop_is_read_as_the_two_in_order(text, first, words):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.then) == (first, 7, B.STOP)
    assert words is None or reading.words == words
    assert reading.describe().startswith(f"read as: @7 {first.value} then stop (")
    assert reading.to_json()["then"] == "stop"
    turn = frozenset({("label", 7, "turning_left"), ("label", 7, "crossing_intersection")})
    if first is B.TURN_LEFT:
        assert reading.followed(turn | {("label", 7, "static")})
        assert not reading.followed(turn)  # turned, never stopped
        assert not reading.followed(frozenset({("label", 7, "static")}))  # stopped, never turned


@pytest.mark.parametrize(
    ("text", "expected", "condition"),
    [
        ("after 2 seconds @741 cuts in front of @1", (B.CUT_IN, 741, 1), "after 2 seconds"),
        ("@741 cuts in front of @1 2 seconds from now", (B.CUT_IN, 741, 1), "2 seconds from now"),
        ("@741 cuts in front of @1 after 2 s", (B.CUT_IN, 741, 1), "after 2 s"),
        ("@12 turns left in 3 seconds", (B.TURN_LEFT, 12, None), "in 3 seconds"),
        ("@12 turns left at 3 s", (B.TURN_LEFT, 12, None), "at 3 s"),
        ("@12 turns left at t = 3", (B.TURN_LEFT, 12, None), "at t = 3"),
        ("2 seconds later, @7 stops", (B.STOP, 7, None), "2 seconds later"),
        ("@741 brakes hard in front of @1 when @1 is 20 m behind", (B.BRAKE_HARD, 741, 1), "when @1 is 20 m behind"),
        ("when @1 is 20 m behind, @741 brakes hard", (B.SLOW_DOWN, 741, None), "when @1 is 20 m behind"),
        ("when @1 is within 15.5 m @741 brakes hard in front of @1", (B.BRAKE_HARD, 741, 1),
         "when @1 is within 15.5 m"),
        ("after @7 turns left, @12 goes first", (B.GO_FIRST, 12, 7), "after @7 turns left"),
        ("If @7 turns left, @12 should stop", (B.STOP, 12, None), "If @7 turns left"),
        ("@12 turns left once @7 has stopped", (B.TURN_LEFT, 12, None), "once @7 has stopped"),
        ("@12 follows @7 until the light turns green", (B.FOLLOW, 12, 7), "until the light turns green"),
        ("@12 yields to @7 as soon as @7 slows down", (B.YIELD, 12, 7), "as soon as @7 slows down"),
    ],
)  # fmt: skip
def test_timing_words_are_kept_on_the_reading_not_dropped(text, expected, condition):
    reading = read_prompt(text)
    assert (reading.behaviour, reading.agent, reading.other) == expected
    assert reading.condition == condition
    said = reading.describe()  # read as a start, or named as not read: never dropped
    named = f"{condition!r} is not read (the behaviour runs at once)"
    assert said.endswith(f"({condition!r})" if reading.trigger else named)
    assert reading.to_json()["condition"] == condition
    assert read_clauses(text)[0].condition == condition


@pytest.mark.parametrize(
    "text",
    ["@12 turns left and then stops", "@12 turns right, then comes to a stop", "@12 turns left and later stops",
     "Please have @12 go left when it reaches the intersection", "Let @12 turn right when it gets to the junction",
     "@12 holds back until @7 has gone by", "@12 waits until @7 has cleared the intersection",
     "@12 yields to @7 until @7 has passed", "@12 gets through before @7 does", "@12 goes first before @7",
     "@12 yields to @7 while @7 turns left", "@12 follows @7 at 2 s headway", "@12 stops at once",
     "@12 slows down if needed", "I want @12 to come to a complete stop before the crosswalk",
     "@12 cuts in front of @7 after overtaking it", "@12 gets through the junction first, with @7 after it"],
)  # fmt: skip
def test_words_a_behaviour_honours_are_no_timing(text):
    assert all(r.read and r.condition == "" for r in read_clauses(text)), [r.describe() for r in read_clauses(text)]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("@4 turns left, then @7 pulls out in front of @1", [(4, B.TURN_LEFT, ""), (7, B.PULL_OUT, "then")]),
        ("@4 turns left and then @7 stops", [(4, B.TURN_LEFT, ""), (7, B.STOP, "and then")]),
        ("@4 turns left, after that @7 stops", [(4, B.TURN_LEFT, ""), (7, B.STOP, "after that")]),
        ("@4 turns left. Afterwards @7 stops.", [(4, B.TURN_LEFT, ""), (7, B.STOP, "Afterwards")]),
        ("@4 turns left and @7 goes straight", [(4, B.TURN_LEFT, ""), (7, B.GO_STRAIGHT, "")]),  # at once: asked so
        ("@4 turns left, then @4 stops", [(4, B.TURN_LEFT, ""), (4, B.STOP, "")]),  # one agent: asked twice
        ("Then @7 stops", [(7, B.STOP, "Then")]),  # after something another prompt asks
    ],
)  # fmt: skip
def test_a_sequence_across_agents_is_kept_on_the_later_clause(text, expected):
    readings = read_clauses(text)
    assert [(r.agent, r.behaviour, r.condition) for r in readings] == expected
    for before, reading in zip([None, *readings[:-1]], readings, strict=True):
        if not reading.condition:
            assert "starts" not in reading.describe() and "sequence" not in reading.describe()
        elif before is not None:  # after another agent's clause: started when its behaviour is done
            assert reading.trigger == AfterDone(before.agent)
            assert f"starts after @{before.agent}'s behaviour" in reading.describe()
        else:  # after nothing this prompt asks: no start LangTraj reads, named
            assert reading.trigger is None and "the sequence" in reading.describe()


def test_pair_words_without_their_second_agent_and_an_overtake_alone_say_why():
    assert read_prompt("@52 cuts in").reason == "cut_in needs exactly one other agent"
    assert read_prompt("@52 tailgates").reason == "tailgate needs exactly one other agent"
    alone = read_prompt("@52 overtakes @1")
    assert alone.behaviour is None and alone.agent == 52
    assert alone.reason == (
        "overtaking alone is not a behaviour LangTraj steers; say '@52 overtakes @1 and cuts in front of it'"
    )
    assert alone.describe().startswith("not read: overtaking alone is not a behaviour LangTraj steers")
    assert read_prompt("@52 overtakes @1 and cuts in front of it").behaviour is B.OVERTAKE_CUT_IN
    assert read_prompt("@52 cuts in front of @1").behaviour is B.CUT_IN
