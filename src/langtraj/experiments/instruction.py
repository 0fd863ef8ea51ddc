"""Instruction following in closed loop (docs/experiments.md, 'Prompts that steer').

    langtraj experiment instruction-following --checkpoint CKPT --data NAME=LABELS_DIR[:SPLIT] \
        [--windows N] [--skip K] [--agents A] [--counterfactuals C] [--rollouts R] [--cfg W]
        [--conditions NAME,...] [--free-text PROMPTS.yaml] [--json OUT]
    langtraj experiment instruction-following --config configs/experiments/instruction-following.yaml

For each held-out window, up to `agents` driven vehicles (objects of interest first) get prompts from
`interdrive.counterfactual.feasible_alternatives`: what the log shows (ground truth) and up to
`counterfactuals` feasible behaviours it does not (turns the lane allows, lane changes into existing
lanes, stopping, pulling over, speeding up, slowing down, going first or yielding in a logged pair). Every
agent of the window is driven by the model, closed loop, once without a prompt and once per prompt and
condition (`CONDITIONS`: which of the prompt's levers are on); the labelers judge each rollout
(`metrics.instruction_following`). Without a prompt the same rollouts are judged against every prompt: the
rate at which the model does the asked thing anyway. Reported per condition: GT-IFR and F-IFR (macro over
behaviour kinds, and per kind), the WOSAC 2025 meta-metric and buckets, the prompted agents' collision and
offroad rates and minADE under their ground-truth prompts, and seconds per simulation.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from langtraj.errors import InputError
from langtraj.experiments.base import EXPERIMENTS, Experiment
from langtraj.experiments.common import (
    DatasetSpec,
    SimulationSettings,
    cell,
    held_out_windows,
    markdown_table,
    require_counts,
    wosac_figures,
)
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import Alternative, feasible_alternatives
from langtraj.interdrive.free_text import FreeTextPrompt, load_free_text_prompts
from langtraj.metrics.controllability import agent_rates, min_ade
from langtraj.metrics.features import SceneMap
from langtraj.metrics.instruction_following import Judgement, instruction_following, judge_rollouts
from langtraj.model.checkpoint import load_model
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType
from langtraj.sim.checkpoints import checkpoint_path
from langtraj.sim.config import ALL_LEVERS, PromptLevers, SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.policies import (
    DEFAULT_NO_COLLISION,
    DEFAULT_ON_ROAD,
    GUIDANCE_ONLY,
    GuidanceBaselinePolicy,
    LangTrajPolicy,
    LoadedModel,
    model_agents,
)

NO_PROMPT = "no prompt"
CONDITIONS: dict[str, PromptLevers | None] = {
    NO_PROMPT: None,
    "text": PromptLevers(text=True, guidance=False, selection=False),
    "guidance": GUIDANCE_ONLY,
    "text + guidance": PromptLevers(text=True, guidance=True, selection=False),
    "default": ALL_LEVERS,
}
"""The compared conditions: no prompt; its text alone; the CTG++-style baseline (guidance alone,
`GuidanceBaselinePolicy`); text and guidance; and what `langtraj simulate` does with a prompt (every lever)."""
REALISM = ("meta", "kinematic", "interactive", "map")


@dataclass(frozen=True, kw_only=True)
class IFRSettings(SimulationSettings):
    """What the experiment runs: the checkpoint, prompts per window, the guidance weights to compare, and the
    simulation settings every closed-loop table has (4 rollouts by default); the JSON holds every judgement."""

    checkpoint: Path
    rollouts: int = 4
    skip: int = 0
    """Windows of the split passed over first (settings are chosen on windows that the report leaves out)."""
    agents: int = 2
    counterfactuals: int = 2
    cfg: float = 0.0
    """Classifier-free guidance weight of the conditions with text."""
    on_road: float = DEFAULT_ON_ROAD
    no_collision: float = DEFAULT_NO_COLLISION
    conditions: tuple[str, ...] = tuple(CONDITIONS)
    free_text: Path | None = None
    """Hand-written prompts (`interdrive.free_text.load_free_text_prompts`): each prompt of a behaviour they
    cover is also run in their words, with every lever, as the condition 'default, free text'."""

    def __post_init__(self) -> None:
        super().__post_init__()
        require_counts(self, ("agents",))
        require_counts(self, ("counterfactuals", "skip"), minimum=0)
        if not math.isfinite(self.cfg) or self.cfg < -1:
            raise InputError(f"must be finite and >= -1, got {self.cfg}", where="--cfg")
        unknown = [c for c in self.conditions if c not in CONDITIONS]
        if unknown or NO_PROMPT not in self.conditions:
            raise InputError(
                f"conditions must include {NO_PROMPT!r} and be among {', '.join(CONDITIONS)}; got {self.conditions}",
                where="--conditions",
            )

    def free_text_prompts(self) -> tuple[FreeTextPrompt, ...]:
        """The hand-written prompts of `free_text` (none without it)."""
        return load_free_text_prompts(self.free_text) if self.free_text else ()


@dataclass(frozen=True)
class IFRCase:
    """One window and the prompts of its chosen agents (ground truth first, then counterfactuals)."""

    scenario: Scenario
    prompts: tuple[Alternative, ...]
    checker: AdherenceChecker = field(repr=False)


def choose_prompts(
    scenario: Scenario, settings: IFRSettings, rng: np.random.Generator
) -> tuple[tuple[Alternative, ...], AdherenceChecker]:
    """Prompts for up to `settings.agents` driven vehicles valid over the whole future that have any: all their
    ground-truth prompts and `counterfactuals` drawn among their feasible counterfactual ones."""
    index = MapIndex.build(scenario.road_map)
    checker = AdherenceChecker.build(scenario, map_index=index)
    agents = scenario.agents
    driven = set(model_agents(scenario).tolist())
    order = [*agents.objects_of_interest.tolist(), *agents.tracks_to_predict.tolist(), *range(agents.num_agents)]
    chosen: list[Alternative] = []
    seen: set[int] = set()
    for a in order:
        if a in seen or a not in driven:
            continue
        seen.add(a)
        if agents.types[a] != AgentType.VEHICLE or not agents.valid[a, scenario.current_index :].all():
            continue
        alternatives = feasible_alternatives(scenario, int(agents.ids[a]), index, logged=checker.logged)
        truth = [alt for alt in alternatives if alt.logged]
        other = [alt for alt in alternatives if not alt.logged]
        if not alternatives:
            continue
        picks = rng.choice(len(other), size=min(settings.counterfactuals, len(other)), replace=False) if other else []
        chosen += truth + [other[int(i)] for i in sorted(picks)]
        if len({alt.track_id for alt in chosen}) >= settings.agents:
            break
    return tuple(chosen), checker


def ifr_cases(spec: DatasetSpec, settings: IFRSettings) -> tuple[list[IFRCase], int]:
    """The windows of the dataset's split with prompts (at most `settings.windows`) and how many had none."""
    rng = np.random.default_rng(settings.seed)
    found, skipped = [], 0
    for _, scenario in held_out_windows(spec, skip=settings.skip):
        if settings.windows is not None and len(found) >= settings.windows:
            break
        if not scenario.logs_future():
            skipped += 1
            continue
        prompts, checker = choose_prompts(scenario, settings, rng)
        if not prompts:
            skipped += 1
            continue
        found.append(IFRCase(scenario, prompts, checker))
    return found, skipped


def _policy(loaded: LoadedModel, settings: IFRSettings, prompt: Alternative | None, condition: str) -> LangTrajPolicy:
    """The policy of `condition` for `prompt` (None: no prompt), as `langtraj simulate` builds it."""
    model, data = loaded
    levers = CONDITIONS[condition]
    request = SimRequest(
        candidates=settings.candidates,
        steps=settings.steps,
        on_road=settings.on_road,
        no_collision=settings.no_collision,
    )
    if prompt is None or levers is None:
        return LangTrajPolicy(model, data, request)
    if levers == GUIDANCE_ONLY:
        return GuidanceBaselinePolicy(model, data, request, prompt=prompt.prompt)
    return LangTrajPolicy(model, data, replace(request, cfg=settings.cfg, levers=levers), prompt=prompt.prompt)


def in_free_text(prompt: Alternative, free_text: Sequence[FreeTextPrompt], pick: int) -> Alternative | None:
    """`prompt` in the words of one of the hand-written prompts of its behaviour (the `pick`-th, cyclically),
    judged by the same facts; None when none covers the behaviour."""
    options = [f for f in free_text if f.behaviour is prompt.behaviour]
    if not options:
        return None
    entry, _ = options[pick % len(options)].entry(prompt.track_id, prompt.other_id)
    return Alternative(prompt.track_id, prompt.behaviour, entry, prompt.facts, prompt.logged, prompt.other_id)


def _safety(case: IFRCase, rollouts: Rollouts, scene_map: SceneMap, tracks: Sequence[int]) -> dict[str, list]:
    """Collision and offroad rates over the rollouts of each of `tracks` (offroad: left out without road edges)."""
    collided, offroad = agent_rates(case.scenario, rollouts, scene_map=scene_map)
    return {
        "collision": [collided[t] for t in tracks],
        "offroad": [offroad[t] for t in tracks if t in offroad],
    }


def _run_prompts(
    loaded: LoadedModel,
    case: IFRCase,
    settings: IFRSettings,
    scene_map: SceneMap,
    prompts: Sequence[Alternative],
    condition: str,
) -> dict:
    config = SimConfig(rollouts=settings.rollouts, seed=settings.seed)
    row: dict = {"judgements": [], "realism": [], "minade": [], "seconds": 0.0, "collision": [], "offroad": []}
    row["prompts"] = []
    for prompt in prompts:
        start = time.perf_counter()
        result = simulate(case.scenario, _policy(loaded, settings, prompt, condition), config)
        rollouts = result.rollouts
        row["seconds"] += time.perf_counter() - start
        judged = judge_rollouts(case.scenario, rollouts, [prompt], checker=case.checker)
        row["judgements"] += judged
        row["realism"].append(wosac_figures(case.scenario, rollouts, scene_map))
        safety = _safety(case, rollouts, scene_map, [prompt.track_id])
        for key, values in safety.items():
            row[key] += values
        row["prompts"].append(
            {
                "scenario_id": case.scenario.scenario_id,
                "text": prompt.prompt.text,
                "behaviour": prompt.behaviour.value,
                "ground_truth": prompt.logged,
                "followed": float(np.mean([j.followed for j in judged])),
                "collision": safety["collision"][0],
                "meta": row["realism"][-1]["meta"],
                "offroad": safety["offroad"][0] if safety["offroad"] else None,
                "steering": result.report.get("prompt", {}).get("steering", []),
            }
        )
        if prompt.logged:
            row["minade"].append(min_ade(case.scenario, rollouts, [prompt.track_id]).mean)
    return row


def run_case(
    loaded: LoadedModel,
    case: IFRCase,
    settings: IFRSettings,
    pick: int = 0,
    free_text: Sequence[FreeTextPrompt] = (),
) -> dict[str, dict]:
    """Per condition: judgements, realism rows (one per simulation), the prompted agents' collision and offroad
    rates and the ground-truth prompts' agents' minADE, and seconds spent simulating; with `free_text`, the
    prompts it covers in its words too."""
    config = SimConfig(rollouts=settings.rollouts, seed=settings.seed)
    scene_map = SceneMap.from_scenario(case.scenario)
    out: dict[str, dict] = {}
    start = time.perf_counter()
    plain = simulate(case.scenario, _policy(loaded, settings, None, NO_PROMPT), config).rollouts
    out[NO_PROMPT] = {
        "judgements": list(judge_rollouts(case.scenario, plain, case.prompts, checker=case.checker)),
        "realism": [wosac_figures(case.scenario, plain, scene_map)],
        "realism_weight": len(case.prompts),  # judged against every prompt: it counts once per prompt
        "minade": [min_ade(case.scenario, plain, [p.track_id]).mean for p in case.prompts if p.logged],
        "seconds": time.perf_counter() - start,
        **_safety(case, plain, scene_map, [p.track_id for p in case.prompts]),
    }
    for condition in settings.conditions:
        if condition != NO_PROMPT:
            out[condition] = _run_prompts(loaded, case, settings, scene_map, case.prompts, condition)
    if free_text:
        worded = [in_free_text(p, free_text, pick + i) for i, p in enumerate(case.prompts)]
        covered = [p for p in worded if p is not None]
        if covered:
            out["default, free text"] = _run_prompts(loaded, case, settings, scene_map, covered, "default")
    return out


def summarize(per_case: Sequence[dict[str, dict]]) -> dict[str, dict]:
    """The table: per condition, GT-IFR and F-IFR (macro and per kind), mean realism and minADE, counts. Realism is
    the mean over a condition's simulations, each window's unprompted simulation counted once per prompt (it is
    judged against each), so that every condition weighs the windows alike."""
    table: dict[str, dict] = {}
    conditions = list(dict.fromkeys(c for case in per_case for c in case))
    for condition in conditions:
        rows = [case[condition] for case in per_case if condition in case]
        judgements: list[Judgement] = [j for row in rows for j in row["judgements"]]
        realism = [r for row in rows for r in row["realism"]]
        weights = [row.get("realism_weight", 1) for row in rows for _ in row["realism"]]
        minade = [m for row in rows for m in row["minade"]]
        report = instruction_following(judgements)
        collision = [c for row in rows for c in row["collision"]]
        offroad = [o for row in rows for o in row["offroad"]]
        seconds = sum(row["seconds"] for row in rows)
        table[condition] = {
            **{k: float(np.average([r[k] for r in realism], weights=weights)) for k in REALISM},
            "minade": float(np.mean(minade)) if minade else math.nan,
            "gt_ifr": report.ground_truth.macro,
            "f_ifr": report.counterfactual.macro,
            "prompted_collision": float(np.mean(collision)) if collision else math.nan,
            "prompted_offroad": float(np.mean(offroad)) if offroad else math.nan,
            "report": report.to_json(),
            "simulations": len(realism),
            "seconds": seconds,
            "seconds_per_simulation": seconds / max(len(realism), 1),
        }
    return table


def markdown(table: dict[str, dict]) -> str:
    """The conditions' table (the paper's realism columns, the prompted agents' safety, GT-IFR and F-IFR, seconds
    per simulation), then F-IFR and GT-IFR per behaviour kind."""
    columns = (*REALISM, "minade", "prompted_collision", "prompted_offroad", "gt_ifr", "f_ifr")
    header = ("condition", *REALISM, "minADE (m)", "prompted collision", "prompted offroad", "GT-IFR", "F-IFR")
    rows = [(name, *(cell(r[k]) for k in columns), f"{r['seconds_per_simulation']:.1f}") for name, r in table.items()]
    kinds = []
    for behaviour in Behaviour:
        cells = []
        for row in table.values():
            f = row["report"]["f_ifr"]["per_kind"].get(behaviour.value)
            g = row["report"]["gt_ifr"]["per_kind"].get(behaviour.value)
            f_cell = f"{cell(f and f['ifr'])} ({f['prompts'] if f else 0})"
            cells.append(f"{f_cell} / {cell(g and g['ifr'])} ({g['prompts'] if g else 0})")
        kinds.append((behaviour.value, *cells))
    per_kind = markdown_table(("behaviour", *(f"{name} F-IFR / GT-IFR" for name in table)), kinds)
    return markdown_table((*header, "s / simulation"), rows) + "\n\n" + per_kind


@EXPERIMENTS.register
class InstructionFollowingExperiment(Experiment):
    """`langtraj experiment instruction-following`: closed-loop GT-IFR and F-IFR per condition, one table per dataset
    (every judgement in the JSON)."""

    name = "instruction-following"
    settings = IFRSettings

    def tables(self, settings: IFRSettings) -> dict[str, dict]:
        loaded = load_model(checkpoint_path(settings.checkpoint))
        free_text = settings.free_text_prompts()
        results = {}
        for spec in settings.datasets:
            found, skipped = ifr_cases(spec, settings)
            if not found:
                raise InputError(
                    f"no held-out window of {spec.labels} has an agent with prompts to judge", where="--data"
                )
            per_case = [run_case(loaded, case, settings, pick=i, free_text=free_text) for i, case in enumerate(found)]
            table = summarize(per_case)
            prompts = sum(len(c.prompts) for c in found)
            results[spec.name] = {
                "table": table,
                "windows": len(found),
                "skipped_windows": skipped,
                "prompts": prompts,
                "judgements": {
                    cond: [j.to_json() for case in per_case for j in case.get(cond, {}).get("judgements", [])]
                    for cond in table
                },
                "prompts_by_condition": {
                    cond: [p for case in per_case for p in case.get(cond, {}).get("prompts", [])] for cond in table
                },
            }
            print(
                f"\n{spec.name}: {len(found)} windows ({skipped} without a judgeable agent), {prompts} prompts, "
                f"{settings.rollouts} rollouts, {settings.candidates} candidates, K = {settings.steps}"
            )
            print(markdown(table))
        return results
