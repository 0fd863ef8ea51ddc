"""A test case of a planner, defined once: the scene, the ego, what the other agents are asked to do, the seeds, the
model and the criteria (`Case`, `Criteria`). The env's episode, a suite's case, a studio job and results.json are
all this type (docs/testing.md, 'Cases'); `langtraj.cases.io` reads and writes it."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from langtraj.scenario.model import FUTURE_STEPS

if TYPE_CHECKING:
    from langtraj.scenario.model import Scenario

EPISODE_STEPS = FUTURE_STEPS
"""Steps of an episode: the 8 s every simulation runs (`max_steps` may cut a case's episodes shorter)."""
EGO_PLACEHOLDER = "@ego"
"""Written in a prompt, stands for the ego's track id (the env replaces it at reset, when the ego is known)."""
ADVERSARY_PLACEHOLDER = re.compile(r"@adv\b")
"""Written in a prompt, stands for the case's adversary (replaced when the case is read)."""
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""A suite's or case's name: letters, digits, '.', '_' and '-', not starting with a punctuation mark."""


@dataclass(frozen=True)
class Criteria:
    """What an episode must keep to pass; each criterion is checked on the whole episode (docs/testing.md,
    'Scenario suites').

    no_at_fault_collision: fail when the ego causes a collision (the env's `at_fault`: the agent hit is in front).
    no_collision: fail on any collision of the ego, whoever is at fault.
    no_offroad: fail when the ego leaves the road at any step.
    min_ttc: fail when the time to collision with the nearest agent ahead drops below this many seconds (null: not
        checked).
    min_progress: fail when the ego's final progress, as a fraction of the logged ego's progress over the episode,
        stays below this (null: not checked).
    no_red_light: fail when the ego crosses the stop point of a lane whose light shows stop (nuPlan's and WOSAC's
        traffic-light compliance).
    no_wrong_way: fail when the ego drives against its lane (nuPlan's driving-direction compliance).
    max_over_speed_limit: fail when the ego's speed exceeds its route's speed limit by more than this (m/s; null:
        not checked; nuPlan's speed-limit compliance).
    comfortable: fail when the ego's acceleration, jerk, yaw rate or lateral acceleration leave nuPlan's comfort
        bounds (`suites.verdict.COMFORT_BOUNDS`).
    terminate_on_collision: end the episode at the ego's first collision (the verdict is then known).
    """

    no_at_fault_collision: bool = True
    no_collision: bool = False
    no_offroad: bool = True
    min_ttc: float | None = None
    min_progress: float | None = None
    no_red_light: bool = False
    no_wrong_way: bool = False
    max_over_speed_limit: float | None = None
    comfortable: bool = False
    terminate_on_collision: bool = True


@dataclass(frozen=True)
class Case:
    """One test case (docs/testing.md, 'Cases'); adding a field here adds it to the env's options, a suite's YAML,
    a studio job and results.json.

    scenario: the scene file (WOMD TFRecord or ScenarioNet pickle), or a `Scenario` in memory (the env only; such
        a case cannot be written).
    index: which scene of the file.
    window: which 9.1-s window of a longer scene (None: the scene as it is; as `langtraj render --window`).
    ego: the ego's track id; None: the env's choice (the scene's self-driving car, else its most important vehicle).
    prompts: prompts for the other agents (`@adv` already replaced by the adversary's id; `@ego` stands for the ego).
    adversary: a track id driven into `target` by collision guidance (None: none).
    target: the track id the adversary aims at, or "ego".
    seeds: the episodes' seeds (one episode per seed).
    checkpoint: the model that drives the other agents (None: the shipped one).
    criteria: what each episode must keep to pass.
    max_steps: end every episode after this many steps (None: the full `EPISODE_STEPS`).
    name: the case's name in its suite (its videos' and JUnit test case's name); None outside a suite.
    """

    scenario: Path | Scenario | None = None
    index: int = 0
    window: int | None = None
    ego: int | None = None
    prompts: tuple[str, ...] = ()
    adversary: int | None = None
    target: int | str | None = None
    seeds: tuple[int, ...] = (0,)
    checkpoint: Path | None = None
    criteria: Criteria = field(default_factory=Criteria)
    max_steps: int | None = None
    name: str | None = None

    @property
    def steps(self) -> int:
        """The steps an episode of this case runs at most."""
        return self.max_steps or EPISODE_STEPS
