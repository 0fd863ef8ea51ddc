"""Words of a behaviour between two agents used with one agent only, which the reader names rather than drops: a pair
kind's words with no second agent ("@7 cuts in", "@7 tailgates") read as that kind needing one, as "@7 runs the red
light" does, and an overtake without a cut-in ("@7 overtakes @1"), which is no behaviour LangTraj steers. A strict
reading refuses both in one line (`refusal`).

See docs/interdrive.md ('Reading a prompt').
"""

from __future__ import annotations

import re

from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour

_PASS = (
    r"(?:overtak(?:e|es|ing|en)|overtook|undertak(?:e|es|ing|en)|undertook|pass(?:es|ed|ing)?"
    r"|(?:gets?|got|goes|go|went|going)\s+past)"
)
_LONE: tuple[tuple[str, str], ...] = (
    (
        "overtake_cut_in",
        rf"\b{_PASS}(?:\s+(?:and|then|and\s+then))?\s+cut(?:s|ting)?\s+in\b(?!\s+(?:front|ahead)\s+of)",
    ),
    ("cut_in", r"\bcut(?:s|ting)?\s+in(?:\s+(?:sharply|suddenly|front|ahead))*\b(?!\s+(?:front\s+|ahead\s+)?of\b)"),
    ("tailgate", r"\btailgat(?:e|es|ed|ing)\b"),
    ("pull_out", r"\b(?:pull|nose|edge)(?:s|ed|ing)?\s+out\s+(?:right\s+|just\s+)?(?:in\s+front|ahead)\b(?!\s+of\b)"),
)
"""A pair kind's words with nobody after them, matched on the normalised text (mentions as `<m0>`, ...)."""
_OVERTAKE = re.compile(rf"\b{_PASS}\s+(?:the\s+\w+\s+)?<m(\d+)>")

NEEDS_OTHER = "{kind} needs exactly one other agent"
"""The reason of a pair kind read without its other agent (as `read._pair_reading` gives it)."""
_NEEDS_OTHER = re.compile(r"^(\w+) needs exactly one other agent$")
OVERTAKE_ALONE = (
    "overtaking alone is not a behaviour LangTraj steers; say '@{agent} overtakes @{other} and cuts in front of it'"
)

_ROLES = {
    "yield": "whom it yields to",
    "go_first": "whom it goes before",
    "follow": "whom it follows",
    "cut_in": "whom it cuts in front of",
    "overtake_cut_in": "whom it overtakes and cuts in front of",
    "brake_hard": "who drives behind it",
    "tailgate": "whom it tailgates",
    "run_red_light": "whose path it crosses",
    "pull_out": "whom it pulls out in front of",
}


def lone_reason(text: str, ids: tuple[int, ...], asked: int | None) -> str | None:
    """Why the normalised `text` of a clause with no behaviour phrase read (`ids`: its mentions' tracks, `asked` the
    placeholder number of the agent asked) is not read, where it holds a pair kind's words alone or an overtake."""
    if asked is None:
        return None
    overtake = _OVERTAKE.search(text)
    if overtake and int(overtake.group(1)) != asked:
        return OVERTAKE_ALONE.format(agent=ids[asked], other=ids[int(overtake.group(1))])
    if len(set(ids)) != 1:
        return None
    for kind, pattern in _LONE:
        if re.search(pattern, text):
            return NEEDS_OTHER.format(kind=kind)
    return None


def refusal(reason: str, clause: str, mentions: int, agent: int | None) -> str | None:
    """The one line a strict reading refuses an unread clause with (`reason` its reader's, `mentions` the distinct
    agents it names): a pair kind with no second agent named, or an overtake alone; None for any other."""
    if reason.startswith(OVERTAKE_ALONE.split(";")[0]):
        return f"clause {clause!r} is not read: {reason}"
    lone = _NEEDS_OTHER.match(reason)
    if lone is None or mentions != 1 or agent is None:
        return None
    kind = Behaviour(lone.group(1))
    role = _ROLES.get(kind.value, "the other agent")
    example = BEHAVIOURS[kind].template.format(agent=agent, other="Y")
    return f"clause {clause!r}: {kind.value} needs a second agent: name {role}, e.g. {example!r}"
