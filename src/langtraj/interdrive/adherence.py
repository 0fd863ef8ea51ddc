"""Prompt adherence: whether a sampled future shows what its prompt says.

A prompt states facts: the single-agent label keys of its target agent and, for an interaction prompt,
the interaction (target, other, subtype). The labelers that made the prompt (the heuristics and the
rule-based detector) read a sample's future, and the sample follows the prompt when every fact is
found there. Only facts the labelers also find on the logged future are checked, so a fact they
cannot reproduce (a SUMO ground-truth interaction the detector misses) is not counted as a miss. A lane
change whose lane positions tell its side also holds the fact `changing_lanes:left` or `changing_lanes:right`
(`lane_change_key`), so a counterfactual prompt can ask for a side (`interdrive.counterfactual`).

This measures instruction following directly (minADE only does so through the logged future), and,
applied to samples drawn without text, bounds what any text-conditioned model could gain from the
labels (`langtraj.experiments.text_gain`).

See docs/interdrive.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

from langtraj.interdrive.dataset import PromptEntry, WindowRecord
from langtraj.interdrive.detector import DetectorConfig, detect_interactions
from langtraj.interdrive.heuristics import HeuristicConfig, label_agents
from langtraj.interdrive.labels import AgentLabel, InteractionLabel
from langtraj.interdrive.taxonomy import LANE_POSITIONS
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario

Fact = tuple[str, int, str] | tuple[str, int, int, str]
"""("label", track, key) or ("interaction", track, other, subtype id)."""

_ACROSS = LANE_POSITIONS[:3]
"""Lane positions from left to right ("single" has no side)."""


def lane_change_side(params: Mapping[str, str]) -> Literal["left", "right"] | None:
    """The side a `changing_lanes` label moves to, from its `from`/`to` lane positions; None where they do
    not order (middle to middle on a road of four lanes or more, or a single lane)."""
    src, dst = params.get("from"), params.get("to")
    if src not in _ACROSS or dst not in _ACROSS or src == dst:
        return None
    return "left" if _ACROSS.index(dst) < _ACROSS.index(src) else "right"


def lane_change_key(side: str) -> str:
    """The fact key of a lane change to `side` ("changing_lanes:left"): `label_facts` adds it beside the
    plain `changing_lanes` key, so a prompt can ask for a direction."""
    return f"changing_lanes:{side}"


def prompt_facts(prompt: PromptEntry) -> frozenset[Fact]:
    """What `prompt` states: each label key of its target (the first agent it mentions) and, when it
    is an interaction prompt naming a second agent, the interaction of the target with that agent."""
    if not prompt.mentions:
        return frozenset()
    target = prompt.mentions[0]
    facts: set[Fact] = {("label", target, key) for key in prompt.labels}
    if prompt.subtype is not None and len(prompt.mentions) > 1:
        facts.add(("interaction", target, prompt.mentions[1], prompt.subtype))
    return frozenset(facts)


def label_facts(labels: Iterable[AgentLabel], interactions: Iterable[InteractionLabel]) -> frozenset[Fact]:
    """The facts a window's labels hold (label keys per track, interactions per ordered pair); a lane
    change whose side `lane_change_side` tells also holds `lane_change_key(side)`."""
    labels = tuple(labels)
    facts: set[Fact] = {("label", lab.track_id, lab.key) for lab in labels}
    for lab in labels:
        side = lane_change_side(lab.params) if lab.key == "changing_lanes" else None
        if side is not None:
            facts.add(("label", lab.track_id, lane_change_key(side)))
    facts |= {("interaction", i.track_id, i.other_id, i.subtype.id) for i in interactions}
    return frozenset(facts)


def prompt_for_sentence(record: WindowRecord, track: int, sentence: str) -> PromptEntry | None:
    """The first prompt of `record`'s pool whose role sentence for `track` is `sentence` (a sample
    carries only the sentence), or None."""
    for prompt in record.prompts:
        if prompt.roles.get(track) == sentence:
            return prompt
    return None


@dataclass
class AdherenceChecker:
    """Reads facts from futures of one scenario window with the labelers' default settings; the map
    index is built once and shared by every sample of the window."""

    scenario: Scenario
    map_index: MapIndex
    logged: frozenset[Fact]
    heuristics: HeuristicConfig
    detector: DetectorConfig

    @classmethod
    def build(
        cls,
        scenario: Scenario,
        heuristics: HeuristicConfig | None = None,
        detector: DetectorConfig | None = None,
        map_index: MapIndex | None = None,
        *,
        logged: bool = True,
    ) -> AdherenceChecker:
        """The checker of `scenario` with its logged facts (`logged` False: none, one labelling saved where no prompt
        is checked against the log); `map_index` may be passed to reuse one."""
        heuristics = heuristics or HeuristicConfig()
        detector = detector or DetectorConfig()
        index = map_index or MapIndex.build(scenario.road_map, infer_neighbors=heuristics.infer_neighbors)
        checker = cls(scenario, index, frozenset(), heuristics, detector)
        if logged:
            checker.logged = checker.facts(scenario)
        return checker

    def facts(self, scenario: Scenario) -> frozenset[Fact]:
        """Every fact the labelers find in `scenario`'s future (the window with some future replaced)."""
        labels, _ = label_agents(scenario, self.heuristics, self.map_index)
        return label_facts(labels, detect_interactions(scenario, labels, self.detector, self.map_index))

    def checkable(self, prompt: PromptEntry) -> frozenset[Fact]:
        """The prompt's facts that the labelers reproduce on the logged future."""
        return prompt_facts(prompt) & self.logged

    @staticmethod
    def follows(wanted: frozenset[Fact], found: frozenset[Fact]) -> bool:
        """Whether every wanted fact is among the found ones."""
        return wanted <= found
