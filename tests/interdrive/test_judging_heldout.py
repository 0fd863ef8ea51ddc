"""The judges by numbers of the six safety-critical pair behaviours on held-out scenes (not tuned on): nuScenes
scene-0103 and scene-0061 (../shared/data/real, skipped when absent) and the synthesized arterial shard of the example
suite (in the repository, always run). In each scene the ego (its sdc) and one other vehicle (the one nearest the ego
at the current step) are given constructed futures, laid along the ego's logged heading from its logged current
position, their sizes the scene's; the scene's other agents stay as logged, those that would come near the two
marked invalid after the current step. Per behaviour, the episodes of `test_judging`: the asked number met, missed by
a little (inside tolerance), missed by a lot, cut short by a contact, and done out of the ego's path; the judge gives
the expected verdict and the reference judge written from positions alone (`test_judging.REFERENCE`) agrees."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from langtraj.scenario import AgentType, Scenario, TrafficLights
from langtraj.scenario.io import read_scenario
from langtraj.scenario.types import StateField, TrafficLightState

from .test_judging import DT, REFERENCE, _judge

pytestmark = pytest.mark.filterwarnings("ignore::langtraj.errors.DataWarning")  # nuScenes boxes read swapped

SYNTH_FILE = Path(__file__).resolve().parents[2] / "configs" / "suites" / "scenes" / "synth-arterial.tfrecord.zst"
SCENES: dict[str, tuple[str | None, int | None]] = {
    "nuscenes-0103": ("sd_nuscenes_v1.0-mini_scene-0103.pkl", 33),  # file in ../shared/data/real, its sdc's id
    "nuscenes-0061": ("sd_nuscenes_v1.0-mini_scene-0061.pkl", 62),
    "synth-arterial": (None, None),  # SYNTH_FILE, scene 0 and its sdc
}
NEAR_M = 8.0
"""A logged agent whose centre comes this near either constructed track after the current step is marked invalid
from then on, out of the way."""
FAR_M = 250.0
"""How far (m) to the ego's left the red-light runner's road is moved for the out-of-path run: it never reaches the
ego's way in the 18.6 s of the longest scene."""


@cache
def _read(path: str) -> Scenario:
    return read_scenario(path, 0)


# --- the constructed futures, in the ego's frame at the current step: x along its logged heading, y to its left ---


@dataclass(frozen=True)
class Frame:
    """The time base of a scene (`t`, s from its current step, [T]) and the sizes of the ego and the actor."""

    t: np.ndarray
    now: int
    ego_length: float
    ego_width: float
    length: float
    width: float

    @property
    def half(self) -> float:
        """Centre to centre (m) of the two along a line when bumper to bumper."""
        return 0.5 * (self.ego_length + self.length)

    def smooth(self, start: float, duration: float) -> np.ndarray:
        r = np.clip((self.t - start) / duration, 0.0, 1.0)
        return 3 * r**2 - 2 * r**3

    def travelled(self, speed: np.ndarray) -> np.ndarray:
        s = np.concatenate([[0.0], np.cumsum(speed[:-1] * DT)])
        return s - s[self.now]

    def track(self, x: np.ndarray | float, y: np.ndarray | float, heading: float = 0.0) -> np.ndarray:
        """[T, 3] x, y and the heading of the motion (`heading` while standing, the last one moved with after)."""
        n = len(self.t)
        x, y = np.broadcast_to(x, (n,)).astype(float), np.broadcast_to(y, (n,)).astype(float)
        dx, dy = np.gradient(x), np.gradient(y)
        h = np.full(n, heading)
        moving = np.hypot(dx, dy) > 1e-4
        h[moving] = np.arctan2(dy[moving], dx[moving])
        for k in range(1, n):
            if not moving[k] and moving[: k + 1].any():
                h[k] = h[k - 1]
        return np.stack([x, y, h], axis=1)


Built = tuple[np.ndarray, np.ndarray, tuple[float, float] | None]  # ego [T, 3], actor [T, 3], stop point (x, y)


def cut_in(f: Frame, gap: float, end_lateral: float = 0.0) -> Built:
    """The actor 3.5 m to the ego's left at 10 m/s like it, `gap` m ahead bumper to bumper, changes toward
    `end_lateral` from 1 s over 3 s."""
    lateral = 3.5 + (end_lateral - 3.5) * f.smooth(1.0, 3.0)
    return f.track(10 * f.t, 0.0), f.track(f.half + gap + 10 * f.t, lateral), None


def overtake(f: Frame, gap: float, change_at: float = 4.0, back_to: float = 0.0) -> Built:
    """The actor passes the ego (10 m/s) on its left at 16 m/s, slows to 10 m/s from 3 s to 4 s `gap` m ahead of it,
    then changes back toward `back_to` from `change_at` over 3 s."""
    speed = 10.0 + 6.0 * (1.0 - np.clip(f.t - 3.0, 0.0, 1.0))
    x = f.travelled(speed)
    x += f.half + gap - (x[f.now + 40] - 10 * 4.0)
    lateral = 3.5 + (back_to - 3.5) * f.smooth(change_at, 3.0)
    return f.track(10 * f.t, 0.0), f.track(x, lateral), None


def brake(f: Frame, decel: float, lead_gap: float = 30.0, swerve: float = 0.0, follower: float = 12.0) -> Built:
    """The actor, `lead_gap` m ahead at 12 m/s, brakes at `decel` from 1 s to a stop (`swerve`: moving that far to
    the right as it does); the ego at `follower` m/s brakes at 4 m/s^2 from 1.5 s (at 16 m/s or more, it does not)."""
    lead = f.travelled(np.maximum(12.0 - decel * np.clip(f.t - 1.0, 0.0, None), 0.0))
    slows = 4.0 if follower < 16 else 0.0
    ego = f.travelled(np.maximum(follower - slows * np.clip(f.t - 1.5, 0.0, None), 0.0))
    return f.track(ego, 0.0), f.track(f.half + lead_gap + lead, -swerve * f.smooth(1.1, 1.2)), None


def tailgate(f: Frame, headway: float, lane: float = 0.0, merge: bool = False) -> Built:
    """The actor closes on the ego (10 m/s) from 20 m behind to `headway` x 10 m between 0.5 s and 3 s and keeps it,
    in the ego's lane or `lane` m to its left; `merge`: `headway` x 10 m behind throughout, moving from `lane` into
    the ego's lane from 1 s over 2 s."""
    gap = 20.0 + (10 * headway - 20.0) * f.smooth(0.5, 2.5)
    lateral = np.full(len(f.t), lane)
    if merge:
        gap, lateral = np.full(len(f.t), 10 * headway), lane * (1.0 - f.smooth(1.0, 2.0))
    ego = 10 * f.t
    return f.track(ego, 0.0), f.track(ego - f.half - gap, lateral), None


def pull_out(f: Frame, margin: float, stops: bool = False) -> Built:
    """The actor stands 8 m right of the ego's way heading across it, sets off at 1 s at 3 m/s^2 (to 8 m/s; `stops`:
    standing again with its front 1.25 m short of the ego's side, at -4.5 m for the cars of `test_judging`), timed to
    be on the ego's way (within 1.5 m of it) `margin` s ahead at the ego's 10 m/s."""
    y = -8.0 + f.travelled(np.clip(3.0 * (f.t - 1.0), 0.0, 8.0))
    entry = f.now + int(np.flatnonzero(y[f.now :] >= -1.5)[0])
    if stops:
        y = np.minimum(y, -0.5 * (f.length + f.ego_width) - 1.25)
    x = 10 * f.t[entry] + f.half + 10 * margin
    return f.track(10 * f.t, 0.0), f.track(np.full(len(f.t), x), y, math.pi / 2), None


def red_light(f: Frame, ahead: float | None, away: float = 0.0) -> Built:
    """The ego drives on at 8 m/s; the actor crosses its way `ahead` m ahead of it (None: timed to touch the ego as it
    gets there) from its left at 10 m/s, its front passing a stop point on its line 9.75 m left of the ego's way at
    about 3 s; `away`: the actor's road and stop point moved that much further left."""
    if ahead is None:  # the ego's centre on the actor's line as the actor's box first touches its side
        ahead = 8 * (41.75 - 0.5 * (f.length + f.ego_width)) / 10
    runner = f.track(ahead, 41.75 + away - 10 * f.t, -math.pi / 2)
    return f.track(8 * f.t, 0.0), runner, (ahead, 9.75 + away)


@dataclass(frozen=True)
class Case:
    build: Callable[[Frame], Built]
    asked: dict[str, float]
    happened: bool
    what: str


KINDS = ("met", "little", "lot", "contact", "off_path")
CASES: dict[str, dict[str, Case]] = {
    "cut_in": {
        "met": Case(lambda f: cut_in(f, 15.0), {"gap": 15.0}, True, "15 m for 15"),
        "little": Case(lambda f: cut_in(f, 17.0), {"gap": 15.0}, True, "17 m for 15"),
        "lot": Case(lambda f: cut_in(f, 2.5), {"gap": 15.0}, False, "2.5 m for 15"),
        "contact": Case(lambda f: cut_in(f, -2.0), {}, False, "into the ego's side"),
        "off_path": Case(lambda f: cut_in(f, 10.0, end_lateral=1.75), {}, False, "half in the lane"),
    },
    "overtake_cut_in": {
        "met": Case(lambda f: overtake(f, 10.0), {}, True, "10 m for 10"),
        "little": Case(lambda f: overtake(f, 12.0), {"gap": 10.0}, True, "12 m for 10"),
        "lot": Case(lambda f: overtake(f, 3.0), {"gap": 10.0}, False, "3 m for 10"),
        "contact": Case(lambda f: overtake(f, 10.0, change_at=0.0), {}, False, "back in while beside"),
        "off_path": Case(lambda f: overtake(f, 10.0, back_to=3.5), {}, False, "never back in"),
    },
    "brake_hard": {
        "met": Case(lambda f: brake(f, 6.0), {"deceleration": 6.0}, True, "6 for 6"),
        "little": Case(lambda f: brake(f, 7.0), {"deceleration": 6.0}, True, "7 for 6"),
        "lot": Case(lambda f: brake(f, 11.0), {"deceleration": 6.0}, False, "11 for 6"),
        "contact": Case(lambda f: brake(f, 6.0, lead_gap=5.0, follower=16.0), {}, False, "rear-ended at once"),
        "off_path": Case(lambda f: brake(f, 6.0, swerve=2.3), {"deceleration": 6.0}, False, "swerves off"),
    },
    "tailgate": {
        "met": Case(lambda f: tailgate(f, 0.4), {}, True, "0.4 s headway"),
        "little": Case(lambda f: tailgate(f, 0.55), {}, True, "0.55 s headway"),
        "lot": Case(lambda f: tailgate(f, 1.0), {}, False, "1 s headway"),
        "contact": Case(lambda f: tailgate(f, -0.05, 3.5, merge=True), {}, False, "into its rear corner"),
        "off_path": Case(lambda f: tailgate(f, 0.4, lane=3.5), {}, False, "in the next lane"),
    },
    "pull_out": {
        "met": Case(lambda f: pull_out(f, 2.0), {}, True, "2 s margin"),
        "little": Case(lambda f: pull_out(f, 2.7), {}, True, "2.7 s margin"),
        "lot": Case(lambda f: pull_out(f, 5.0), {}, False, "5 s ahead"),
        "contact": Case(lambda f: pull_out(f, -0.35), {}, False, "hit before it is on the way"),
        "off_path": Case(lambda f: pull_out(f, 2.0, stops=True), {}, False, "stops short of the way"),
    },
    "run_red_light": {
        "met": Case(lambda f: red_light(f, 47.05), {}, True, "the ego about 12 m from the crossing"),
        "little": Case(lambda f: red_light(f, 63.05), {}, True, "about 28 m for 32"),
        "lot": Case(lambda f: red_light(f, 85.05), {}, False, "about 50 m away"),
        "contact": Case(lambda f: red_light(f, None), {}, False, "hit before crossing"),
        "off_path": Case(lambda f: red_light(f, 47.05, away=FAR_M), {}, False, "a road far away"),
    },
}


# --- the held-out scenes and the episodes played in them ---


@dataclass(frozen=True)
class Held:
    scene: Scenario
    ego: int
    actor: int


def _held(scene: Scenario) -> Held:
    """The scene, its sdc and the vehicle nearest it at the current step (valid then, not the sdc)."""
    a, now = scene.agents, scene.current_index
    ego_row = int(scene.sdc_index)
    xy = a.states[:, now, :2].astype(float)
    far = np.hypot(*(xy - xy[ego_row]).T)
    fits = a.valid[:, now] & (a.types == int(AgentType.VEHICLE)) & (np.arange(len(a.ids)) != ego_row)
    actor_row = int(np.argmin(np.where(fits, far, np.inf)))
    assert fits[actor_row], "no other vehicle in the scene at its current step"
    return Held(scene, int(a.ids[ego_row]), int(a.ids[actor_row]))


@pytest.fixture(scope="module")
def held_out(request) -> Callable[[str], Held]:
    def load(name: str) -> Held:
        file, sdc = SCENES[name]
        if file is None:
            return _held(_read(str(SYNTH_FILE)))
        folder = request.getfixturevalue("real_data_dir")  # skips when ../shared/data/real is absent
        if not (folder / file).is_file():
            pytest.skip(f"held-out nuScenes scene {file} not found in {folder}")
        held = _held(_read(str(folder / file)))
        assert held.ego == sdc, f"{file}: the sdc is @{held.ego}, not @{sdc}"
        return held

    return load


def play(held: Held, case: Case) -> Scenario:
    """`held`'s scene with the ego's and the actor's futures (from the current step) overwritten by `case`, laid
    along the ego's logged heading from its logged position (sizes, z as logged at the current step); logged agents
    that would come within `NEAR_M` of either marked invalid after the current step; for a stop point, the scene's
    lights replaced by one signal there showing red throughout."""
    scene, a, now = held.scene, held.scene.agents, held.scene.current_index
    rows = {int(i): k for k, i in enumerate(a.ids)}
    ego_row, actor_row = rows[held.ego], rows[held.actor]
    x0, y0, _, h0 = (float(v) for v in a.states[ego_row, now, :4])
    c, s = math.cos(h0), math.sin(h0)
    frame = Frame(
        t=(np.arange(scene.num_steps) - now) * DT,
        now=now,
        ego_length=float(a.states[ego_row, now, StateField.LENGTH]),
        ego_width=float(a.states[ego_row, now, StateField.WIDTH]),
        length=float(a.states[actor_row, now, StateField.LENGTH]),
        width=float(a.states[actor_row, now, StateField.WIDTH]),
    )
    ego, actor, stop = case.build(frame)

    def world(u: np.ndarray | float, v: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        return x0 + c * np.asarray(u) - s * np.asarray(v), y0 + s * np.asarray(u) + c * np.asarray(v)

    states, valid = a.states.copy(), a.valid.copy()
    placed = {}
    for row, local in ((ego_row, ego), (actor_row, actor)):
        x, y = world(local[:, 0], local[:, 1])
        h = (local[:, 2] + h0 + math.pi) % (2 * math.pi) - math.pi
        vx, vy = np.gradient(x, DT), np.gradient(y, DT)
        states[row, now:, [0, 1, 3, 4, 5]] = np.stack([x, y, h, vx, vy])[:, now:]
        states[row, now:, [2, 6, 7, 8]] = states[row, now, [2, 6, 7, 8]][:, None]
        valid[row, now:] = True
        placed[row] = np.stack([x, y], axis=1)[now + 1 :]
    for row in range(len(a.ids)):
        if row not in placed and valid[row, now + 1 :].any():
            logged = states[row, now + 1 :, :2].astype(float)
            near = [(np.hypot(*(logged - p).T) < NEAR_M) & valid[row, now + 1 :] for p in placed.values()]
            if np.any(near):
                valid[row, now + 1 :] = False
    lights = scene.traffic_lights
    if stop is not None:
        sx, sy = world(*stop)
        stop_point = [[float(sx), float(sy), float(states[ego_row, now, 2])]]
        n = scene.num_steps
        red = np.full((n, 1), int(TrafficLightState.STOP), np.int8)
        lights = TrafficLights(np.array([101]), red, np.ones((n, 1), bool), np.array(stop_point))
    return replace(scene, agents=replace(a, states=states, valid=valid), traffic_lights=lights)


PARAMS = [
    pytest.param(scene, behaviour, what, id=f"{scene}-{behaviour}-{what}")
    for scene in SCENES
    for behaviour in CASES
    for what in KINDS
]


@pytest.mark.parametrize(("name", "behaviour", "what"), PARAMS)
def test_each_judge_and_the_reference_agree_on_held_out_scenes(held_out, name, behaviour, what):
    held = held_out(name)
    case = CASES[behaviour][what]
    played = play(held, case)
    now, ego_row = held.scene.current_index, int(held.scene.sdc_index)
    logged = held.scene.agents.states[ego_row, now, :2]
    assert np.allclose(played.agents.states[ego_row, now, :2], logged, atol=1e-3), "the ego left its logged place"
    judgement = _judge(behaviour, played, held.actor, held.ego, case.asked)
    label = f"{name} {behaviour} {what} ({case.what}; @{held.actor} toward the ego @{held.ego})"
    assert judgement.happened is case.happened, f"{label}: {judgement.why}"
    reference = bool(REFERENCE[behaviour](played, held.actor, held.ego, case.asked))
    assert reference is case.happened, f"{label}: the reference says {reference}, the judge {judgement.why}"
    assert judgement.why and "\n" not in judgement.why
    if case.happened:
        assert judgement.done_step is not None and all(m.ok is not False for m in judgement.measures), label
    assert (judgement.contact_step is not None) is (what == "contact"), f"{label}: contact {judgement.contact_step}"


def test_every_behaviour_has_each_kind_of_held_out_episode():
    assert set(CASES) == set(REFERENCE)
    assert all(tuple(kinds) == KINDS for kinds in CASES.values())
    assert sum(case.happened for kinds in CASES.values() for case in kinds.values()) == 2 * len(CASES)
