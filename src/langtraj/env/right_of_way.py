"""Who had the right of way where two agents' paths cross, from the signals and signs each passed (docs/testing.md,
'Step info'): an agent that crossed a red light's stop point owes the way to one that did not; one that passed a stop
sign owes it to one that came without passing any (at an all-way stop, the later to pass its sign owes it). A
passing counts for `ENTRY_MEMORY_S`, long enough to clear a junction. Where neither decides, the lanes do
(`env.fault.right_of_way`). Every agent's passings are logged from the scene's history on (under the log's lights,
then those the episode sees, `EpisodeLights`), so a car that ran its red before the start owes the way too."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from langtraj.env.rules import EpisodeLights
from langtraj.roads.stop_lines import StopLines
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField

ENTRY_MEMORY_S = 5.0
"""How long (s) a red light crossed or a stop sign passed decides the right of way: the time to clear a junction."""
NEVER = -(10**9)
"""The step of a passing that never happened."""


class Basis(StrEnum):
    """What decided who owed the right of way."""

    SIGNAL = "signal"  # one of the two crossed a red light's stop point, the other did not
    SIGN = "sign"  # one passed a stop sign, the other none (or passed its own sign first)
    LANES = "lanes"  # one turned across the road the other kept, or came from off the road


@dataclass(frozen=True)
class RightOfWay:
    """Who owed whom the right of way at a contact: `ego_owed` True when the ego had to give way, False when the other
    had to; `basis` what says so."""

    ego_owed: bool
    basis: Basis


class Passings:
    """The last step each agent of `scenario` crossed a red light's stop point and passed a stop sign's line, logged
    step by step (`update`) from `ENTRY_MEMORY_S` before the episode's first step `start` on, under the lights the
    episode sees (`lights`)."""

    def __init__(self, scenario: Scenario, lights: EpisodeLights, start: int):
        self.lights = lights
        self.signs = StopLines.of_signs(scenario.road_map)
        self.memory = round(ENTRY_MEMORY_S / STEP_SECONDS)
        num = scenario.num_agents
        self.red = np.full(num, NEVER, np.int64)
        self.sign = np.full(num, NEVER, np.int64)
        states, valid = scenario.agents.states, scenario.agents.valid
        for step in range(max(start - self.memory, 1), start + 1):  # the logged history, under the log's lights
            both = valid[:, step - 1] & valid[:, step]
            self.update(states[:, step - 1], states[:, step], both, step, logged=True)

    def update(self, before: np.ndarray, now: np.ndarray, valid: np.ndarray, step: int, logged: bool = False) -> None:
        """Log the passings of the agents `valid` [A] between their states `before` [A, 9] and `now` [A, 9] (at
        `step`, under the lights the episode sees then; `logged`: the log's, for a step of the history)."""
        if not valid.any() or (self.lights.log is None and not len(self.signs)):
            return
        xy = [StateField.X, StateField.Y]
        rows = np.flatnonzero(valid)
        was, is_ = before[rows][:, xy].astype(np.float64), now[rows][:, xy].astype(np.float64)
        heading = now[rows, StateField.HEADING].astype(np.float64)
        self.red[rows[self.lights.runs(was, is_, heading, step, logged)]] = step
        self.sign[rows[self.signs.passed(was, is_, heading)]] = step

    def right_of_way(self, ego: int, other: int, step: int) -> RightOfWay | None:
        """Who of rows `ego` and `other` owed the other the right of way at `step` by signals, else by signs; None
        where neither decides."""
        recent = step - self.memory
        red_ego, red_other = self.red[ego] >= recent, self.red[other] >= recent
        if red_ego != red_other:
            return RightOfWay(ego_owed=bool(red_ego), basis=Basis.SIGNAL)
        sign_ego, sign_other = int(self.sign[ego]), int(self.sign[other])
        if sign_ego < recent and sign_other < recent:
            return None
        if sign_ego < recent or sign_other < recent:  # only one passed a sign: it owes the way
            return RightOfWay(ego_owed=sign_ego >= recent, basis=Basis.SIGN)
        if sign_ego == sign_other:  # an all-way stop passed at one step: nobody's by signs
            return None
        return RightOfWay(ego_owed=sign_ego > sign_other, basis=Basis.SIGN)  # the later to pass owes it
