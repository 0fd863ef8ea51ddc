"""The prompt reader's rules: the verb forms (`verb`: every inflection of a base verb), the word classes and the
regular-expression rule tables, one list of patterns per behaviour kind, compiled into `RULES`; with the kinds one
kind subsumes (`SUBSUMES`) and the negation, 'instead of' and passive patterns that stop a reading. The patterns run
over the normalised text of `read.py`, where each `@id` mention is a placeholder `<m0>`, `<m1>`, ...; a named group
`other` marks the other agent of a pair kind and `agent` the agent a request names as its object.

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from langtraj.interdrive.behaviour import Behaviour

SLOT = r"<m\d+>"
_VEHICLE = (
    r"(?:car|truck|lorry|van|bus|coach|vehicle|cyclist|bike|bicycle|pedestrian|motorbike|motorcycle|scooter|taxi|cab"
    r"|suv|sedan|person|walker|driver|agent|one|tractor|trailer)"
)
_APPOSITION = rf"(?:(?:the|a|an|that|this)\s+(?:[\w-]+\s+){{0,2}}?{_VEHICLE}\s*,?\s+)"
"""A noun phrase naming the other agent before its mention: "follows the lorry, @7", "behind the truck @7"."""
_OTHER = rf"{_APPOSITION}?(?P<other>{SLOT})"
_OBJ = rf"(?:\s+(?P<agent>{SLOT}))?"
"""The asked agent as the object of a request: "move @12 one lane to the left", "bring @12 to a halt"."""
PLACEHOLDER = re.compile(r"<m(\d+)>")

# ---------------------------------------------------------------------------------------------- words

_IRREGULAR: dict[str, tuple[str, ...]] = {
    "go": ("goes", "going", "went", "gone"),
    "take": ("takes", "taking", "took", "taken"),
    "make": ("makes", "making", "made"),
    "come": ("comes", "coming", "came"),
    "get": ("gets", "getting", "got", "gotten"),
    "hang": ("hangs", "hanging", "hung"),
    "let": ("lets", "letting"),
    "cut": ("cuts", "cutting"),
    "put": ("puts", "putting"),
    "hold": ("holds", "holding", "held"),
    "keep": ("keeps", "keeping", "kept"),
    "bring": ("brings", "bringing", "brought"),
    "give": ("gives", "giving", "gave", "given"),
    "lose": ("loses", "losing", "lost"),
    "slide": ("slides", "sliding", "slid"),
    "swing": ("swings", "swinging", "swung"),
    "drive": ("drives", "driving", "drove", "driven"),
    "ride": ("rides", "riding", "rode", "ridden"),
    "run": ("runs", "running", "ran"),
    "stand": ("stands", "standing", "stood"),
    "sit": ("sits", "sitting", "sat"),
    "beat": ("beats", "beating", "beaten"),
    "bear": ("bears", "bearing", "bore", "borne"),
    "freeze": ("freezes", "freezing", "froze", "frozen"),
    "draw": ("draws", "drawing", "drew", "drawn"),
    "speed": ("speeds", "speeding", "sped"),
    "fall": ("falls", "falling", "fell", "fallen"),
    "shoot": ("shoots", "shooting", "shot"),
    "leave": ("leaves", "leaving"),  # not "left": that is a side
    "grind": ("grinds", "grinding", "ground"),
    "have": ("has", "having", "had"),
    "do": ("does", "doing", "did", "done"),
    "shed": ("sheds", "shedding"),
    "set": ("sets", "setting"),
    "hit": ("hits", "hitting"),
    "see": ("sees", "seeing", "saw", "seen"),
}
_DOUBLED = frozenset(
    {"stop", "nip", "hop", "slip", "step", "drop", "pop", "swap", "slot", "tag", "tap", "gun", "permit", "submit"}
)
"""Verbs doubling their last consonant: stopping, stopped."""


def _forms(base: str) -> tuple[str, ...]:
    """The base, third-person, -ing and past forms of a regular or listed irregular verb."""
    if base in _IRREGULAR:
        return (base, *_IRREGULAR[base])
    consonant_y = base.endswith("y") and base[-2] not in "aeiou"
    if base.endswith(("s", "sh", "ch", "x", "z")):
        third = base + "es"
    else:
        third = base[:-1] + "ies" if consonant_y else base + "s"
    if base in _DOUBLED:
        stem = base + base[-1]
    else:
        stem = base[:-1] if base.endswith("e") and not base.endswith("ee") else base
    past = base + "d" if base.endswith("e") else (base[:-1] + "ied" if consonant_y else stem + "ed")
    if base.endswith("el"):  # travel: British travelling, travelled beside traveling, traveled
        return base, third, stem + "ing", past, base + "ling", base + "led"
    return base, third, stem + "ing", past


def verb(*bases: str) -> str:
    """A non-capturing group of every form of `bases` (a multi-word base inflects its first word)."""
    forms: set[str] = set()
    for base in bases:
        head, _, tail = base.partition(" ")
        forms.update(f"{form} {tail}".strip() for form in _forms(head))
    return "(?:" + "|".join(sorted((re.escape(f).replace(r"\ ", r"\s+") for f in forms), key=len, reverse=True)) + ")"


def _gap(words: int) -> str:
    """Up to `words` words within one clause (not across 'and', 'then', 'but', 'or' or punctuation)."""
    return rf"(?:\s+(?!(?:and|then|but|or)\b)[\w'<>-]+){{0,{words}}}?"


_TIGHT_GAP = r"(?:(?!\b(?:and|then|but|or)\b)[^,;.!?]){0,40}?"
"""Up to 40 characters within one clause."""

_POSSESSIVE = r"(?:the|its|your|their|his|her|one's)"


# ---------------------------------------------------------------------------------------------- rules


@dataclass(frozen=True)
class _Rule:
    behaviour: Behaviour
    pattern: re.Pattern[str]


_NOT_LANE = r"(?![ -]?(?:hand\s+)?(?:lanes?|side|kerb|curb|shoulder|verge|edge|of\s+way|-of-way)\b)"
"""Not "the left lane", "the right side", "the right of way": a side word that names no turn."""
_NOT_ADVERB = r"(?!\s+(?:ahead|away|now|there|here|behind|where|after|before|back|up|through|past|across|on)\b)"
"""Not "go right ahead", "turn right away"."""
_TURN_VERBS = verb("turn", "swing", "steer", "bear", "head", "go", "hook", "hang", "branch", "fork", "peel", "wheel")
_TURN_TAKE = verb("hang", "take", "make", "hook", "do", "pull", "throw", "swing", "bang", "hit", "execute", "perform")
_TURN_DET = (
    r"(?:a|an|the)"
    r"(?:\s+(?:next|first|second|third|upcoming|coming|following|sharp|quick|hard|tight|wide|gentle|slight))*"
)
_TURN_NOUN = r"(?:road|street|turning|turn|exit|branch|arm|fork|avenue|way)"
_JUNCTION = r"(?:junction|intersection|crossroads|roundabout|lights|crossing)"


def _turn(side: str) -> list[str]:
    s = rf"(?:{side}(?:-hand)?|{side}wards?)"
    exit_verbs = verb("exit", "leave", "turn out of", "come out of")
    return [
        rf"\b{_TURN_VERBS}(?:\s+(?:off|away|round|around|out|sharply|hard))?"
        rf"(?:\s+to(?:wards)?\s+{_POSSESSIVE}\s+|\s+){s}\b{_NOT_LANE}{_NOT_ADVERB}",
        rf"\b{_TURN_TAKE}\s+{_TURN_DET}\s+{side}(?:-hand)?(?:[ -](?:turn|turning|hander))?\b{_NOT_LANE}",
        rf"\b{side}(?:-hand)?[ -]turn(?:ing)?\b(?![ -]lanes?\b)",
        rf"\b{_TURN_NOUN}\s+(?:on|to)\s+{_POSSESSIVE}\s+{side}\b{_NOT_LANE}",
        rf"\b(?:onto|into|down|up|along|via)\s+{_TURN_DET}\s+{side}(?:-hand)?\s+{_TURN_NOUN}\b",
        rf"\b{exit_verbs}(?:\s+(?:the|a)\s+{_JUNCTION})?\s+(?:(?:to(?:wards)?|on|by|via)\s+{_POSSESSIVE}\s+)?{s}\b"
        rf"{_NOT_LANE}{_NOT_ADVERB}",
        rf"\b{verb('make')}\s+{_POSSESSIVE}\s+way\s+(?:to(?:wards)?\s+the\s+|over\s+to\s+the\s+)?{s}\b{_NOT_LANE}",
    ]


_GO_ON = verb(
    "go", "keep", "continue", "carry", "head", "proceed", "drive", "travel", "move", "ride", "cycle", "walk", "stay",
    "run", "push", "press", "cruise", "roll",
)  # fmt: skip
_STRAIGHT = [
    rf"\b{_GO_ON}(?:\s+(?:on|going|driving|right|dead|directly))?\s+straight\b(?!\s*(?:away|after|afterwards|off|back)\b)",
    r"\bstraight\s+(?:on|ahead|through|over|across)\b",
    r"\b(?:without\s+(?:turning|making\s+(?:a|any)\s+turns?)|no\s+turns?|no\s+turning|making\s+no\s+turns?)\b"
    r"(?!\s+(?:left|right|off\s+to))",
    r"\bin\s+a\s+straight\s+line\b|\bstraight\s+course\b",
    r"\bin\s+the\s+same\s+direction\b(?!\s+as\b)",
    rf"\b{verb('stay', 'keep', 'remain')}\s+on\s+(?:this|the\s+same|its|your|their|the\s+current|the\s+main)"
    r"\s+(?:road|street|route)\b",
]

_MOTION = verb(
    "change", "switch", "swap", "move", "shift", "get", "pull", "merge", "nip", "hop", "slide", "cut", "go", "head",
    "drift", "slip", "slot", "jump", "steer", "ease", "edge", "pop", "duck", "tuck", "weave", "dart", "squeeze",
    "cross", "step", "glide", "drop", "come",
)  # fmt: skip
_SIDESTEP = verb(
    "move", "shift", "get", "merge", "nip", "hop", "slide", "cut", "drift", "slip", "slot", "jump", "steer", "ease",
    "edge", "pop", "duck", "tuck", "weave", "dart", "squeeze", "step", "glide",
)  # fmt: skip
"""Verbs of moving across to a side without naming a lane ("moves over to the left"); not "pulls over to the
right", which is pulling over."""
_POSITIONS = (
    r"(?:left|leftmost|left-most|far-left|far\s+left|left-hand)",
    r"(?:middle|center|centre|central)",
    r"(?:right|rightmost|right-most|far-right|far\s+right|right-hand)",
)
"""Lane position words by order from left to right."""


def _lane_np(side: str) -> str:
    """A lane on `side`: "the left lane", "the lane on its left", "the neighbouring lane to the left"."""
    words = r"(?:(?!(?:and|then|but|or)\b)[\w'-]+\s+){0,2}?"
    side_word = rf"(?:{side}|{side}-hand|far-{side}|far\s+{side}|{side}most|{side}-most)"
    det = r"(?:(?:the|a|an|its|your|their|one)\s+)?"
    return (
        rf"(?:{det}{words}{side_word}\s+lanes?\b"
        rf"|{det}{words}lanes?\s+{words}(?:on|to|at)\s+{_POSSESSIVE}\s+(?:far\s+)?{side}\b(?!-hand\s+side|\s+side))"
    )


def _lane_change(side: str) -> list[str]:
    to_side = rf"(?:to(?:wards)?\s+{_POSSESSIVE}\s+(?:far\s+)?{side}|{side}wards?|{side})\b"
    not_place = r"(?![ -]?(?:hand\s+)?(?:side|kerb|curb|shoulder|verge|edge)\b)"
    return [
        rf"\b{_MOTION}{_OBJ}(?:\s+(?:over|across|back|out))?\s+(?:into|to|onto|towards?|in\s+to|across|over)\s+{_lane_np(side)}",
        rf"\b{verb('get')}{_OBJ}\s+in\s+{_lane_np(side)}",
        rf"\b{_MOTION}{_OBJ}(?:\s+(?:over|across|back))?\s+(?:(?:one|a|1)\s+lane|lanes?)\s+(?:over\s+)?{to_side}{not_place}",
        rf"\b{_MOTION}{_OBJ}\s+(?:over\s+)?(?:{side}|{side}wards?)\s+(?:one|a|1)\s+lane\b",
        rf"\b{side}(?:-hand)?[ -]lane[ -]change\b|\blane[ -]change\s+(?:to(?:wards)?|on)\s+{_POSSESSIVE}\s+{side}\b",
        rf"\b{_SIDESTEP}{_OBJ}\s+(?:over|across)\s+{to_side}{not_place}",
    ]


def _lane_from_to() -> list[tuple[Behaviour, str]]:
    """Lane changes named by their lanes: "from the leftmost lane to the middle lane" is to the right."""
    out = []
    for i, src in enumerate(_POSITIONS):
        for j, dst in enumerate(_POSITIONS):
            if i != j:
                out.append(
                    (
                        Behaviour.LANE_CHANGE_RIGHT if j > i else Behaviour.LANE_CHANGE_LEFT,
                        rf"\b{_MOTION}{_OBJ}(?:\s+lanes?)?(?:\s+over)?\s+from\s+(?:the\s+)?{src}(?:\s+lane)?\s+"
                        rf"(?:to|into|over\s+to|across\s+to)\s+(?:the\s+)?{dst}(?:\s+lane)?\b",
                    )
                )
    return out


_STOP_NOUN = r"(?:stop|halt|standstill)"
_STOP = [
    rf"(?<!non-)(?<!bus\s)\b{verb('stop', 'halt')}\b(?!\s+(?:sign|line|lights?)\b|-)",
    rf"\b(?:{verb('come', 'draw', 'grind', 'roll', 'brake', 'slow', 'slow down', 'ease')}"
    rf"|{verb('bring')}\s+(?:it|(?P<agent>{SLOT})))\s+(?:in)?to\s+a"
    rf"(?:\s+(?:full|complete|dead|total|sudden|quick|gentle|smooth|controlled))?\s+{_STOP_NOUN}\b",
    r"\b(?:at\s+a\s+)?standstill\b",
    rf"\b(?:{verb('stand', 'stay', 'remain', 'keep', 'sit', 'hold')}|is|are|be|being|been)\s+"
    r"(?:completely\s+|perfectly\s+|totally\s+|absolutely\s+|dead\s+)?(?:still|stationary|motionless|static|put)\b"
    r"(?!\s+\w+ing\b)",
    rf"\b{verb('stay', 'remain')}\s+in\s+place\b|\b{verb('hold')}\s+{_POSSESSIVE}\s+position\b",
    r"\b(?:stationary|motionless)\b",
    r"\b(?:(?:does|do|is|are)\s+not|doesn't|don't|isn't|aren't|not)\s+(?:move|moving)\b"
    r"(?!\s+(?:over|into|across|aside|out|left|right|to|onto|off|away|up)\b)",
    rf"\b{verb('freeze')}\b",
    rf"\b{verb('pull')}\s+up\b",
]

_PLACE = (
    r"(?:side\s+of\s+the\s+(?:road|street)|roadside|road\s+side|kerb|curb|kerbside|curbside|hard\s+shoulder"
    r"|shoulder|verge|edge\s+of\s+the\s+(?:road|street)|lay-by|layby)"
)
_TO_THE_SIDE = verb(
    "move", "steer", "head", "go", "get", "pull", "drive", "ease", "edge", "tuck", "draw", "swing", "park", "stop",
    "halt", "come", "bring it", "roll", "coast", "nose", "bear",
)  # fmt: skip
_PULL_OVER = [
    rf"\b{verb('pull')}{_OBJ}\s+(?:over|in|off|aside)\b"
    r"(?!\s+(?:behind|in\s+front|ahead|between|next\s+to|alongside)\b|[^,;.]{0,25}\blanes?\b)",
    rf"\b{_TO_THE_SIDE}"
    rf"{_gap(5)}\s+(?:at|by|on|onto|to|towards|against|beside|alongside|into|next\s+to|near)"
    rf"\s+(?:the\s+|a\s+)?(?:near\s+|left\s+|right\s+|nearside\s+|left-hand\s+|right-hand\s+)?{_PLACE}\b",
    rf"\b(?:onto|towards?)\s+(?:the\s+)?{_PLACE}\b",
]

_SPEED_UP = [
    rf"\b{verb('speed')}{_OBJ}\s+up\b",
    rf"\b{verb('accelerate')}\b(?!\s+(?:away\s+from|to\s+avoid)\b)",
    rf"\b{verb('pick')}\s+up\s+(?:the\s+|some\s+)?(?:speed|pace|tempo|momentum)\b",
    rf"\b{verb('gain', 'gather', 'build', 'build up')}\s+(?:some\s+|more\s+)?(?:speed|pace|momentum)\b",
    rf"\b{verb('hit', 'press', 'floor', 'stamp on', 'step on', 'push', 'mash', 'open up')}\s+(?:the|its|your|their)"
    r"\s+(?:accelerator|gas(?:\s+pedal)?|throttle)\b",
    rf"\b(?:{verb('increase', 'raise')}|up(?:s|ped|ping)?)\s+(?:{_POSSESSIVE}\s+|some\s+)?(?:speed|pace)\b",
    rf"\b{verb('step')}\s+on\s+(?:it|the\s+(?:gas|accelerator|throttle))\b",
    rf"\b{verb('put')}\s+(?:{_POSSESSIVE}|the)\s+foot\s+down\b|\b{verb('floor', 'gun')}\s+it\b",
    rf"\b{verb('hurry')}(?:\s+up)?\b|\b{verb('get')}\s+a\s+move\s+on\b",
    r"\b(?:faster|quicker|more\s+quickly)\b",
    rf"\b{verb('quicken')}\s+(?:{_POSSESSIVE}\s+)?pace\b",
]

_SLOW_DOWN = [
    rf"\b{verb('slow')}(?:{_OBJ}\s+(?:down|up))?\b",
    rf"\b{verb('decelerate', 'brake')}\b",
    rf"\b{verb('hit', 'tap', 'touch', 'use', 'apply', 'press', 'step on')}\s+(?:the|its|your|their)\s+brakes?\b",
    rf"\b{verb('ease', 'back')}\s+(?:off|up|back)\b"
    r"(?:\s+(?:on\s+|off\s+)?(?:the\s+)?(?:throttle|gas|accelerator|pedal|pace|speed))?",
    rf"\b{verb('come', 'get', 'lift', 'back', 'let')}\s+off\s+(?:the\s+)?(?:throttle|gas|accelerator|pedal)\b",
    rf"\b{verb('lose', 'reduce', 'drop', 'cut', 'lower', 'decrease', 'shed', 'bleed off', 'bring down', 'lessen')}"
    rf"\s+(?:{_POSSESSIVE}\s+|some\s+|a\s+bit\s+of\s+|a\s+little\s+|some\s+of\s+{_POSSESSIVE}\s+)?(?:speed|pace)\b",
    rf"\b{verb('take')}\s+it\s+(?:easy|slow|slower)\b",
    r"\b(?:slower|more\s+slowly)\b",
]

_GO_FIRST_VERBS = verb(
    "go", "get", "pass", "cross", "proceed", "head", "enter", "clear", "claim", "make it", "squeeze", "nip", "slip",
    "shoot", "dart", "race", "rush", "jump", "turn", "merge", "pull out", "take", "set off", "drive", "move", "travel",
    "reach", "arrive", "cut",
)  # fmt: skip
_AHEAD_VERBS = verb(
    "go", "get", "pass", "cross", "proceed", "enter", "clear", "claim", "make it", "squeeze", "nip", "slip", "shoot",
    "dart", "race", "rush", "jump", "turn", "merge", "pull out", "cut", "reach",
)  # fmt: skip
"""Verbs of going ahead of another agent in time (not "drives ahead of @7", which says where it is)."""
_GO_FIRST = [
    rf"\b{_GO_FIRST_VERBS}{_gap(5)}\s+(?:before|sooner\s+than|earlier\s+than)\s+{_OTHER}",
    rf"\b{_AHEAD_VERBS}"
    rf"{_gap(5)}\s+ahead\s+of\s+{_OTHER}",
    rf"\b{verb('cross', 'dart', 'shoot', 'pass', 'go', 'turn')}"
    rf"(?:\s+(?:out|across))?\s+in\s+front\s+of\s+{_OTHER}",
    rf"\b{verb('take', 'have', 'claim', 'keep', 'assert', 'use', 'exercise', 'get', 'seize')}"
    rf"\s+(?:{_POSSESSIVE}\s+)?(?:right\s+of\s+way|right-of-way|priority|precedence)"
    rf"(?:\s+(?:over|from|ahead\s+of|before|against)\s+{_OTHER})?",
    rf"\b(?:{_GO_FIRST_VERBS}|be|is|are){_gap(3)}\s+first\b"
    r"(?!\s+(?:junction|intersection|left|right|exit|turn|turning|lane|road|street|time|one|lights)\b)",
    r"\bfirst\s+to\s+(?:go|cross|pass|enter|move|proceed|get\s+through|clear|drive)\b",
    rf"\b{verb('beat', 'outrun')}\s+{_OTHER}",
    r"\b(?:do(?:es)?\s+not|do(?:es)?n't|never|won't|will\s+not|without|not)\s+(?:\w+\s+)?"
    rf"{verb('yield', 'give way', 'wait', 'stop', 'slow', 'slow down', 'brake', 'hold back')}\s+(?:to|for)\s+{_OTHER}",
    rf"\b(?:while|whilst|as|with)\s+{_OTHER}\s+"
    rf"{verb('yield', 'give way', 'wait', 'hold back')}(?:\s+(?:to|for)\s+(?:it|them|him|her))?\b",
    rf"\b{verb('have', 'take', 'get')}\s+(?:its|your|their|his|her|the)\s+turn\s+(?:before|ahead\s+of)\s+{_OTHER}",
]

_CUT_IN_VERBS = verb(
    "cut", "nip", "dive", "swerve", "squeeze", "slot", "tuck", "merge", "slip", "jump", "weave", "change lanes",
    "switch lanes", "move over", "pull in", "pull over", "barge", "force its way", "push in",
)  # fmt: skip
_CUT_MANNER = r"(?:over|back|across|sharply|suddenly|right|just|closely|dangerously|abruptly|tightly|aggressively)"
_JUST_AHEAD = r"(?:in\s+front\s+of|ahead\s+of|just\s+ahead\s+of)"
_CUTS_IN = rf"{_CUT_IN_VERBS}(?:\s+(?:in|{_CUT_MANNER}))*\s+(?:{_JUST_AHEAD}|in\s+on)"
"""A cut in front of someone named next: "cuts in front of", "swerves sharply in ahead of", "cuts in on"."""
_CUT_IN = [
    rf"\b{_CUTS_IN}\s+{_OTHER}",
    rf"\b{verb('cut', 'push', 'barge')}\s+in\s+on\s+{_OTHER}",
    rf"\b{verb('cut')}\s+(?:off|up)\s+{_OTHER}",
    rf"\b{verb('cut')}\s+{_OTHER}\s+(?:off|up)\b",
    rf"\b{verb('change lanes', 'switch lanes', 'move', 'merge', 'cut', 'pull', 'swerve', 'squeeze')}"
    rf"(?:\s+(?:over|across))?\s+(?:in)?to\s+{_OTHER}'s\s+lane\b"
    r"(?:\s+(?:right\s+|just\s+)?(?:in\s+front\s+of|ahead\s+of)\s+(?:it|them|him|her))?",
]
"""Changing into the other's lane just ahead of it (Euro NCAP's cut-in); "pulls out in front of @7" is a pull-out
(from a side road, not a lane beside it: `_PULL_OUT`)."""

_PASS_VERBS = verb(
    "overtake", "pass", "get past", "go past", "get by", "go by", "get round", "go round", "get around", "go around",
    "race past", "speed past", "zoom past", "blow past", "shoot past", "drive past", "whizz past", "whiz past",
    "undertake", "outpace", "overhaul",
)  # fmt: skip
_FILLER_WORDS = r"(?:(?:sharply|suddenly|abruptly|quickly|immediately|right\s+away|aggressively)\s+)*"
_SAME = r"(?:it|them|him|her|(?P=other))"
"""The other agent named again after a pass ("overtakes @7 and cuts in front of it")."""
_THEN = r"(?:\s*,)?\s+(?:and\s+then|and|then|before|to)\s+"
_ITS_LANE = (
    rf"(?:back\s+)?(?:in)?to\s+(?:its|their|his|her|{_SAME}'s)\s+lane\b"
    rf"(?:\s+(?:right\s+|just\s+)?(?:in\s+front\s+of|ahead\s+of)\s+{_SAME})?"
)
_CUT_BACK = (
    rf"(?:{_CUT_IN_VERBS}(?:\s+(?:in(?!\s+(?:front|on)\b)|{_CUT_MANNER}))*(?:\s+(?:{_JUST_AHEAD}|in\s+on)"
    rf"\s+{_SAME}|\s+{_ITS_LANE}|\s+(?:in|back)\b)?"
    rf"|{verb('move', 'pull', 'swing', 'swerve', 'get', 'go', 'steer', 'drift')}\s+{_ITS_LANE}"
    rf"|{verb('cut')}\s+(?:off\s+{_SAME}|{_SAME}\s+(?:off|up)))\b(?!\s+(?:in\s+)?(?:front|ahead|on|in)\b)"
)
"""The cut back in after a pass: "cuts in (front of it)", "pulls in ahead of it", "moves into its lane", "cuts it
off"."""
_OVERTAKE_CUT_IN = [
    rf"\b{_PASS_VERBS}\s+{_OTHER}{_THEN}{_FILLER_WORDS}{_CUT_BACK}",
    rf"\b{_PASS_VERBS}(?:{_THEN}|\s+){_FILLER_WORDS}{_CUTS_IN}\s+{_OTHER}",
    rf"\b{_CUTS_IN}\s+{_OTHER}(?:\s*,)?\s+(?:(?:right|just)\s+)?(?:after|once)"
    rf"\s+{verb('overtake', 'pass', 'get past', 'go past')}\s+{_SAME}",
    rf"\b{_PASS_VERBS}\s+{_OTHER}\s+and\s+{verb('cut')}\s+{_SAME}\s+(?:off|up)\b",
]
"""Passing the other and then changing into its lane just ahead of it: "overtakes @7 and cuts in front of it",
"passes @7, then pulls in ahead of it", "overtakes and cuts in front of @7", "cuts in front of @7 after passing it"
(NHTSA's lane-change pre-crash scenarios)."""

_IN_FRONT = r"(?:(?:right|just|directly|immediately)\s+)?(?:in\s+front\s+of|ahead\s+of)"
_HARD = r"(?:hard|sharply|suddenly|abruptly|heavily|violently|harshly|fiercely|firmly|urgently|all\s+of\s+a\s+sudden)"
_DECELERATION_WORDS = r"(?:\s+(?:at|with|by)\s+(?:a\s+deceleration\s+of\s+)?[\d.]+\s*(?:m/s\^?2|m/s²|m/s/s|g)(?!\w))"
"""A deceleration the text gives ("at 6 m/s^2", "at 0.5 g"), read by `read.py`'s `_DECELERATION`."""
_BRAKE_HARD = [
    rf"\b{verb('brake', 'stop', 'decelerate')}(?:(?:\s+{_HARD})+(?:\s+and\s+{_HARD})?{_DECELERATION_WORDS}?"
    rf"|{_DECELERATION_WORDS})\s+{_IN_FRONT}\s+{_OTHER}",
    rf"\b{verb('slam on', 'stamp on', 'jam on', 'stand on', 'mash', 'hit', 'smash')}\s+(?:the|its|their|his|her)"
    rf"\s+brakes?{_TIGHT_GAP}\s+{_IN_FRONT}\s+{_OTHER}",
    rf"\b{verb('do', 'make', 'perform', 'carry out', 'execute')}\s+an?\s+(?:emergency|hard|sudden|panic|abrupt)"
    rf"\s+(?:stop|brake|braking\s+manoeuvre|braking\s+maneuver|braking){_TIGHT_GAP}\s+{_IN_FRONT}\s+{_OTHER}",
    rf"\b{verb('brake-check', 'brake check', 'brake test', 'brake-test')}\s+{_OTHER}",
    rf"\b{verb('force', 'make', 'cause')}\s+{_OTHER}\s+to\s+(?:brake|slow\s+down|stop|slam\s+on\s+the\s+brakes)\b"
    rf"(?:\s+{_HARD})?",
]
"""Braking hard in the other's lane just ahead of it (Euro NCAP's braking lead vehicle): "brakes hard in front of
@7", "slams on the brakes ahead of @7", "brake-checks @7", "forces @7 to brake"."""

_TAILGATE = [
    rf"\b{verb('tailgate')}\s+{_OTHER}",
    rf"\b{verb('follow', 'drive', 'stay', 'sit', 'keep', 'travel', 'ride', 'tail')}"
    rf"\s+(?:far\s+|way\s+|much\s+)?(?:too|dangerously|aggressively|uncomfortably|very|really|extremely)\s+"
    rf"close(?:ly)?\s+(?:behind|to|on|after)\s+{_OTHER}",
    rf"\b{verb('follow', 'tail')}\s+{_OTHER}\s+(?:far\s+|way\s+|much\s+)?(?:too|dangerously|aggressively"
    r"|uncomfortably|very|really|extremely)\s+close(?:ly)?\b",
    rf"\b{verb('ride', 'sit on', 'hug', 'crowd')}\s+{_OTHER}'s\s+(?:bumper|tail|rear)\b",
    rf"\b{verb('ride', 'sit on', 'hug', 'crowd')}\s+the\s+(?:bumper|tail|rear)\s+of\s+{_OTHER}",
    rf"\b{verb('sit', 'stay', 'drive', 'be')}\s+(?:right\s+)?on\s+{_OTHER}'s\s+(?:bumper|tail)\b",
]
"""Following the other too closely (the detector's tailgating: under 0.6 s of headway at speed)."""

_RED = r"(?:a\s+|the\s+|its\s+|their\s+)?(?:red\s+(?:light|signal|traffic\s+light)s?|red|stop\s+light|light\s+on\s+red)"
_WHOSE_PATH = rf"(?:the\s+(?:path|way|lane)\s+of\s+)?{_OTHER}(?:'s\s+(?:path|way|lane))?"
_ACROSS = rf"(?:across|into|through|in\s+front\s+of|ahead\s+of|right\s+in\s+front\s+of|before)\s+{_WHOSE_PATH}"
_RED_VERBS = verb(
    "run", "jump", "skip", "ignore", "blow through", "blow", "go through", "drive through", "speed through",
    "race through", "shoot through", "cross on", "go on", "drive on", "run through", "disregard",
)  # fmt: skip
_RUN_RED_LIGHT = [
    rf"\b{_RED_VERBS}\s+{_RED}(?!\w)",
    rf"\b{_RED_VERBS}\s+{_RED}{_TIGHT_GAP}\s+{_ACROSS}",
    rf"\b{verb('cross', 'enter', 'go through', 'drive through', 'pass through', 'cut across', 'drive across')}"
    rf"\s+(?:the\s+)?(?:junction|intersection|crossing)\s+(?:on|against|through)\s+(?:a\s+|the\s+)?red"
    rf"(?:\s+light)?{_TIGHT_GAP}\s+{_ACROSS}",
    rf"\b{verb('cross', 'cut across', 'pull across', 'drive across')}\s+{_WHOSE_PATH}\s+(?:on|against|through)"
    r"\s+(?:a\s+|the\s+)?red(?:\s+light)?\b",
]
"""Running a red light across the other's path (NHTSA's running-a-red-light pre-crash scenario): "runs the red light
across @7's path", "jumps the red in front of @7", "crosses the junction on red in front of @7", "cuts across @7's
path on a red light"; or "runs the red light" alone, the other agent the one other mention ("ignores the red light
and goes in front of @7")."""

_PULL_OUT_VERBS = verb(
    "pull out", "nose out", "edge out", "creep out", "inch out", "emerge", "come out", "turn out", "shoot out",
    "dart out", "lurch out", "roll out", "back out", "reverse out", "pull away",
)  # fmt: skip
_PLACE = (
    r"(?:a|an|the|its|their|his|her)\s+(?:[\w-]+\s+)?(?:side\s+road|side\s+street|road|street|driveway|drive|junction"
    r"|intersection|parking\s+(?:spot|space|lot|bay)|car\s+park|kerb|curb|lane|alley|alleyway|entrance|exit|gate"
    r"|garage|forecourt|minor\s+road|t-junction)"
)
_FROM_PLACE = (
    rf"(?:\s+(?:of|from|out\s+of)\s+{_PLACE})?"
    r"(?:\s+(?:in)?to\s+(?:the\s+)?(?:road|street|traffic|lane|main\s+road))?"
)
_PULL_OUT = [
    rf"\b{_PULL_OUT_VERBS}(?:\s+(?:suddenly|right|just|sharply|abruptly|quickly|blindly|straight))*{_FROM_PLACE}"
    rf"\s+(?:{_IN_FRONT}|(?:in)?to\s+the\s+(?:path|way)\s+of|across\s+the\s+path\s+of)\s+{_OTHER}",
    rf"\b{_PULL_OUT_VERBS}(?:\s+(?:suddenly|right|just|sharply|abruptly|quickly|blindly|straight))*{_FROM_PLACE}"
    rf"\s+(?:in)?to\s+{_OTHER}'s\s+(?:path|way|lane)\b",
    rf"\b{verb('pull', 'turn', 'come', 'drive', 'emerge')}\s+(?:(?:left|right)\s+)?(?:out\s+)?(?:of|from|out\s+of)"
    rf"\s+{_PLACE}"
    rf"{_TIGHT_GAP}\s+{_IN_FRONT}\s+{_OTHER}",
]
"""Pulling out in front of the other from a side road, a driveway or the kerb (NHTSA's pre-crash scenarios at
non-signalized junctions): "pulls out in front of @7", "pulls out of the side road into the path of @7", "noses out
of a driveway into @7's lane", "emerges from the junction right in front of @7", "turns left out of the side road in
front of @7"."""

_YIELD = [
    rf"\b{verb('yield', 'give way', 'defer', 'cede', 'submit')}"
    rf"(?:\s+(?:the\s+)?(?:right\s+of\s+way|right-of-way|priority|precedence|the\s+junction))?\s+(?:to|for)\s+{_OTHER}",
    rf"\b{verb('give up', 'hand over', 'surrender', 'concede')}\s+(?:the\s+|its\s+)?(?:right\s+of\s+way|right-of-way"
    rf"|priority|precedence)\s+to\s+{_OTHER}",
    rf"\b{verb('give', 'grant', 'leave', 'offer')}\s+{_OTHER}\s+(?:the\s+|its\s+)?(?:right\s+of\s+way|right-of-way"
    r"|priority|precedence|way|room|space|the\s+go-ahead|a\s+chance|the\s+gap)\b",
    rf"\b{verb('let', 'allow', 'permit', 'wave', 'invite')}\s+{_OTHER}\s+(?:to\s+)?"
    r"(?:through|by|past|in|ahead|out|on|over|first|[a-z]+)\b"
    r"(?:\s+(?:first|by|past|through|ahead(?!\s+of)|across|in\s+front|over|on|in|(?:the|its)\s+(?:right\s+of\s+way|turn)"
    r"|priority))*",
    rf"\b(?:{verb('wait', 'stop', 'slow', 'brake', 'hold', 'pause', 'halt', 'hang', 'stay', 'sit', 'hover')}"
    rf"(?:\s+(?:down|back|off|up|hard|\w+ly))?|{verb('make', 'leave')}\s+(?:room|way|space|a\s+gap))"
    rf"{_gap(4)}\s+(?:for|until|till)\s+{_OTHER}",
    rf"\b{verb('hang', 'hold', 'stay', 'keep', 'sit', 'wait', 'hover', 'drop')}\s+back\b(?:{_TIGHT_GAP}{_OTHER})?",
    rf"\b(?:so|so\s+that|allowing|letting|to\s+let|and\s+let)\s+{_OTHER}\s+(?:can\s+|could\s+|may\s+|is\s+able\s+to\s+)?"
    r"(?:go|pass|cross|proceed|get\s+(?:by|past|through|in)|merge|enter|clear|through|by|past)\w*"
    r"(?:\s+(?:first|by|past|through|ahead(?!\s+of)|across|in))*",
    rf"\b{verb('wait')}\s+(?:{_POSSESSIVE})\s+turn\b(?:\s+(?:behind|after)\s+{_OTHER})?",
    rf"\bafter\s+{_OTHER}\s+(?:has\s+|have\s+)?(?:passed|gone|crossed|cleared|gone\s+by|gone\s+through|got\s+through)\b",
    rf"\b{verb('yield', 'give way')}\b",
]

_BEHIND_VERBS = verb(
    "stay", "keep", "remain", "drive", "travel", "sit", "tuck", "fall", "slot", "hang", "queue", "ride", "drop",
    "settle", "line", "tag", "creep", "cruise", "trundle",
)  # fmt: skip
_FOLLOW = [
    rf"\b{verb('follow', 'trail', 'tail', 'shadow')}\s+(?:(?:close(?:ly)?\s+)?(?:behind|after)\s+)?{_OTHER}",
    rf"\b{_BEHIND_VERBS}"
    rf"(?:\s+(?:in|back|up|right|directly|close|closely|just|along))*\s+behind\s+{_OTHER}",
    rf"\b{verb('keep', 'maintain', 'hold')}\s+(?:a\s+)?(?:safe\s+|steady\s+|constant\s+|good\s+)?(?:distance|gap)"
    rf"\s+(?:behind|to)\s+{_OTHER}",
    rf"\b(?:in\s+the\s+(?:wake|tracks|footsteps)\s+of|on\s+the\s+tail\s+of)\s+{_OTHER}",
]


def _build_rules() -> tuple[_Rule, ...]:
    specs: list[tuple[Behaviour, str]] = []
    for side, turn, change in (
        ("left", Behaviour.TURN_LEFT, Behaviour.LANE_CHANGE_LEFT),
        ("right", Behaviour.TURN_RIGHT, Behaviour.LANE_CHANGE_RIGHT),
    ):
        specs += [(turn, p) for p in _turn(side)]
        specs += [(change, p) for p in _lane_change(side)]
    specs += _lane_from_to()
    for behaviour, patterns in (
        (Behaviour.GO_STRAIGHT, _STRAIGHT),
        (Behaviour.STOP, _STOP),
        (Behaviour.PULL_OVER, _PULL_OVER),
        (Behaviour.SPEED_UP, _SPEED_UP),
        (Behaviour.SLOW_DOWN, _SLOW_DOWN),
        (Behaviour.OVERTAKE_CUT_IN, _OVERTAKE_CUT_IN),  # before the cut-in it ends with
        (Behaviour.CUT_IN, _CUT_IN),  # before going first: "cuts in ahead of @7" is a cut-in
        (Behaviour.BRAKE_HARD, _BRAKE_HARD),
        (Behaviour.TAILGATE, _TAILGATE),  # before following
        (Behaviour.RUN_RED_LIGHT, _RUN_RED_LIGHT),  # before going first
        (Behaviour.PULL_OUT, _PULL_OUT),  # before going first
        (Behaviour.GO_FIRST, _GO_FIRST),
        (Behaviour.YIELD, _YIELD),
        (Behaviour.FOLLOW, _FOLLOW),
    ):
        specs += [(behaviour, p) for p in patterns]
    return tuple(_Rule(b, re.compile(p)) for b, p in specs)


RULES = _build_rules()

_CHANGE_AND_SPEED = frozenset(
    {Behaviour.LANE_CHANGE_LEFT, Behaviour.LANE_CHANGE_RIGHT, Behaviour.SPEED_UP, Behaviour.SLOW_DOWN}
)
SUBSUMES: dict[Behaviour, frozenset[Behaviour]] = {
    Behaviour.PULL_OVER: frozenset({Behaviour.STOP, Behaviour.SLOW_DOWN}),
    Behaviour.STOP: frozenset({Behaviour.SLOW_DOWN}),
    Behaviour.YIELD: frozenset({Behaviour.STOP, Behaviour.SLOW_DOWN}),
    Behaviour.GO_FIRST: frozenset({Behaviour.SPEED_UP}),
    Behaviour.FOLLOW: frozenset({Behaviour.SLOW_DOWN, Behaviour.SPEED_UP}),
    Behaviour.CUT_IN: _CHANGE_AND_SPEED,
    Behaviour.OVERTAKE_CUT_IN: frozenset({Behaviour.CUT_IN, Behaviour.GO_FIRST}) | _CHANGE_AND_SPEED,
    Behaviour.BRAKE_HARD: frozenset({Behaviour.STOP, Behaviour.SLOW_DOWN}),
    Behaviour.TAILGATE: frozenset({Behaviour.FOLLOW, Behaviour.SPEED_UP, Behaviour.SLOW_DOWN}),
    Behaviour.RUN_RED_LIGHT: frozenset({Behaviour.GO_FIRST, Behaviour.SPEED_UP, Behaviour.GO_STRAIGHT}),
    Behaviour.PULL_OUT: frozenset({Behaviour.GO_FIRST, Behaviour.SPEED_UP, Behaviour.TURN_LEFT, Behaviour.TURN_RIGHT}),
}
"""A kind that, asked with another, is part of it: "pulls over and stops", "brakes to let @7 pass"."""

NEGATION = re.compile(
    r"\b(?:not|never|no\s+longer|without|neither|nor|cannot|no|refuses?\s+to|refusing\s+to|fails?\s+to"
    r"|avoid(?:s|ing)?)\b|n't\b"
)
CONTRAST = re.compile(r"\b(?:instead\s+of|rather\s+than)\b[^,;.!?]*")
"""What follows 'instead of' in its clause is what the prompt does not ask ("goes straight instead of turning")."""
PASSIVE = re.compile(rf"\b(?:is|are|was|were|be|been|being|gets?|got)\b[^,;.!?]*?\bby\s+{SLOT}")
"""A passive clause naming an agent ("@7 is followed by @12"): who does what is not read."""


THEN_KINDS: dict[Behaviour, frozenset[Behaviour]] = {
    kind: frozenset({Behaviour.STOP})
    for kind in (
        Behaviour.TURN_LEFT,
        Behaviour.TURN_RIGHT,
        Behaviour.GO_STRAIGHT,
        Behaviour.LANE_CHANGE_LEFT,
        Behaviour.LANE_CHANGE_RIGHT,
    )
}
"""What may follow a manoeuvre asked of one agent in one clause ("turns left and then stops", "changes to the left
lane and stops"): the manoeuvre is steered and judged first, then the stop past it (`interdrive.targets.stop_after`)."""
