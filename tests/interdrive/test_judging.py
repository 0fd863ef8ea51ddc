"""The judges by numbers of the six safety-critical pair behaviours (`interdrive.judging`; docs/testing.md, 'Judged
by numbers') on constructed episodes: per behaviour the asked number met, missed by a little (inside tolerance),
missed by a lot, cut short by a contact, and done out of the other's path; and a reference judge written here from
positions alone (its own geometry, no shared helpers) that must give the same verdicts on every episode."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import KINDS
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.judging import Measure
from langtraj.interdrive.judging.base import boxes_overlap
from langtraj.scenario import Agents, AgentType, RoadMap, Scenario, TrafficLights
from langtraj.scenario.types import TrafficLightState

T, NOW, DT = 91, 10, 0.1
LENGTH, WIDTH = 4.5, 2.0
t = (np.arange(T) - NOW) * DT  # seconds from the current step


def smooth(start: float, duration: float) -> np.ndarray:
    """0 before `start`, 1 after `start + duration`, a smoothstep between (s from the current step)."""
    r = np.clip((t - start) / duration, 0.0, 1.0)
    return 3 * r**2 - 2 * r**3


def travelled(speed: np.ndarray) -> np.ndarray:
    """Distance [T] at per-step `speed` [T], 0 at the current step."""
    s = np.concatenate([[0.0], np.cumsum(speed[:-1] * DT)])
    return s - s[NOW]


def track(x: np.ndarray, y: np.ndarray, heading: float = 0.0) -> np.ndarray:
    """[T, 3] x, y and the heading of the motion (`heading` while standing still)."""
    x, y = np.broadcast_to(x, (T,)).astype(float), np.broadcast_to(y, (T,)).astype(float)
    dx, dy = np.gradient(x), np.gradient(y)
    h = np.full(T, heading)
    moving = np.hypot(dx, dy) > 1e-4
    h[moving] = np.arctan2(dy[moving], dx[moving])
    for k in range(1, T):  # standing: the heading it last moved with
        if not moving[k] and moving[: k + 1].any():
            h[k] = h[k - 1]
    return np.stack([x, y, h], axis=1)


def episode(tracks: Mapping[int, np.ndarray], lights: TrafficLights | None = None) -> Scenario:
    ids = sorted(tracks)
    states = np.zeros((len(ids), T, 9), np.float32)
    for n, i in enumerate(ids):
        states[n, :, [0, 1, 3]] = tracks[i].T
        states[n, :, 4:6] = np.gradient(tracks[i][:, :2], DT, axis=0)
        states[n, :, 6:9] = (LENGTH, WIDTH, 1.6)
    return Scenario(
        scenario_id="judged",
        timestamps=np.arange(T) * DT,
        current_index=NOW,
        sdc_index=0,
        agents=Agents(
            ids=np.array(ids),
            types=np.full(len(ids), int(AgentType.VEHICLE), np.int8),
            states=states,
            valid=np.ones((len(ids), T), bool),
        ),
        road_map=RoadMap(()),
        traffic_lights=lights,
        metadata={},
    )


# --- the episodes: agent 2 does the behaviour toward the ego, 1 ---


def cut_in(gap: float, end_lateral: float = 0.0, curve: bool = False) -> Scenario:
    """2, 3.5 m to the ego's left at 10 m/s like it, `gap` m ahead bumper to bumper, changes toward `end_lateral` from
    1 s over 3 s; `curve`: both on a left bend of 200 m radius."""
    lateral = 3.5 + (end_lateral - 3.5) * smooth(1.0, 3.0)
    if not curve:
        return episode({1: track(10 * t, 0.0), 2: track(LENGTH + gap + 10 * t, lateral)})
    radius = 200.0

    def on_bend(s: np.ndarray, left: np.ndarray) -> np.ndarray:
        angle = s / radius
        return track((radius - left) * np.sin(angle), radius - (radius - left) * np.cos(angle))

    return episode({1: on_bend(10 * t, np.zeros(T)), 2: on_bend(LENGTH + gap + 10 * t, lateral)})


def overtake(gap: float, change_at: float = 4.0, back_to: float = 0.0, via: float | None = None) -> Scenario:
    """2 passes the ego (10 m/s) on its left at 16 m/s, slows to 10 m/s from 3 s to 4 s `gap` m ahead of it, then
    changes back toward `back_to` from `change_at` over 3 s (`via`: first over to that lateral in 1.5 s)."""
    speed = 10.0 + 6.0 * (1.0 - np.clip(t - 3.0, 0.0, 1.0))
    x = travelled(speed)
    x += LENGTH + gap - (x[NOW + 40] - 10 * 4.0)
    if via is None:
        lateral = 3.5 + (back_to - 3.5) * smooth(change_at, 3.0)
    else:
        lateral = 3.5 + (via - 3.5) * smooth(change_at, 1.5) + (back_to - via) * smooth(change_at + 1.5, 1.5)
    return episode({1: track(10 * t, 0.0), 2: track(x, lateral)})


def brake(decel: float, lead_gap: float = 30.0, swerve: float = 0.0, follower: float = 12.0) -> Scenario:
    """Lead 2, `lead_gap` m ahead at 12 m/s, brakes at `decel` from 1 s to a stop (`swerve`: moving that far to the
    right as it does); the ego at `follower` m/s brakes at 4 m/s^2 from 1.5 s (at 16 m/s or more, it does not)."""
    lead = travelled(np.maximum(12.0 - decel * np.clip(t - 1.0, 0.0, None), 0.0))
    slows = 4.0 if follower < 16 else 0.0
    ego = travelled(np.maximum(follower - slows * np.clip(t - 1.5, 0.0, None), 0.0))
    return episode({1: track(ego, 0.0), 2: track(LENGTH + lead_gap + lead, -swerve * smooth(1.1, 1.2))})


def tailgate(headway: float, lane: float = 0.0, merge: bool = False) -> Scenario:
    """2 closes on the ego (10 m/s) from 20 m behind to `headway` x 10 m between 0.5 s and 3 s and keeps it, in the
    ego's lane or `lane` m to its left; `merge`: `headway` x 10 m behind throughout, moving from `lane` into the
    ego's lane from 1 s over 2 s."""
    gap = 20.0 + (10 * headway - 20.0) * smooth(0.5, 2.5)
    lateral = np.full(T, lane)
    if merge:
        gap, lateral = np.full(T, 10 * headway), lane * (1.0 - smooth(1.0, 2.0))
    ego = 30.0 + 10 * t
    return episode({1: track(ego, 0.0), 2: track(ego - LENGTH - gap, lateral)})


def pull_out(margin: float, stop_at: float | None = None) -> Scenario:
    """2 stands 8 m right of the ego's way, sets off north at 1 s at 3 m/s^2 (to 8 m/s; `stop_at`: standing again
    there), timed to be on the ego's way (within 1.5 m of it) with `margin` s at the ego's 10 m/s."""
    y = -8.0 + travelled(np.clip(3.0 * (t - 1.0), 0.0, 8.0))
    entry = NOW + int(np.flatnonzero(y[NOW:] >= -1.5)[0])
    if stop_at is not None:
        y = np.minimum(y, stop_at)
    x = -40.0 + 10 * t[entry] + LENGTH + 10 * margin
    return episode({1: track(-40.0 + 10 * t, 0.0), 2: track(np.full(T, x), y, math.pi / 2)})


def red_light(ego_y0: float, state: TrafficLightState = TrafficLightState.STOP, ego_x: float = 1.75) -> Scenario:
    """2 drives east at 10 m/s past a stop point at x = -8 (its front there at about 3 s) under `state`; the ego drives
    north at 8 m/s along x = `ego_x` from `ego_y0`."""
    lights = TrafficLights([101], np.full((T, 1), state, np.int8), np.ones((T, 1), bool), [[-8.0, -1.75, 0.0]])
    return episode({1: track(ego_x, ego_y0 + 8 * t), 2: track(-40.0 + 10 * t, -1.75)}, lights)


@dataclass(frozen=True)
class Case:
    behaviour: str
    scene: Scenario
    asked: dict[str, float]
    happened: bool
    what: str


EPISODES = {
    "cut_in met": Case("cut_in", cut_in(15.0), {"gap": 15.0}, True, "met"),
    "cut_in a little": Case("cut_in", cut_in(17.0), {"gap": 15.0}, True, "inside tolerance"),
    "cut_in a lot": Case("cut_in", cut_in(2.5), {"gap": 15.0}, False, "2.5 m for 15"),
    "cut_in contact": Case("cut_in", cut_in(-2.0), {}, False, "into the ego's side"),
    "cut_in out of path": Case("cut_in", cut_in(10.0, end_lateral=1.75), {}, False, "half in the lane"),
    "cut_in half in, touching": Case("cut_in", cut_in(-1.0, end_lateral=1.75), {}, False, "half in and touching"),
    "cut_in on a bend": Case("cut_in", cut_in(10.0, curve=True), {}, True, "on a 200-m bend"),
    "overtake met": Case("overtake_cut_in", overtake(10.0), {}, True, "met"),
    "overtake a little": Case("overtake_cut_in", overtake(12.0), {"gap": 10.0}, True, "inside tolerance"),
    "overtake a lot": Case("overtake_cut_in", overtake(3.0), {"gap": 10.0}, False, "3 m for 10"),
    "overtake contact": Case("overtake_cut_in", overtake(10.0, change_at=0.0), {}, False, "back in while beside"),
    "overtake out of path": Case("overtake_cut_in", overtake(10.0, back_to=3.5), {}, False, "never back in"),
    "overtake far side": Case("overtake_cut_in", overtake(10.0, via=-3.5), {}, False, "over to the far side"),
    "brake met": Case("brake_hard", brake(6.0), {"deceleration": 6.0}, True, "met"),
    "brake a little": Case("brake_hard", brake(7.0), {"deceleration": 6.0}, True, "inside tolerance"),
    "brake a lot": Case("brake_hard", brake(11.0), {"deceleration": 6.0}, False, "11 for 6"),
    "brake default": Case("brake_hard", brake(4.5), {}, True, "4 asked by default"),
    "brake contact": Case("brake_hard", brake(6.0, lead_gap=5.0, follower=16.0), {}, False, "rear-ended at once"),
    "brake out of path": Case("brake_hard", brake(6.0, swerve=2.3), {"deceleration": 6.0}, False, "swerves off"),
    "tailgate met": Case("tailgate", tailgate(0.4), {}, True, "met"),
    "tailgate a little": Case("tailgate", tailgate(0.55), {}, True, "inside tolerance"),
    "tailgate a lot": Case("tailgate", tailgate(1.0), {}, False, "1 s headway"),
    "tailgate too close": Case("tailgate", tailgate(0.1), {}, False, "0.1 s headway"),
    "tailgate contact": Case("tailgate", tailgate(-0.05, 3.5, merge=True), {}, False, "into its rear corner"),
    "tailgate out of path": Case("tailgate", tailgate(0.4, lane=3.5), {}, False, "in the next lane"),
    "pull_out met": Case("pull_out", pull_out(2.0), {}, True, "met"),
    "pull_out a little": Case("pull_out", pull_out(2.7), {}, True, "inside tolerance"),
    "pull_out a lot": Case("pull_out", pull_out(5.0), {}, False, "5 s ahead"),
    "pull_out contact": Case("pull_out", pull_out(-0.35), {}, False, "hit before it is on the way"),
    "pull_out out of path": Case("pull_out", pull_out(2.0, stop_at=-4.5), {}, False, "stops short of the way"),
    "red met": Case("run_red_light", red_light(-48.8), {}, True, "met"),
    "red a little": Case("run_red_light", red_light(-64.8), {}, True, "28 m for 32"),
    "red a lot": Case("run_red_light", red_light(-86.8), {}, False, "50 m away"),
    "red behind": Case("run_red_light", red_light(-20.0), {}, False, "the ego passed first"),
    "red contact": Case("run_red_light", red_light(-32.55), {}, False, "hit before crossing"),
    "red out of path": Case("run_red_light", red_light(-48.8, ego_x=80.0), {}, False, "a road far away"),
    "red on green": Case("run_red_light", red_light(-48.8, TrafficLightState.GO), {}, False, "on green"),
}


# --- the reference judge: positions (and lights) alone, its own geometry, nothing shared ---


def _ref_box(x: float, y: float, h: float, length: float, width: float) -> np.ndarray:
    c, s = math.cos(h), math.sin(h)
    corners = ((length / 2, width / 2), (-length / 2, width / 2), (-length / 2, -width / 2), (length / 2, -width / 2))
    return np.array([[x + c * a - s * b, y + s * a + c * b] for a, b in corners])


def _ref_cross(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def _ref_touch(p: np.ndarray, q: np.ndarray) -> bool:
    def inside(point, poly):
        signs = [_ref_cross(poly[(k + 1) % 4] - poly[k], point - poly[k]) for k in range(4)]
        return all(s > 1e-9 for s in signs) or all(s < -1e-9 for s in signs)

    def cross(a, b, c, d):
        def o(u, v, w):
            return np.sign(_ref_cross(v - u, w - u))

        return o(a, b, c) * o(a, b, d) < 0 and o(c, d, a) * o(c, d, b) < 0

    if any(inside(v, q) for v in p) or any(inside(v, p) for v in q):
        return True
    return any(cross(p[i], p[(i + 1) % 4], q[j], q[(j + 1) % 4]) for i in range(4) for j in range(4))


def _ref_frame(scene: Scenario, agent: int, other: int) -> dict[str, Any]:
    """From the current step on: the agent along and across the other's positions joined up (extended 300 m), its
    heading off that line, the bumper gaps, both speeds by central differences, and the first step their boxes
    touch."""
    rows = {int(i): k for k, i in enumerate(scene.agents.ids)}
    now = scene.current_index
    a, o = (scene.agents.states[rows[x], now:].astype(float) for x in (agent, other))
    line = [o[0, :2]]
    for p in o[1:, :2]:
        if np.hypot(*(p - line[-1])) > 0.05:
            line.append(p)
    line = np.array(line)
    if len(line) < 2:
        line = np.array([o[0, :2], o[0, :2] + [math.cos(o[0, 3]), math.sin(o[0, 3])]])
    first, last = line[1] - line[0], line[-1] - line[-2]
    line = np.vstack([line[0] - 300 * first / np.hypot(*first), line, line[-1] + 300 * last / np.hypot(*last)])
    seg = np.diff(line, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    start = np.concatenate([[0.0], np.cumsum(lengths)])[:-1]

    def place(p):
        u = np.clip(((p - line[:-1]) * seg).sum(1) / lengths**2, 0, 1)
        d = np.hypot(*(line[:-1] + u[:, None] * seg - p).T)
        k = int(np.argmin(d))
        side = np.sign(seg[k, 0] * (p - line[k])[1] - seg[k, 1] * (p - line[k])[0])
        return start[k] + u[k] * lengths[k], side * d[k], math.atan2(seg[k, 1], seg[k, 0])

    pa, po = [place(p) for p in a[:, :2]], [place(p) for p in o[:, :2]]
    along = np.array([x[0] - y[0] for x, y in zip(pa, po, strict=True)])
    off = np.array([(h - x[2] + math.pi) % (2 * math.pi) - math.pi for h, x in zip(a[:, 3], pa, strict=True)])
    touch = [k for k in range(len(a)) if _ref_touch(_ref_box(*a[k, [0, 1, 3, 6, 7]]), _ref_box(*o[k, [0, 1, 3, 6, 7]]))]
    half = (a[:, 6] + o[:, 6]) / 2
    return {
        "along": along,
        "ahead": along - half,
        "behind": -along - half,
        "lat": np.array([x[1] for x in pa]),
        "off": np.abs(np.degrees(off)),
        "v": np.hypot(*np.gradient(a[:, :2], DT, axis=0).T),
        "v_other": np.hypot(*np.gradient(o[:, :2], DT, axis=0).T),
        "contact": touch[0] if touch else len(a),
        "xy": a[:, :2],
        "heading": a[:, 3],
        "length": a[:, 6],
        "other_length": o[:, 6],
    }


def _ref_first_run(mask: np.ndarray, length: int, end: int, since: int = 0) -> int | None:
    """The first step >= `since` opening a run of `mask` at least `length` long, or one reaching step `end`."""
    k = since
    while k < len(mask):
        if mask[k]:
            stop = k
            while stop < len(mask) and mask[stop]:
                stop += 1
            if stop - k >= length or stop >= end > k:
                return k
            k = stop
        k += 1
    return None


def _ref_settled_at(f: dict[str, Any], since: int) -> int | None:
    settled = (np.abs(f["lat"]) <= 1.0) & (f["off"] <= 8.0) & (f["ahead"] > 0)
    if since > 0 and settled[since - 1]:
        return None  # a settled run cannot hold an out-of-path step
    k = _ref_first_run(settled, 10, f["contact"], since)
    return k if k is not None and k < f["contact"] else None


def _ref_gap_ok(f: dict[str, Any], k: int | None, gap: float) -> bool:
    """The gap when the agent entered the lane (its centre within 1.75 m, ahead) on its way to settling at `k`."""
    if k is None:
        return False
    entry = k
    while entry > 0 and abs(f["lat"][entry - 1]) <= 1.75 and f["ahead"][entry - 1] > 0:
        entry -= 1
    return abs(f["ahead"][entry] - gap) <= max(3.0, 0.2 * gap)


def ref_cut_in(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f = _ref_frame(scene, agent, other)
    out = np.flatnonzero(np.abs(f["lat"]) >= 2.0)
    return bool(out.size) and _ref_gap_ok(f, _ref_settled_at(f, int(out[0])), asked.get("gap", 10.0))


def ref_overtake(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f = _ref_frame(scene, agent, other)
    behind = np.flatnonzero(f["ahead"] < 0)
    out = np.flatnonzero(np.abs(f["lat"]) >= 2.0)
    if not behind.size or not out.size:
        return False
    side = np.sign(f["lat"][out[0]])
    k = _ref_settled_at(f, max(int(out[0]), int(behind[0])))
    until = f["contact"] if k is None else min(k, f["contact"])
    return (-side * f["lat"][:until]).max() <= 1.0 and _ref_gap_ok(f, k, asked.get("gap", 10.0))


def ref_brake(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f, wanted = _ref_frame(scene, agent, other), asked.get("deceleration", 4.0)
    v, n = f["v"], len(f["v"])
    dec = np.array([(v[k] - v[k + 5]) / 0.5 if k + 5 < min(n, f["contact"]) and v[k] >= 3 else 0.0 for k in range(n)])
    if dec.max() <= 2.0:
        return False
    onset = int(np.flatnonzero(dec > 2.0)[0])
    stopped = np.flatnonzero((v < 0.5) & (np.arange(n) > onset))
    until = min(int(stopped[0]) + 1 if stopped.size else n, f["contact"])
    in_path = (np.abs(f["lat"][onset:until]) <= 1.5).all() and (f["off"][onset:until] <= 15.0).all()
    return bool(in_path and 0 < f["ahead"][onset] <= 60 and abs(dec.max() - wanted) <= max(1.5, 0.25 * wanted))


def ref_tailgate(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f = _ref_frame(scene, agent, other)
    gap, n = f["behind"], len(f["v"])
    follows = (np.abs(f["lat"]) <= 1.5) & (f["off"] <= 15) & (gap > 0) & (f["v"] >= 5) & (np.arange(n) < f["contact"])
    headway = np.where(follows, gap / np.maximum(f["v"], 1e-6), np.inf)
    k = _ref_first_run(headway < 0.6, 10, n + 1)
    return k is not None and 0.2 <= float(np.median(headway[headway < 0.6])) <= 0.6


def ref_pull_out(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f = _ref_frame(scene, agent, other)
    waiting = (np.abs(f["lat"]) > 2.5) & (f["v"] <= 3.0)
    on_way = np.flatnonzero((np.abs(f["lat"]) <= 1.5) & (f["ahead"] > 0))
    if not on_way.size or not waiting[: on_way[0]].any() or on_way[0] >= f["contact"]:
        return False
    entry = int(on_way[0])
    set_off = int(np.flatnonzero(waiting[:entry])[-1])
    speed = f["v_other"][set_off]
    return entry - set_off <= 40 and speed >= 3.0 and 1.0 <= f["ahead"][entry] / speed <= 3.0


def ref_red_light(scene: Scenario, agent: int, other: int, asked: Mapping[str, float]) -> bool:
    f, lights = _ref_frame(scene, agent, other), scene.traffic_lights
    if lights is None:
        return False
    u = np.stack([np.cos(f["heading"]), np.sin(f["heading"])], axis=1)
    to_stop = ((lights.stop_points[0, :2] - f["xy"]) * u).sum(1) - f["length"] / 2
    passed = np.flatnonzero((to_stop[:-1] > 0) & (to_stop[1:] <= 0)) + 1
    now = scene.current_index
    if not passed.size or lights.states[now + passed[0], 0] != TrafficLightState.STOP:
        return False
    run = int(passed[0])
    if abs(f["lat"][run]) <= 2.5 or f["contact"] <= run:
        return False
    near = np.flatnonzero(np.abs(f["lat"][run : run + 41]) < 1.0)
    if not near.size or run + near[0] >= f["contact"]:
        return False
    ahead = f["along"][run + near[0]] - f["other_length"][run] / 2
    return bool(0 < ahead <= max(4 * f["v_other"][run], 15.0))


def _judge(behaviour: str, scene: Scenario, agent: int, other: int, asked: Mapping[str, float]):
    """The behaviour's judge by numbers, through the registry, its parameters' defaults where `asked` gives none."""
    judged = kind(behaviour)
    return judged.judge(scene, agent, other, {**judged.asked({}), **asked})


REFERENCE: dict[str, Callable[[Scenario, int, int, Mapping[str, float]], bool]] = {
    "cut_in": ref_cut_in,
    "overtake_cut_in": ref_overtake,
    "brake_hard": ref_brake,
    "tailgate": ref_tailgate,
    "pull_out": ref_pull_out,
    "run_red_light": ref_red_light,
}


@pytest.mark.parametrize("name", list(EPISODES))
def test_each_judge_and_the_reference_agree_on_every_constructed_episode(name):
    case = EPISODES[name]
    judgement = _judge(case.behaviour, case.scene, 2, 1, case.asked)
    assert judgement.happened is case.happened, f"{name} ({case.what}): {judgement.why}"
    assert bool(REFERENCE[case.behaviour](case.scene, 2, 1, case.asked)) is case.happened, (
        f"{name}: the reference disagrees"
    )
    assert judgement.why and "\n" not in judgement.why
    if case.happened:
        assert judgement.done_step is not None and all(m.ok is not False for m in judgement.measures)


def test_every_behaviour_has_a_judge_and_episodes_of_each_kind():
    judged = {name for name in KINDS.names() if kind(name).judged is not None}
    assert (
        judged == set(REFERENCE) == {"cut_in", "overtake_cut_in", "brake_hard", "tailgate", "pull_out", "run_red_light"}
    )
    for behaviour in judged:
        kinds = {c.what for c in EPISODES.values() if c.behaviour == behaviour}
        assert len(kinds) >= 5, behaviour


def _measure(judgement, name: str) -> Measure:
    return next(m for m in judgement.measures if m.name == name)


def test_a_cut_in_reports_its_gap_beside_the_asked_one():
    met = _judge("cut_in", EPISODES["cut_in met"].scene, 2, 1, {"gap": 15.0})
    gap = _measure(met, "gap")
    assert gap.asked == 15.0 and gap.realised == pytest.approx(15.0, abs=0.05) and gap.tolerance == 3.0 and gap.ok
    assert 3.0 <= _measure(met, "time to settle").realised <= 4.0 and met.contact_step is None
    assert _judge("cut_in", EPISODES["cut_in met"].scene, 2, 1, {"gap": 40.0}).measures[0].tolerance == 8.0
    missed = _judge("cut_in", EPISODES["cut_in a lot"].scene, 2, 1, {"gap": 15.0})
    assert missed.why == "gap 2.5 m done, 15 m asked (+-3 m)"
    assert missed.measures[0].describe() == "gap 15 m asked, 2.5 m done (+-3 m)"
    short = _judge("cut_in", EPISODES["cut_in half in, touching"].scene, 2, 1, {})
    assert short.why.startswith("cut short by a contact at ") and short.done_step is None and short.contact_step
    away = _judge("cut_in", EPISODES["cut_in out of path"].scene, 2, 1, {})
    assert "1.8 m to its side" in away.why and away.measures[0].realised is None
    lead = _judge("cut_in", episode({1: track(10 * t, 0.0), 2: track(20 + 10 * t, 0.2)}), 2, 1, {})
    assert "from the start" in lead.why


def test_a_cut_ins_gap_is_read_when_it_enters_the_lane_and_a_follower_that_fell_back_is_named():
    # the ego brakes from 10 to 6 m/s from 2.5 s, as the cutter (10 m ahead) enters its lane: the gap opens after
    ego_speed = 10.0 - 4.0 * np.clip((t - 2.5) / 2.0, 0.0, 1.0)
    lateral = 3.5 - 3.5 * smooth(1.0, 3.0)
    braking = episode({1: track(travelled(ego_speed), 0.0), 2: track(LENGTH + 10.0 + 10 * t, lateral)})
    entered_then = _judge("cut_in", braking, 2, 1, {"gap": 10.0})
    assert entered_then.happened and _measure(entered_then, "gap").realised == pytest.approx(10.6, abs=0.6)
    assert ref_cut_in(braking, 2, 1, {"gap": 10.0})
    # the ego brakes from the start: by the time the cutter enters its lane the gap has grown, the ego's doing
    early = 10.0 - 4.0 * np.clip(t / 1.5, 0.0, 1.0)
    fell_back = episode({1: track(travelled(early), 0.0), 2: track(LENGTH + 10.0 + 10 * t, lateral)})
    wide = _judge("cut_in", fell_back, 2, 1, {"gap": 10.0})
    assert not wide.happened and wide.why.endswith("@1 had slowed from 9.9 to 6.0 m/s by then (its own doing)")


def test_an_overtake_reports_its_passing_speed_and_passes_on_its_own_side():
    met = _judge("overtake_cut_in", EPISODES["overtake met"].scene, 2, 1, {})
    assert _measure(met, "passing speed").realised == pytest.approx(16.0, abs=0.2)
    assert _measure(met, "faster than the other").realised == pytest.approx(6.0, abs=0.2)
    assert _measure(met, "gap").realised == pytest.approx(10.0, abs=0.1)
    far = _judge("overtake_cut_in", EPISODES["overtake far side"].scene, 2, 1, {})
    over = _measure(far, "over to the far side")
    assert over.realised == pytest.approx(3.5, abs=0.1) and over.ok is False and "over to the far side" in far.why
    plain = _judge("overtake_cut_in", EPISODES["cut_in met"].scene, 2, 1, {})
    assert "a cut-in, not an overtake" in plain.why


def test_a_braking_lead_reports_its_peak_and_whether_it_stayed_in_the_path():
    met = _judge("brake_hard", EPISODES["brake met"].scene, 2, 1, {"deceleration": 6.0})
    assert _measure(met, "peak deceleration").realised == pytest.approx(6.0, abs=0.1)
    assert _measure(met, "off the path").realised < 0.1 and _measure(met, "speed when braking began").realised > 11
    hard = _judge("brake_hard", EPISODES["brake a lot"].scene, 2, 1, {"deceleration": 6.0})
    assert hard.why == "peak deceleration 11 m/s^2 done, 6 m/s^2 asked (+-1.5 m/s^2)"
    off = _judge("brake_hard", EPISODES["brake out of path"].scene, 2, 1, {"deceleration": 6.0})
    assert off.why.startswith("did not brake in front of @1: it left its path while braking (2.3 m to the side")
    assert _measure(off, "turned off the path").realised > 15
    # a third car moves from the next lane into the 30-m gap between them, 12 m behind the lead, as it brakes
    base = EPISODES["brake met"].scene
    lead, ego = base.agents.xy[1], base.agents.xy[0]
    between = episode({1: track(ego[:, 0], 0.0), 2: track(lead[:, 0], 0.0),
                       3: track(lead[:, 0] - 12.0 - LENGTH, 3.5 * (1.0 - smooth(0.5, 1.0)))})  # fmt: skip
    cut = _judge("brake_hard", between, 2, 1, {"deceleration": 6.0})
    assert cut.happened is False and cut.why.startswith("@3 came between @1 and it at 1.")
    short = _judge("brake_hard", EPISODES["brake contact"].scene, 2, 1, {})
    assert "cut short by a contact at 1." in short.why


def test_a_tailgater_reports_its_headways_and_time_under_the_line():
    met = _judge("tailgate", EPISODES["tailgate met"].scene, 2, 1, {})
    assert _measure(met, "headway").realised == pytest.approx(0.4, abs=0.01)
    assert _measure(met, "time under 0.6 s").realised >= 5.0 and _measure(met, "shortest headway").realised < 0.41
    far = _judge("tailgate", EPISODES["tailgate a lot"].scene, 2, 1, {})
    assert "not the 1 s tailgating needs" in far.why and _measure(far, "headway").realised == pytest.approx(1.0, 0.01)
    assert _judge("tailgate", EPISODES["tailgate too close"].scene, 2, 1, {}).why.startswith("headway 0.1 s done")
    assert "never behind @1" in _judge("tailgate", EPISODES["tailgate out of path"].scene, 2, 1, {}).why
    # the ego brakes to a stand from 1 s on: the tailgater, 1.5 s behind and slowing with it, never closes in; the
    # reason says the ego's doing, measured
    ego = 30.0 + np.where(t < 1.0, 10 * t, 10.0 + 10 * (t - 1.0) - 2.5 * (t - 1.0) ** 2)
    ego = np.where(t < 3.0, ego, 30.0 + 10.0 + 10.0 * 2.0 - 2.5 * 4.0)
    stopped = episode({1: track(ego, 0.0), 2: track(ego - LENGTH - 15.0, 0.0)})
    assert _judge("tailgate", stopped, 2, 1, {}).why.endswith("@1 came to a stand (from 10.0 m/s; its own doing)")
    with pytest.raises(InputError, match="unknown asked values gap"):
        _judge("tailgate", EPISODES["tailgate met"].scene, 2, 1, {"gap": 3.0})


def test_a_pull_out_reports_its_margin_at_the_others_speed_when_it_set_off():
    met = _judge("pull_out", EPISODES["pull_out met"].scene, 2, 1, {})
    assert _measure(met, "margin").realised == pytest.approx(2.0, abs=0.15)
    assert _measure(met, "other's speed when it set off").realised == pytest.approx(10.0, abs=0.1)
    late = _judge("pull_out", EPISODES["pull_out contact"].scene, 2, 1, {})
    assert late.why.startswith("cut short by a contact")
    assert _judge("pull_out", EPISODES["pull_out out of path"].scene, 2, 1, {}).why == "never came onto @1's way"
    assert _judge("pull_out", EPISODES["pull_out a lot"].scene, 2, 1, {}).why == "margin 5 s done, 2 s asked (+-1 s)"
    # the ego slows from 10 to 4 m/s from 0.5 s on: a pull-out timed for it at 10 m/s comes out far ahead, and the
    # reason says the ego's doing, measured
    puller = EPISODES["pull_out met"].scene.agents.xy[1]  # @2, set off for an ego at 10 m/s
    ego = -40.0 + travelled(np.clip(10.0 - 2.0 * np.clip(t - 0.5, 0.0, None), 4.0, 10.0))
    slowing = episode({1: track(ego, 0.0), 2: track(puller[:, 0], puller[:, 1], math.pi / 2)})
    why = _judge("pull_out", slowing, 2, 1, {}).why
    assert why.startswith("margin ") and why.endswith("@1 slowed from 10.0 to 4.0 m/s meanwhile (its own doing)")


def test_a_red_light_run_reports_when_it_crossed_on_red_and_its_lead_over_the_other():
    met = _judge("run_red_light", EPISODES["red met"].scene, 2, 1, {})
    assert _measure(met, "crossing on red").realised == pytest.approx(3.0, abs=0.1)
    assert _measure(met, "red for").realised == pytest.approx(3.0, abs=0.1)
    assert _measure(met, "other's front to the crossing").realised == pytest.approx(12.0, abs=1.0)
    assert _measure(met, "time ahead of the other").realised == pytest.approx(1.5, abs=0.15)
    assert "was there first" in _judge("run_red_light", EPISODES["red behind"].scene, 2, 1, {}).why
    assert "on go, not red" in _judge("run_red_light", EPISODES["red on green"].scene, 2, 1, {}).why
    assert "never crossed @1's path" in _judge("run_red_light", EPISODES["red out of path"].scene, 2, 1, {}).why
    dark = replace(EPISODES["red met"].scene, traffic_lights=None)
    assert _judge("run_red_light", dark, 2, 1, {}).why == "never crossed a signal's stop line"
    # a runner standing short of its line all along, the other crawling 40 m off: the other's driving, measured
    lights = EPISODES["red met"].scene.traffic_lights
    held = episode({1: track(1.75, -40.0 + 1.0 * t), 2: track(np.full_like(t, -14.0), -1.75)}, lights)
    assert _judge("run_red_light", held, 2, 1, {}).why == (
        "never crossed a signal's stop line: it stood short of it from 0 s (waiting for @1); @1 drove at 1.0 m/s "
        "meanwhile and came no nearer than 34 m"
    )


def test_measures_and_judgements_as_json_and_lines():
    m = Measure("gap", "m", 15.0, 2.5, 3.0, False)
    assert m.to_json() == {
        "name": "gap", "unit": "m", "asked": 15.0, "realised": 2.5, "tolerance": 3.0, "ok": False,
        "describe": "gap 15 m asked, 2.5 m done (+-3 m)",
    }  # fmt: skip
    assert m.describe() == "gap 15 m asked, 2.5 m done (+-3 m)" and m.missed() == "gap 2.5 m done, 15 m asked (+-3 m)"
    assert Measure("passing speed", "m/s", None, 14.23, None, None).describe() == "passing speed 14.2 m/s done"
    assert Measure("gap", "m", 10.0, None, 3.0, False).describe() == "gap 10 m asked, never done (+-3 m)"
    judgement = _judge("cut_in", EPISODES["cut_in met"].scene, 2, 1, {"gap": 15.0})
    data = judgement.to_json()
    assert data["happened"] is True and data["measures"][0]["name"] == "gap" and data["contact_step"] is None
    with pytest.raises(InputError, match=r"asked\.gap"):
        _judge("cut_in", EPISODES["cut_in met"].scene, 2, 1, {"gap": -1.0})
    with pytest.raises(InputError, match="@9 is not in the scene"):
        _judge("cut_in", EPISODES["cut_in met"].scene, 9, 1, {})
    gone = EPISODES["cut_in met"].scene
    valid = gone.agents.valid.copy()
    valid[0, NOW:] = False  # the ego is not seen after the start
    gone = replace(gone, agents=replace(gone.agents, valid=valid))
    for behaviour in REFERENCE:
        judged = _judge(behaviour, gone, 2, 1, {})
        assert not judged.happened and judged.why.endswith("never in the scene together after its start"), behaviour


def test_box_overlap_by_separating_axes():
    xy = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    other = np.array([[4.4, 0.0], [4.6, 0.0], [3.5, 2.5]])
    size = np.array([[LENGTH, WIDTH]] * 3)
    turned = np.array([0.0, 0.0, math.pi / 4])
    assert boxes_overlap(xy, np.zeros(3), size, other, turned, size).tolist() == [True, False, True]


def _real_scene(real_data_dir) -> Scenario:
    from langtraj.scenario.io import read_scenario

    path = real_data_dir / "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl"
    if not path.is_file():
        pytest.skip(f"{path.name} not found in {real_data_dir}")
    return read_scenario(path, 0)


def _on_path(path: np.ndarray, station: np.ndarray, left: np.ndarray) -> np.ndarray:
    """[T, 3] x, y, heading at `station` along the polyline `path` and `left` of it."""
    steps = np.diff(path, axis=0)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*steps.T))])
    x, y = np.interp(station, arc, path[:, 0]), np.interp(station, arc, path[:, 1])
    h = np.interp(station, 0.5 * (arc[1:] + arc[:-1]), np.unwrap(np.arctan2(steps[:, 1], steps[:, 0])))
    return track(x - np.sin(h) * left, y + np.cos(h) * left, float(h[0]))


def _overwrite(scene: Scenario, tracks: Mapping[int, np.ndarray]) -> Scenario:
    states = scene.agents.states.copy()
    for track_id, new in tracks.items():
        row = int(np.flatnonzero(scene.agents.ids == track_id)[0])
        states[row, NOW:, [0, 1, 3]] = new[NOW:].T
    return replace(scene, agents=replace(scene.agents, states=states))


def test_constructed_cut_in_and_braking_lead_on_a_real_scene(real_data_dir):
    """On 8a34, the ego (1101) drives its logged path at 11 m/s; 741 cuts in on it from its right lane, then 738 ahead
    of it brakes hard, each overwriting their logged futures; the reference judge agrees."""
    scene = _real_scene(real_data_dir)
    rows = {int(i): k for k, i in enumerate(scene.agents.ids)}
    logged = scene.agents.states[rows[1101], NOW:, :2].astype(float)
    first, last = logged[1] - logged[0], logged[-1] - logged[-2]
    path = np.vstack([logged[0] - 300 * first / np.hypot(*first), logged, logged[-1] + 300 * last / np.hypot(*last)])
    half = 0.5 * (scene.agents.states[rows[1101], NOW, 6] + scene.agents.states[rows[741], NOW, 6])
    ego = _on_path(path, 300.0 + 11.0 * t, np.zeros(T))
    for gap, asked, happened in ((12.0, 12.0, True), (12.0, 25.0, False)):
        cutter = _on_path(path, 300.0 + 11.0 * t + gap + half, -3.4 + 3.4 * smooth(1.0, 3.0))
        played = _overwrite(scene, {1101: ego, 741: cutter})
        judgement = _judge("cut_in", played, 741, 1101, {"gap": asked})
        assert judgement.happened is happened, judgement.why
        assert bool(ref_cut_in(played, 741, 1101, {"gap": asked})) is happened
        assert _measure(judgement, "gap").realised == pytest.approx(gap, abs=0.3)
    braking = travelled(np.maximum(11.0 - 6.0 * np.clip(t - 1.0, 0, None), 0.0))
    follower = _on_path(path, 300.0 + travelled(np.maximum(11.0 - 4.0 * np.clip(t - 1.5, 0, None), 0.0)), np.zeros(T))
    for swerve, happened in ((0.0, True), (2.5, False)):
        lead = _on_path(path, 330.0 + braking, -swerve * smooth(1.1, 1.2))
        played = _overwrite(scene, {1101: follower, 738: lead})
        judgement = _judge("brake_hard", played, 738, 1101, {"deceleration": 6.0})
        assert judgement.happened is happened, judgement.why
        assert bool(ref_brake(played, 738, 1101, {"deceleration": 6.0})) is happened
        if swerve:
            assert "it left its path while braking (2.5 m to the side" in judgement.why
        else:
            assert _measure(judgement, "peak deceleration").realised == pytest.approx(6.0, abs=0.3)


def test_a_cut_in_that_never_settled_says_how_the_other_drove_meanwhile():
    # the cutter keeps 10 m/s in the lane beside; the other speeds up from 10 to 16 m/s and leaves it behind
    fast = 10.0 + 6.0 * np.clip(t / 3.0, 0.0, 1.0)
    sped = episode({1: track(travelled(fast), 0.0), 2: track(10 * t, 3.5)})
    away = _judge("cut_in", sped, 2, 1, {"gap": 10.0})
    assert not away.happened and away.why.endswith("@1 sped up from 10.0 to 16.0 m/s meanwhile (its own doing)")
    # ... or stops
    stops = np.clip(10.0 - 4.0 * t, 0.0, None)
    stood = episode({1: track(travelled(stops), 0.0), 2: track(10 * t, 3.5)})
    why = _judge("cut_in", stood, 2, 1, {}).why
    assert why.endswith("@1 came to a stand (from 9.9 m/s; its own doing)")
    # where it stayed beside the other against the asked gap: level with it (4.5 m behind its front), then far ahead
    assert "(at closest 3.5 m to its side): beside it, from 4 m behind @1's front to " in why
    assert "m ahead (10 m asked)" in why
    # an other that keeps its speed is not named
    assert "its own doing" not in _judge("cut_in", EPISODES["cut_in out of path"].scene, 2, 1, {}).why


def test_a_cut_in_held_back_by_a_car_ahead_in_its_own_lane_names_it():
    # the cutter keeps 2 m ahead of the other, beside it, 10 m behind a car in its own lane: short of the asked 10 m
    held = episode({1: track(10 * t, 0.0), 2: track(10 * t + 2.0, 3.5), 3: track(10 * t + 16.5, 3.5)})
    why = _judge("cut_in", held, 2, 1, {"gap": 10.0}).why
    assert "; held behind @3 in its own lane (10-10 m ahead of it)" in why
    free = episode({1: track(10 * t, 0.0), 2: track(10 * t + 2.0, 3.5), 3: track(10 * t + 16.5, 7.0)})
    assert "held behind" not in _judge("cut_in", free, 2, 1, {"gap": 10.0}).why  # the car is a lane further over
