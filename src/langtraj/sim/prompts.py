"""Typed `@id` prompts in a simulation: parsed against the scene, merged into one prompt entry (each driven agent's
sentence), checked against the agents the model drives, and read once each, clause by clause (`read_prompts`,
`interdrive.reader`). Those readings are what the map is asked about (a behaviour it does not allow where the agent is
is warned about, `PromptSteering.warnings`; a stop the prompt also asks for is kept on its own) and what steers the
simulation: each behaviour's target and the criteria selection judges by (`prompt_steering`; docs/simulation.md,
'Prompts that steer'). What the steering does at each replan is
`sim.prompt_replan`'s."""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.frames import Origin
from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.prompts import parse_user_prompt
from langtraj.interdrive.prompts.compose import MENTION
from langtraj.interdrive.reader import PromptReading, read_clauses
from langtraj.interdrive.reader.alone import refusal
from langtraj.interdrive.reader.spelling import did_you_mean
from langtraj.interdrive.reader.timing import condition_note, kind_of
from langtraj.interdrive.reader.when import trigger_of
from langtraj.interdrive.targets import (
    BehaviourTarget,
    Feasibility,
    TargetUnavailable,
    derive_target,
    feasibility,
    then_feasibility,
)
from langtraj.interdrive.triggers import AfterDone, AtTime, Now, WhenReady
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario
from langtraj.sim.adherence import Ask
from langtraj.sim.config import PromptLevers
from langtraj.sim.staging import Staged


def user_prompt_entry(scenario: Scenario, text: str) -> PromptEntry:
    """A typed `@id` prompt validated against the scene and role-rephrased for each mentioned agent."""
    prompt = parse_user_prompt(text, scenario.agents.ids.tolist())
    return PromptEntry.of(prompt)


def prompt_mentions(scenario: Scenario, prompts: Sequence[str]) -> list[int]:
    """The track ids the prompts name, in order of first mention, each once (whom a video or view highlights)."""
    named: list[int] = []
    for text in prompts:
        named += [m for m in user_prompt_entry(scenario, text).mentions if m not in named]
    return named


def merged_prompt(scenario: Scenario, prompts: Sequence[str]) -> PromptEntry | None:
    """One prompt entry from several typed prompts; an agent named by two prompts is an error."""
    entries = [user_prompt_entry(scenario, text) for text in prompts]
    if not entries:
        return None
    if len(entries) == 1:
        return entries[0]
    roles: dict[int, str] = {}
    for entry in entries:
        for track in entry.mentions:
            if track in roles:
                raise InputError(f"agent @{track} is named by two prompts; describe it in one", where="prompt")
            roles[track] = entry.roles[track]
    return PromptEntry("; ".join(e.text for e in entries), tuple(roles), roles, None, (), "user")


def check_prompt_driven(prompt: PromptEntry, driven_ids: Sequence[int], max_driven: int | None) -> None:
    """InputError naming the prompt's agents that are not among `driven_ids` (the model's agents: every
    sim agent, or the `max_driven` most important)."""
    outside = [m for m in prompt.mentions if m not in set(driven_ids)]
    if outside:
        which = (
            f"it drives the {max_driven} most important (--max-driven)"
            if max_driven is not None
            else "it drives the agents valid at the current step"
        )
        raise InputError(
            f"agents {', '.join(f'@{m}' for m in outside)} are not among the {len(driven_ids)} agents the model "
            f"drives in this scene ({which})",
            where="prompt",
        )


def read_prompts(texts: Sequence[str], *, strict: bool = True) -> tuple[PromptReading, ...]:
    """Each typed prompt read once, clause by clause (`interdrive.reader.read_clauses`): the readings its warnings,
    its guidance and its selection take. With `strict` (typed prompts), a clause of a prompt of several that cannot
    be read, an agent asked by two clauses, or timing words the reader does not honour (`PromptReading.condition`)
    are an InputError naming the clause or the words; a prompt of one clause that cannot be read steers by its text
    alone, unless `_unread_problem` refuses it. Without it (a dataset prompt's sentence), nothing is refused."""
    readings: list[PromptReading] = []
    asked: dict[int, PromptReading] = {}
    for text in texts:
        clauses = read_clauses(text)
        for i, reading in enumerate(clauses):
            if not strict:
                continue
            problem = None if reading.read else _unread_problem(reading)
            if problem is not None:
                raise InputError(problem, where="prompt")
            if reading.condition and reading.trigger is None:
                previous = clauses[i - 1].agent if i else None
                raise InputError(_timing_problem(text, reading, previous), where="prompt")
            _check_figures(text, reading)
            if len(clauses) > 1 and not reading.read:
                raise InputError(
                    f"clause {reading.clause!r} of {text!r} cannot be read ({reading.reason}); write each agent's "
                    "behaviour in words the reader knows (docs/interdrive.md, 'Reading a prompt')",
                    where="prompt",
                )
            if reading.read and reading.agent is not None:
                if reading.agent in asked:
                    raise InputError(
                        f"@{reading.agent} is asked twice ({asked[reading.agent].clause!r} and {reading.clause!r}); "
                        "ask each agent one behaviour",
                        where="prompt",
                    )
                asked[reading.agent] = reading
        readings += clauses
    return tuple(readings)


def _check_figures(text: str, reading: PromptReading) -> None:
    """A one-line InputError where the text asks a parameter outside its accepted range ("with a 50 m gap") or gives
    a figure the behaviour takes none of ("tailgates @7 at 5 m"): refused before the run, never dropped."""
    try:
        reading.asked()
    except InputError as exc:
        raise InputError(f"prompt {text!r}: {exc.detail}", where="prompt") from None
    unused = reading.unused_figures()
    if unused:
        raise InputError(
            f"prompt {text!r}: {', '.join(repr(u) for u in unused)} is not read: {reading.behaviour} takes no such "
            "figure (its parameters: "
            f"{', '.join(p.name for p in kind(str(reading.behaviour)).parameters) or 'none'}); remove it",
            where="prompt",
        )


def _timing_problem(text: str, reading: PromptReading, previous: int | None) -> str:
    """The one line refusing timing words that say no start LangTraj reads, after a clause asking `previous`
    (`reader.when.trigger_of` says why)."""
    where = f" (clause {reading.clause!r})" if reading.clause and reading.clause != text else ""
    if reading.agent is None:
        return f"prompt {text!r}{where}: the {kind_of(reading.condition)} {reading.condition!r} starts no behaviour"
    try:
        trigger_of(reading.condition, reading.agent, previous)
    except ValueError as exc:
        return f"prompt {text!r}{where}: {exc}"
    return f"prompt {text!r}{where}: the timing {reading.condition!r} is not read"


def _unread_problem(reading: PromptReading) -> str | None:
    """Why an unread clause is refused even alone rather than steering by its text: an agent named as both sides of
    a pair ("@5 yields to @5"), a pair behaviour with no second agent named or an overtake alone
    (`reader.alone.refusal`), or a misspelt reader word ("yeilds", `reader.spelling.did_you_mean`), or None."""
    mentions = MENTION.findall(reading.clause)
    repeated = next((m for m in mentions if mentions.count(m) > 1), None)
    if repeated is not None:
        return f"clause {reading.clause!r} names @{repeated} twice; a behaviour between two agents needs two agents"
    alone = refusal(reading.reason, reading.clause, len(set(mentions)), reading.agent)
    if alone is not None:
        return alone
    fixed = did_you_mean(reading.clause)
    if fixed is None:
        return None
    unknown = f"{', '.join(repr(typed) for typed, _ in fixed[1])} not a word the reader knows"
    return f"clause {reading.clause!r} cannot be read ({unknown}); did you mean {fixed[0]!r}?"


def _verdict(
    scenario: Scenario, reading: PromptReading, index: MapIndex, routes: Mapping[int, np.ndarray] | None = None
) -> Feasibility | None:
    """The map's one answer for a read behaviour: its target, or why there is none (None for a prompt not read), the
    agents with a known route (`routes`: an ego's mission) read on it."""
    if reading.behaviour is None or reading.agent is None:
        return None
    if BEHAVIOURS[reading.behaviour].is_pair and reading.other is None:
        return None
    verdict = feasibility(
        scenario,
        reading.agent,
        reading.behaviour,
        index,
        other_id=reading.other,
        gap=reading.metres,
        deceleration=reading.deceleration,
        routes=routes,
    )
    return verdict if reading.then is None else then_feasibility(verdict, reading.then)


def _fallback(
    scenario: Scenario, reading: PromptReading, verdict: Feasibility | None, index: MapIndex
) -> Feasibility | None:
    """Where the map gives a read behaviour no target, the first kind the prompt also asks for that it allows
    ("pulls over and comes to a stop" where no kerb is in reach: the stop, kept on its own); else `verdict`."""
    if verdict is None or verdict.target is not None or reading.agent is None:
        return verdict
    for also in reading.also:
        kept = feasibility(scenario, reading.agent, also, index)
        if kept.target is not None:
            return kept
    return verdict


def _warning(reading: PromptReading, verdict: Feasibility | None, kept: Feasibility | None = None) -> str | None:
    """The warning about a reading: one line when it asks of its agent a behaviour the map and the agents' states do
    not allow from where they are (a turn or lane change with no lane for it, a pull-over away from the kerb lane,
    slowing down while stopped, a cut-in onto a lane not beside its own, a red-light run where no signal shows red,
    a braking lead with no follower): "@12 cannot turn left: no left turn from its lane at the next junction ...",
    saying what is `kept` instead; for a pair behaviour also where the scene cannot tell ("... the scene has no
    traffic lights (the scene cannot tell)"). Where the map cannot tell a single-agent behaviour, and for a prompt
    not read, None. A warning
    does not stop a simulation: the model is conditioned on the prompt as typed, and a suite reports the scenario as
    not feasible rather than not followed."""
    if verdict is None or verdict.status == "feasible":
        return None
    if kept is not None and kept is not verdict:
        return f"{verdict.message}; its {BEHAVIOURS[kept.behaviour].manoeuvre} is kept on its own"
    if verdict.status == "undecided" and BEHAVIOURS[verdict.behaviour].is_pair:  # the scene lacks what it takes
        return f"{verdict.message} (the scene cannot tell)"
    return verdict.message if verdict.status == "infeasible" else None


@dataclass(frozen=True)
class PromptSteering:
    """What typed prompts steer in one simulation: what the reader made of each (`readings`), the guidance toward
    each read behaviour's target (`steerings`, when the guidance lever is on; for yielding or going first also the
    other agent's side of it), what selection judges (`asks`, when the selection lever is on), one line per prompt
    saying so (`notes`), the targets, and what the map does not allow of what they ask (`warnings`,
    `PromptSteering.warnings`)."""

    readings: tuple[PromptReading, ...] = ()
    steerings: tuple[Steering, ...] = ()
    asks: tuple[Ask, ...] = ()
    notes: tuple[str, ...] = ()
    targets: tuple[BehaviourTarget, ...] = ()
    warnings: tuple[str, ...] = ()
    sentences: dict[int, str] = field(default_factory=dict)
    """Track id -> the sentence the model is conditioned on in place of the typed words, for a read behaviour it never
    saw in training (`conditioning_sentence`)."""
    staged: tuple[Staged, ...] = ()
    """The read behaviours that start at their trigger (`sim.staging`), steered from the replan where it holds."""

    @property
    def kerb_slots(self) -> tuple[int, ...]:
        """Slots steered to the kerb (a pull-over): their target asks their box nearer the road edge than the hard
        constraints keep every other vehicle's (`KERB_MIN_CLEARANCE` against `HardConstraints.road_margin`)."""
        return tuple(s.slot for s in self.steerings if s.target.behaviour is Behaviour.PULL_OVER)

    @property
    def prompted_slots(self) -> tuple[int, ...]:
        """Slots a prompt steers or judges (with a pair behaviour's other agent): their manoeuvre is the prompt's, which
        the hard constraints' polish leaves as the projection made it (`HardConstraints.polish`)."""
        slots = {s.slot for s in self.steerings} | {a.slot for a in self.asks} | {a.other_slot for a in self.asks}
        slots |= {s.slot for s in self.staged}
        return tuple(sorted(slot for slot in slots if slot is not None))

    def to_json(self) -> dict[str, Any]:
        return {
            "read": [r.to_json() for r in self.readings],
            "targets": [t.to_json() for t in self.targets],
            "steering": list(self.notes),
        }


def prompt_steering(
    scenario: Scenario,
    readings: Sequence[PromptReading],
    rows: np.ndarray,
    origin: Origin,
    levers: PromptLevers,
    index: MapIndex | None = None,
    external: Collection[int] = (),
    routes: Mapping[int, np.ndarray] | None = None,
) -> PromptSteering:
    """From each typed prompt's reading (`read_prompts`): its behaviour's target, derived from the map (`index`,
    built here when not given) at the current step (`interdrive.targets`), as guidance and selection criteria for
    the driven agents `rows` (scenario rows in slot order), and the warnings about it (`warnings`). A prompt
    the reader cannot read, or whose target the map does not give, steers by the levers it can (text; selection
    still judges a read behaviour), and its note says so. A read agent the model does not drive is an InputError.
    `routes`: the routes the `external` agents drive (`SimWorld.routes`), which targets toward them read."""
    slots = {int(scenario.agents.ids[row]): slot for slot, row in enumerate(rows)}
    readings = tuple(readings)
    index = index if index is not None else MapIndex.build(scenario.road_map)
    steerings, asks, notes, targets, warnings = [], [], [], [], []
    sentences: dict[int, str] = {}
    asked = {r.agent for r in readings if r.read}
    staged: list[Staged] = []
    for reading in readings:
        reading = on_live_state(reading, external)
        if reading.trigger is not None and reading.read and reading.agent in slots:
            if not BEHAVIOURS[reading.behaviour].is_pair:  # the map's verdict on a manoeuvre holds later too
                verdict = _verdict(scenario, reading, index, routes)
                if (warning := _warning(reading, verdict, _fallback(scenario, reading, verdict, index))) is not None:
                    warnings.append(warning)
            if (warning := _holds_at_start(scenario, reading)) is not None:
                warnings.append(warning)
            staged.append(_staged(scenario, reading, slots, levers, len(asks)))
            if levers.selection:
                asks.append(staged[-1].ask_of)
            notes.append(
                f"{reading.describe()}; staged {reading.trigger.describe()}: its target from the agents' state then"
                + (", adherence-first selection from then" if levers.selection else "")
            )
            continue
        verdict = _verdict(scenario, reading, index, routes)
        steered = _fallback(scenario, reading, verdict, index)
        if (warning := _warning(reading, verdict, steered)) is not None:
            warnings.append(warning)
        if reading.behaviour is None or reading.agent is None:
            alone = "it steers by its text alone" if levers.text else "nothing steers it (the text lever is off)"
            head = f"not read: {reading.reason}" if reading.behaviour is None else reading.describe()
            head += f"; {condition_note(reading.condition)}" if reading.condition and not reading.read else ""
            notes.append(f"{head}; {alone}")
            continue
        if reading.agent not in slots:
            raise InputError(f"@{reading.agent} is not among the agents the model drives", where="prompt")
        other_row = None if reading.other is None else scenario.agents.index_of(reading.other)
        ask = Ask(
            reading.agent,
            scenario.agents.index_of(reading.agent),
            slots[reading.agent],
            reading.behaviour if steered is None else steered.behaviour,
            reading.other,
            other_row,
            None if reading.other is None else slots.get(reading.other),
            then=reading.then if steered is verdict else None,
        )
        used = ["text"] if levers.text else []
        if levers.guidance and steered is not None:
            target = steered.target
            if target is None:
                notes.append(f"{reading.describe()}; no target: {steered.message}")
            else:
                targets.append(target)
                steerings.append(Steering.of(target, origin, slots))
                sentence = conditioning_sentence(target) if levers.text else None
                if sentence is not None:
                    sentences[target.track_id] = sentence
                    used.append(f"the model conditioned on {sentence!r}")
                if steered is not verdict:
                    used.append(f"no target for it ({verdict.reason}), so its {target.behaviour.value} alone")
                used.append(f"guidance toward {target.reason}")
                counterpart, why = _counterpart(scenario, reading, slots, index, asked)
                if counterpart is not None:
                    steerings.append(Steering.of(counterpart, origin, slots))
                    used.append(f"@{counterpart.track_id} toward {counterpart.reason}")
                elif why:
                    used.append(f"@{reading.other} unsteered ({why})")
        if levers.selection:
            asks.append(ask)
            used.append("adherence-first selection")
        notes.append(f"{reading.describe()}; steered by {', '.join(used) or 'nothing'}")
    return PromptSteering(
        readings, tuple(steerings), tuple(asks), tuple(notes), tuple(targets), tuple(warnings), sentences, tuple(staged)
    )


def on_live_state(reading: PromptReading, external: Collection[int]) -> PromptReading:
    """`reading`, staged as soon as the scene allows it (`WhenReady`) where it puts its agent in the path of an
    `external` agent (an ego under a planner: `BehaviourKind.in_path`) and says no time: its target is then derived
    from where the planner has driven that agent, not where it was at the start (docs/simulation.md, 'Timing in
    words')."""
    if reading.trigger is not None or reading.condition or not reading.read or reading.other not in external:
        return reading
    return replace(reading, trigger=WhenReady()) if kind(str(reading.behaviour)).in_path else reading


def _holds_at_start(scenario: Scenario, reading: PromptReading) -> str | None:
    """The warning about a condition on the agents' state that holds at the start already ("when @ego is within 20 m
    of @35" with the ego 12 m behind): the behaviour starts at once, as OpenSCENARIO's conditions without an edge do,
    not when the condition comes about; None otherwise. Worded so that a suite does not read it as the scene ruling
    the behaviour out (`suites.happened.not_happened`)."""
    trigger = reading.trigger
    if trigger is None or isinstance(trigger, (AtTime, AfterDone, WhenReady)):
        return None
    start = Now(scenario, 0.0)
    if not trigger.holds(start):
        return None
    measured, behaviour = trigger.measured(start), Behaviour(reading.behaviour).value
    return (
        f"the start of @{reading.agent}'s {behaviour} ({trigger.describe()}) holds already at the start"
        + (f" ({measured})" if measured else "")
        + ": it starts at once, not when that comes about"
    )


def _staged(scenario: Scenario, reading: PromptReading, slots: dict[int, int], levers: PromptLevers, at: int) -> Staged:
    """A read behaviour that starts at its trigger (`sim.staging`): its ask (index `at`) judged from then."""
    assert reading.trigger is not None and reading.agent is not None and reading.behaviour is not None
    for track in reading.trigger.agents:
        scenario.agents.index_of(track)  # an unknown agent in the timing words is bad input, named
    other_row = None if reading.other is None else scenario.agents.index_of(reading.other)
    ask = Ask(
        reading.agent,
        scenario.agents.index_of(reading.agent),
        slots[reading.agent],
        reading.behaviour,
        reading.other,
        other_row,
        None if reading.other is None else slots.get(reading.other),
        then=reading.then,
    )
    return Staged(reading, reading.trigger, slots[reading.agent], at if levers.selection else None, ask)


def conditioning_sentence(target: BehaviourTarget) -> str | None:
    """The sentence the model is conditioned on for a target of a kind it never saw in training: that of the kind its
    spec names (`BehaviourSpec.conditioned_as`; a lane change to the side the target takes); None for a kind it
    knows."""
    kind = BEHAVIOURS[target.behaviour].conditioned_as
    if kind is None:
        return None
    if BEHAVIOURS[kind].is_lane_change and target.side is not None:
        kind = Behaviour.LANE_CHANGE_LEFT if target.side == "left" else Behaviour.LANE_CHANGE_RIGHT
    return BEHAVIOURS[kind].text(target.track_id, target.other_id)


_OPPOSITE = {Behaviour.YIELD: Behaviour.GO_FIRST, Behaviour.GO_FIRST: Behaviour.YIELD}


def _counterpart(
    scenario: Scenario, reading: PromptReading, slots: dict[int, int], index: MapIndex, asked: set[int | None]
) -> tuple[BehaviourTarget | None, str]:
    """For yielding or going first, the other agent's side of it (going first, or yielding) when the model drives
    it, no clause of its own asks it something (`asked`) and the map gives its target (a yield happens only if the
    other agent goes); else None and why (empty for a behaviour without a side for the other agent)."""
    opposite = _OPPOSITE.get(reading.behaviour)  # type: ignore[arg-type]
    if opposite is None or reading.agent is None:
        return None, ""
    if reading.other in asked:
        return None, ""
    if reading.other not in slots:
        return None, "the model does not drive it"
    try:
        target = derive_target(scenario, reading.other, opposite, index, other_id=reading.agent)  # type: ignore[arg-type]
    except TargetUnavailable as exc:
        return None, f"no target: {exc.detail}"
    return target, ""
