"""Instruction following in closed loop: whether simulated rollouts do what their prompts ask, judged by the labelers.

A rollout becomes a scenario whose future is the rollout (`rollout_scenario`); the labelers that make the
InterDrive labels (the heuristic single-agent labeler and the rule-based interaction detector, through
`interdrive.adherence.AdherenceChecker`) read it, and a prompt is followed in that rollout when every fact that
judges it (`interdrive.counterfactual.behaviour_facts`) is found there. The instruction-following rate (IFR) of a
behaviour kind is the mean, over its prompts, of the share of a prompt's rollouts that follow it; the macro IFR is
the mean over the kinds that have prompts. GT-IFR is over ground-truth prompts (what the log shows), F-IFR over
feasible counterfactual ones. Judging the rollouts of a run without the prompt gives the base rate (how often the
agent does it unasked).

See docs/interdrive.md ('Counterfactual prompts and instruction following').
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.adherence import AdherenceChecker, Fact
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.counterfactual import Alternative
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import Agents, Scenario
from langtraj.scenario.types import StateField


def rollout_scenario(scenario: Scenario, rollouts: Rollouts, rollout: int) -> Scenario:
    """The scenario with its future replaced by rollout `rollout`: each rollout agent's poses (speed from its
    positions) fill the steps after the current one, up to the scenario's last step; agents that are not in the
    rollouts are hidden after the current step (as in a simulation, which moves only the sim agents)."""
    if not 0 <= rollout < rollouts.num_rollouts:
        raise InputError(f"rollout {rollout} of {rollouts.num_rollouts}", where="rollout")
    c = scenario.current_index
    steps = min(rollouts.num_steps, scenario.num_steps - c - 1)
    rows = np.array([scenario.agents.index_of(int(i)) for i in rollouts.object_id], np.int64)
    states = scenario.agents.states.copy()
    valid = scenario.agents.valid.copy()
    cols = np.arange(c + 1, c + 1 + steps)
    xy = np.stack([rollouts.x[rollout, :, :steps], rollouts.y[rollout, :, :steps]], -1).astype(np.float64)
    before = states[rows, c, : StateField.Y + 1].astype(np.float64)[:, None]
    dt = np.diff(scenario.timestamps[c : c + 1 + steps]).reshape(1, -1)
    speed = np.linalg.norm(np.diff(np.concatenate([before, xy], 1), axis=1), axis=-1) / np.maximum(dt, 1e-6)
    poses = np.concatenate([xy, rollouts.heading[rollout, :, :steps, None], speed[..., None]], -1)
    block = states[rows][:, cols]
    Agents.write_poses(block, poses)
    block[..., StateField.Z] = rollouts.z[rollout, :, :steps]
    sizes = [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]
    block[..., sizes] = states[rows, c][:, None, sizes]
    states[rows[:, None], cols[None, :]] = block
    others = np.setdiff1d(np.arange(scenario.num_agents), rows)
    valid[others, c + 1 :] = False
    valid[rows[:, None], cols[None, :]] = True
    return replace(scenario, agents=replace(scenario.agents, states=states, valid=valid))


@dataclass(frozen=True)
class Judgement:
    """Whether rollout `rollout` of scenario `scenario_id` follows the prompt asking `track_id` for `behaviour`
    (judged by `facts`; `missing` are those not found); `ground_truth` when the log shows the behaviour."""

    scenario_id: str
    track_id: int
    behaviour: Behaviour
    ground_truth: bool
    facts: frozenset[Fact]
    rollout: int
    followed: bool
    missing: frozenset[Fact] = frozenset()

    @property
    def prompt_key(self) -> tuple[str, int, str, tuple[Fact, ...]]:
        """What identifies the prompt across its rollouts."""
        return self.scenario_id, self.track_id, self.behaviour.value, tuple(sorted(self.facts, key=str))

    def to_json(self) -> dict[str, Any]:
        return {
            "scenario_id": self.scenario_id,
            "track_id": self.track_id,
            "behaviour": self.behaviour.value,
            "ground_truth": self.ground_truth,
            "facts": [list(f) for f in sorted(self.facts, key=str)],
            "rollout": self.rollout,
            "followed": self.followed,
            "missing": [list(f) for f in sorted(self.missing, key=str)],
        }


def judge_rollouts(
    scenario: Scenario,
    rollouts: Rollouts,
    prompts: Sequence[Alternative],
    *,
    checker: AdherenceChecker | None = None,
) -> tuple[Judgement, ...]:
    """Judge every prompt on every rollout of `rollouts` (one labelling per rollout); `checker`, when given, is
    the scene's `AdherenceChecker` (its map index and labeler settings are reused). A prompt about an agent the
    rollouts do not hold raises InputError."""
    present = set(int(i) for i in rollouts.object_id)
    for prompt in prompts:
        named = {prompt.track_id} | ({prompt.other_id} if prompt.other_id is not None else set())
        if not named <= present:
            missing = ", ".join(f"@{t}" for t in sorted(named - present))
            raise InputError(f"the rollouts hold no track {missing} ({prompt.behaviour.value} prompt)", where="prompts")
    if not prompts:
        return ()
    checker = checker or AdherenceChecker.build(scenario)
    out = []
    for r in range(rollouts.num_rollouts):
        found = checker.facts(rollout_scenario(scenario, rollouts, r))
        for prompt in prompts:
            missing = prompt.facts - found
            out.append(
                Judgement(
                    scenario.scenario_id,
                    prompt.track_id,
                    prompt.behaviour,
                    prompt.logged,
                    prompt.facts,
                    r,
                    not missing,
                    frozenset(missing),
                )
            )
    return tuple(out)


@dataclass(frozen=True)
class KindRate:
    """IFR of one behaviour kind: the mean over its `prompts` of each one's share of followed rollouts
    (`judgements` rollouts judged in all)."""

    behaviour: Behaviour
    ifr: float
    prompts: int
    judgements: int

    def to_json(self) -> dict[str, Any]:
        return {"ifr": self.ifr, "prompts": self.prompts, "judgements": self.judgements}


@dataclass(frozen=True)
class IFRGroup:
    """IFR per behaviour kind (in `BEHAVIOURS` order, kinds without prompts left out) and their macro average
    (None without prompts), over one group of prompts (ground-truth or counterfactual)."""

    per_kind: tuple[KindRate, ...]
    macro: float | None
    prompts: int
    judgements: int

    @classmethod
    def of(cls, judgements: Iterable[Judgement]) -> IFRGroup:
        by_prompt: dict[tuple[str, int, str, tuple[Fact, ...]], list[Judgement]] = {}
        for judgement in judgements:
            by_prompt.setdefault(judgement.prompt_key, []).append(judgement)
        by_kind: dict[Behaviour, list[list[Judgement]]] = {}
        for group in by_prompt.values():
            by_kind.setdefault(group[0].behaviour, []).append(group)
        rates = []
        for behaviour in BEHAVIOURS:
            groups = by_kind.get(behaviour)
            if not groups:
                continue
            shares = [float(np.mean([j.followed for j in g])) for g in groups]
            rates.append(KindRate(behaviour, float(np.mean(shares)), len(groups), sum(len(g) for g in groups)))
        macro = float(np.mean([r.ifr for r in rates])) if rates else None
        return cls(tuple(rates), macro, len(by_prompt), sum(r.judgements for r in rates))

    def rate(self, behaviour: Behaviour) -> KindRate | None:
        return next((r for r in self.per_kind if r.behaviour is behaviour), None)

    def to_json(self) -> dict[str, Any]:
        return {
            "macro": self.macro,
            "prompts": self.prompts,
            "judgements": self.judgements,
            "per_kind": {r.behaviour.value: r.to_json() for r in self.per_kind},
        }


@dataclass(frozen=True)
class IFRReport:
    """GT-IFR (`ground_truth`: prompts the log shows) and F-IFR (`counterfactual`: feasible prompts it does not)."""

    ground_truth: IFRGroup
    counterfactual: IFRGroup

    def to_json(self) -> dict[str, Any]:
        return {"gt_ifr": self.ground_truth.to_json(), "f_ifr": self.counterfactual.to_json()}


def instruction_following(judgements: Iterable[Judgement]) -> IFRReport:
    """GT-IFR and F-IFR per behaviour kind and macro-averaged, with counts, from judged rollouts."""
    judgements = tuple(judgements)
    return IFRReport(
        IFRGroup.of(j for j in judgements if j.ground_truth),
        IFRGroup.of(j for j in judgements if not j.ground_truth),
    )
