"""What happened to the ego at a step (docs/testing.md, 'Step info'): each collision, with whom, of which kind and
whether the ego caused it (`env.fault`, with the right of way from the signals and signs every agent passed:
`env.right_of_way`), off-road, time to collision with the agent ahead, with the WOSAC metrics'
own box geometry (`metrics.interaction`, `metrics.road`), so a suite and the realism scores agree on what a
collision is."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.env.fault import CollisionKind, at_fault, collision_kind, left_its_lane, right_of_way
from langtraj.env.right_of_way import Passings
from langtraj.env.rules import EpisodeLights
from langtraj.metrics.features import COLLISION_THRESHOLD, OFFROAD_THRESHOLD
from langtraj.metrics.interaction import MAX_TTC, pair_signed_distance, time_to_collision
from langtraj.metrics.road import RoadEdgeIndex, distance_to_road_edge
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField


@dataclass(frozen=True)
class Contact:
    """One agent whose box overlaps the ego's: its track id, the kind of contact, whether the ego caused it and, for
    the kinds right of way decides (`crossed`, `owed`), what decided it (`env.right_of_way.Basis`: signal, sign or
    lanes)."""

    partner: int
    kind: CollisionKind
    at_fault: bool
    right_of_way: str | None = None

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {"with": self.partner, "kind": self.kind.value, "at_fault": self.at_fault}
        if self.right_of_way is not None:
            out["right_of_way"] = self.right_of_way
        return out


@dataclass(frozen=True)
class StepEvents:
    """The ego's safety figures at one step."""

    contacts: tuple[Contact, ...]  # every agent whose box overlaps the ego's
    offroad: bool
    ttc: float  # s until the ego reaches the agent it follows at constant speeds (`MAX_TTC` when none)
    min_distance: float  # m between the ego's box and the nearest other box (negative: overlap)

    @property
    def collision(self) -> bool:
        return bool(self.contacts)

    @property
    def collided_with(self) -> tuple[int, ...]:
        return tuple(c.partner for c in self.contacts)

    @property
    def at_fault(self) -> bool:
        """A collision the ego causes (`env.fault`)."""
        return any(c.at_fault for c in self.contacts)


class EventJudge:
    """Judges the ego (scenario row `ego`) against every other valid agent, the road edges of `scenario` (`edges`:
    `metrics.road.road_edge_index` of them, None without any) and its lanes (`index`, for side contacts and right of
    way). With `lights` (the episode's), every agent's passings of red lights and stop signs are logged from the
    scene's history on, so that right of way at a crossing goes by them (`env.right_of_way`); each `judge` then
    names its step, and steps come in order."""

    def __init__(
        self,
        scenario: Scenario,
        ego: int,
        edges: RoadEdgeIndex | None,
        index: MapIndex | None = None,
        lights: EpisodeLights | None = None,
    ):
        self.ego = ego
        self.ids = scenario.agents.ids.astype(np.int64)
        self.vehicles = scenario.agents.types == AgentType.VEHICLE
        self.edges = edges
        self.index = index
        c = scenario.current_index
        self.passings = None if lights is None else Passings(scenario, lights, c)
        self._last = scenario.agents.states[:, c].copy(), scenario.agents.valid[:, c].copy(), c

    def judge(self, states: np.ndarray, valid: np.ndarray, step: int | None = None) -> StepEvents:
        """The figures from every agent's state [A, 9] and validity [A] at one step (`step` of the scenario, after
        the last judged; needed with `lights`)."""
        if self.passings is not None:
            if step is None or step <= self._last[2]:
                raise ValueError(f"judge needs the steps in order after {self._last[2]}, got {step}")
            before, was_valid, _ = self._last
            self.passings.update(before, states, was_valid & valid, step)
            self._last = states.copy(), valid.copy(), step
        s = states.astype(np.float64)
        x, y, heading = s[:, StateField.X], s[:, StateField.Y], s[:, StateField.HEADING]
        length, width = s[:, StateField.LENGTH], s[:, StateField.WIDTH]
        speed = np.hypot(s[:, StateField.VX], s[:, StateField.VY])

        def grid(v: np.ndarray) -> np.ndarray:  # [1 rollout, A, 1 step]
            return v[None, :, None]

        e = self.ego
        ttc = time_to_collision(
            grid(x), grid(y), grid(heading), grid(length), grid(width), grid(speed), grid(valid), np.array([e])
        )
        others = np.flatnonzero(valid)
        others = others[others != e]
        gap = pair_signed_distance(x[e], y[e], heading[e], length[e], width[e],
                                   x[others], y[others], heading[others], length[others], width[others])  # fmt: skip
        hit = others[gap < COLLISION_THRESHOLD]
        boxes = np.stack([x, y, heading, length, width, s[:, StateField.VX], s[:, StateField.VY]], axis=1)
        contacts = []
        for row in hit:  # one or two at a step, and only at a contact: nothing cached
            way = None
            if self.vehicles[e] and self.vehicles[row]:  # a pedestrian or cyclist ahead stays the ego's to avoid
                passed = None if self.passings is None else self.passings.right_of_way(e, int(row), self._last[2])
                way = right_of_way(self.index, boxes[e], boxes[row], passed)
            kind = collision_kind(boxes[e], boxes[row], self.index, way)
            side = kind in (CollisionKind.LATERAL, CollisionKind.CROSSED)
            left_lane = left_its_lane(self.index, boxes[e]) if side else None
            decided = (
                way.basis.value if way is not None and kind in (CollisionKind.CROSSED, CollisionKind.OWED) else None
            )
            contacts.append(Contact(int(self.ids[row]), kind, at_fault(kind, left_lane), decided))
        offroad = False
        if self.edges is not None:
            one = s[e : e + 1]
            dist = distance_to_road_edge(
                self.edges, x[e : e + 1], y[e : e + 1], one[:, StateField.Z], heading[e : e + 1], length[e : e + 1],
                width[e : e + 1], one[:, StateField.HEIGHT], np.ones(1, bool),
            )  # fmt: skip
            offroad = bool(dist[0] > OFFROAD_THRESHOLD)
        return StepEvents(
            contacts=tuple(contacts),
            offroad=offroad,
            ttc=float(min(ttc[0, 0, 0], MAX_TTC)),
            min_distance=float(gap.min()) if len(gap) else math.inf,
        )
