"""What the numbers judges share: the `Measure` (asked beside realised) and `Judgement` records, and the numpy
geometry they read a played pair of agents by: positions along and across the other agent's own driven path, speeds
and decelerations from positions, and oriented-box contacts (docs/testing.md, 'Judged by numbers').

Every judge reads the played scene only, from its current step to its end, and never a map lane: "the other's path"
is where the other agent actually drove, extended straight at both ends. Steps are counted from the current step (0),
as the env counts an episode's steps, so a judgement's `done_step` and `contact_step` read as the suite's collision
steps do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.polylines import arc_lengths, point_at, project_on_polyline, resample
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField

PATH_SPACING_M = 0.5
"""Spacing of the other's driven path (m): fine enough that a lateral offset is read to centimetres."""
PATH_EXTENSION_M = 150.0
"""How far the driven path is extended straight past both ends (m): an agent ahead of where the other stopped, or
behind where it started, still has a place along it."""
MIN_PATH_M = 1.0
"""A driven path shorter than this (m) is a standing agent's: its heading line through where it stood stands in."""
PATH_HEADING_SPAN_M = 1.5
"""The path's heading at a station is the direction between the points this far (m) before and after it, so that a
standing agent's jitter does not turn it."""
SMOOTH_STEPS = 3
"""Speeds from positions are averaged over this many steps (light smoothing: a step change of speed is spread over
0.2 s either side, the 0.5-s decelerations read through it unchanged)."""
IN_PATH_LATERAL_M = 1.5
"""A centre this close to the other's path (m) is in it: the interaction detector's leader lateral
(`DetectorConfig.leader_lateral`), so that a car this near covers the other's path with part of its width."""
IN_PATH_HEADING = math.radians(15.0)
"""Heading along the other's path within this (rad): a braking lead swerving further, or a tailgater turned further,
is not in the path (lane changes turn 3 to 8 degrees)."""
EPSILON_SPEED = 0.1
"""The least speed (m/s) a time gap divides by: a standing agent's time gap is its gap over this."""


def _number(value: float) -> str:
    """`value` for a line of text: one decimal from 10 on, two below, trailing zeros dropped (15, 2.5, 0.43)."""
    text = f"{value:.1f}" if abs(value) >= 10 else f"{value:.2f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def amount(value: float | None, unit: str) -> str:
    """A number of a measure with its unit, as every line and report writes it: `2.5 m`, `14.2 m/s`; `never` for
    None."""
    return "never" if value is None else f"{_number(value)} {unit}"


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(float(value), 3)


@dataclass(frozen=True)
class Measure:
    """One number of a manoeuvre: `asked` (None: nothing is asked, the figure is reported) beside `realised` (None:
    the manoeuvre never got that far), within `tolerance` either side of `asked` (None: none applies), and `ok`
    (None: the measure decides nothing; else whether it holds)."""

    name: str
    unit: str
    asked: float | None
    realised: float | None
    tolerance: float | None
    ok: bool | None

    def __post_init__(self) -> None:
        # rounded to the millimetre once, so that every line, report and JSON file shows the same figure
        for key in ("asked", "realised", "tolerance"):
            object.__setattr__(self, key, _rounded(getattr(self, key)))
        object.__setattr__(self, "ok", None if self.ok is None else bool(self.ok))

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "unit": self.unit,
            "asked": self.asked,
            "realised": self.realised,
            "tolerance": self.tolerance,
            "ok": self.ok,
            "describe": self.describe(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Measure:
        """The measure `to_json` wrote (its `describe` line is derived, so not read back)."""
        return cls(*(data[k] for k in ("name", "unit", "asked", "realised", "tolerance", "ok")))

    def _tolerance(self) -> str:
        return "" if self.tolerance is None else f" (+-{amount(self.tolerance, self.unit)})"

    def describe(self) -> str:
        """One line, asked first: `gap 15 m asked, 2.5 m done (+-3 m)`; `passing speed 14.2 m/s done`; `gap 10 m
        asked, never done (+-3 m)`."""
        done = "never done" if self.realised is None else f"{amount(self.realised, self.unit)} done"
        if self.asked is None:
            return f"{self.name} {done}"
        return f"{self.name} {amount(self.asked, self.unit)} asked, {done}{self._tolerance()}"

    def missed(self) -> str:
        """One line, realised first, for why a judgement failed: `gap 2.5 m done, 15 m asked (+-3 m)`."""
        done = "never done" if self.realised is None else f"{amount(self.realised, self.unit)} done"
        if self.asked is None:
            return f"{self.name} {done}"
        return f"{self.name} {done}, {amount(self.asked, self.unit)} asked{self._tolerance()}"


@dataclass(frozen=True)
class Judgement:
    """Whether a pair behaviour `happened` by its numbers: completed within tolerance before any contact between the
    two; its `measures`, `why` (one line for reports), `done_step` (when it was completed, counted from the current
    step; None: never) and `contact_step` (the two agents' first contact, likewise; None: none)."""

    happened: bool
    measures: tuple[Measure, ...]
    why: str
    done_step: int | None
    contact_step: int | None

    def to_json(self) -> dict[str, Any]:
        return {
            "happened": self.happened,
            "measures": [m.to_json() for m in self.measures],
            "why": self.why,
            "done_step": self.done_step,
            "contact_step": self.contact_step,
        }


def at(step: int) -> str:
    """`step` (counted from the current step) as the time it happened: `3.4 s`."""
    return f"{_number(step * STEP_SECONDS)} s"


def cut_short(contact_step: int) -> str:
    """The reason of a manoeuvre that a contact ended before it was done."""
    return f"cut short by a contact at {at(contact_step)}"


def asked_value(asked: Mapping[str, float], key: str) -> float:
    """`asked[key]`, a finite number >= 0 (the behaviour's parameter, its default where the prompt gives none:
    `BehaviourKind.asked`); a missing or bad one is an InputError naming the key."""
    if key not in asked:
        raise InputError("not given", where=f"asked.{key}")
    value = float(asked[key])
    if not math.isfinite(value) or value < 0:
        raise InputError(f"must be a finite number >= 0, got {value}", where=f"asked.{key}")
    return value


def smoothed(values: np.ndarray, width: int = SMOOTH_STEPS) -> np.ndarray:
    """A centred moving average of `values` [n] over `width` steps, NaN left out (NaN where a value is NaN)."""
    known = np.isfinite(values)
    if width <= 1 or not known.any():
        return values.copy()
    kernel = np.ones(width)
    total = np.convolve(np.where(known, values, 0.0), kernel, mode="same")
    count = np.convolve(known.astype(np.float64), kernel, mode="same")
    return np.where(known, total / np.maximum(count, 1.0), np.nan)


def speeds(xy: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Speed [n] (m/s) from positions [n, 2] at valid steps: the mean of the displacements into and out of each step
    over 0.1 s, then `smoothed`; NaN where the agent is not valid or has no valid neighbour."""
    p = np.where(valid[:, None], xy, np.nan)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1) / STEP_SECONDS  # [n - 1], NaN across a gap
    both = np.stack([np.concatenate([[np.nan], step]), np.concatenate([step, [np.nan]])])
    known = np.isfinite(both)
    count = known.sum(axis=0)
    mean = np.where(count > 0, np.where(known, both, 0.0).sum(axis=0) / np.maximum(count, 1), np.nan)
    return smoothed(np.where(valid, mean, np.nan))


def decelerations(speed: np.ndarray, steps: int) -> np.ndarray:
    """Deceleration [n] (m/s^2, positive slowing down) averaged over the `steps` from each step: (v[t] - v[t + steps])
    / (steps x 0.1 s); NaN where either end is unknown or past the end."""
    out = np.full(len(speed), np.nan)
    if len(speed) > steps:
        out[:-steps] = (speed[:-steps] - speed[steps:]) / (steps * STEP_SECONDS)
    return out


def boxes_overlap(
    xy_a: np.ndarray,
    heading_a: np.ndarray,
    size_a: np.ndarray,
    xy_b: np.ndarray,
    heading_b: np.ndarray,
    size_b: np.ndarray,
) -> np.ndarray:
    """bool [n]: the oriented boxes (centre [n, 2], heading [n], size [n, 2] as length and width) of two agents
    overlap at each step, by the separating-axis test (boxes that only touch along an edge do not)."""
    axes_a = np.stack([np.cos(heading_a), np.sin(heading_a)], axis=-1)
    axes_b = np.stack([np.cos(heading_b), np.sin(heading_b)], axis=-1)
    normals_a, normals_b = axes_a[:, ::-1] * [-1.0, 1.0], axes_b[:, ::-1] * [-1.0, 1.0]
    delta = xy_b - xy_a
    separated = np.zeros(len(xy_a), bool)
    for axis in (axes_a, normals_a, axes_b, normals_b):
        reach_a = 0.5 * (
            size_a[:, 0] * np.abs((axis * axes_a).sum(-1)) + size_a[:, 1] * np.abs((axis * normals_a).sum(-1))
        )
        reach_b = 0.5 * (
            size_b[:, 0] * np.abs((axis * axes_b).sum(-1)) + size_b[:, 1] * np.abs((axis * normals_b).sum(-1))
        )
        separated |= np.abs((delta * axis).sum(-1)) >= reach_a + reach_b
    return ~separated


@dataclass(frozen=True)
class Track:
    """One agent over the played steps from the current step on ([n] arrays; positions NaN where not valid): centre
    `xy` [n, 2], `heading`, `length`, `width`, `valid`, and `speed` from positions (NaN where unknown)."""

    track_id: int
    xy: np.ndarray
    heading: np.ndarray
    length: np.ndarray
    width: np.ndarray
    valid: np.ndarray
    speed: np.ndarray

    @property
    def size(self) -> np.ndarray:
        return np.stack([self.length, self.width], axis=-1)


def track(scene: Scenario, track_id: int) -> Track:
    """Agent `track_id` of `scene` from its current step to its end; an id not in the scene is an InputError."""
    found = np.flatnonzero(scene.agents.ids == track_id)
    if not found.size:
        raise InputError(f"@{track_id} is not in the scene", where="agent")
    start = min(int(scene.current_index), scene.num_steps - 1)
    states = scene.agents.states[int(found[0]), start:].astype(np.float64)
    valid = scene.agents.valid[int(found[0]), start:].astype(bool)
    xy = np.where(valid[:, None], states[:, [StateField.X, StateField.Y]], np.nan)
    return Track(
        track_id=int(track_id),
        xy=xy,
        heading=np.where(valid, states[:, StateField.HEADING], np.nan),
        length=states[:, StateField.LENGTH],
        width=states[:, StateField.WIDTH],
        valid=valid,
        speed=speeds(xy, valid),
    )


def driven_path(other: Track) -> np.ndarray:
    """The polyline [M, 2] where `other` drove from the current step on (every `PATH_SPACING_M`), extended straight by
    `PATH_EXTENSION_M` at both ends; for an agent that moved less than `MIN_PATH_M`, its heading line through where
    it stood. Raises InputError when it is never valid."""
    known = np.flatnonzero(other.valid)
    if not known.size:
        raise InputError(f"@{other.track_id} is not valid after the current step", where="agent")
    line = resample(other.xy[known], PATH_SPACING_M)
    if len(line) < 2 or arc_lengths(line)[-1] < MIN_PATH_M:
        heading = float(other.heading[known[0]])
        base = other.xy[known[0]]
        direction = np.array([math.cos(heading), math.sin(heading)])
        line = np.stack([base - direction * 0.5 * MIN_PATH_M, base + direction * 0.5 * MIN_PATH_M])
    arc = arc_lengths(line)
    reach = min(2.0, float(arc[-1]))
    first = point_at(line, reach) - line[0]
    last = line[-1] - point_at(line, float(arc[-1]) - reach)
    first, last = first / np.linalg.norm(first), last / np.linalg.norm(last)
    return np.vstack([line[0] - first * PATH_EXTENSION_M, line, line[-1] + last * PATH_EXTENSION_M])


@dataclass(frozen=True)
class PairView:
    """Agent `agent` seen from the other agent `other` over the played steps ([n] arrays, NaN where either is not
    valid): `along`, the agent's centre ahead of the other's along the other's driven path (m; negative behind);
    `across`, its centre's offset from that path (m, positive on the path's left); `heading_off`, its heading less
    the path's there (rad); `contact`, the two boxes overlap (bool); `contact_step`, the first such step or None."""

    agent: Track
    other: Track
    along: np.ndarray
    across: np.ndarray
    heading_off: np.ndarray
    contact: np.ndarray
    contact_step: int | None

    @property
    def steps(self) -> int:
        return len(self.along)

    @property
    def both(self) -> np.ndarray:
        return self.agent.valid & self.other.valid

    @property
    def half_lengths(self) -> np.ndarray:
        return 0.5 * (self.agent.length + self.other.length)

    @property
    def gap_ahead(self) -> np.ndarray:
        """Bumper to bumper (m) from the other's front to the agent's rear, along the path (negative: not ahead)."""
        return self.along - self.half_lengths

    @property
    def gap_behind(self) -> np.ndarray:
        """Bumper to bumper (m) from the agent's front to the other's rear, along the path (negative: not behind)."""
        return -self.along - self.half_lengths

    def in_path(self) -> np.ndarray:
        """bool [n]: the agent is in the other's path, its centre within `IN_PATH_LATERAL_M` and its heading within
        `IN_PATH_HEADING` of the path's."""
        with np.errstate(invalid="ignore"):
            return (
                self.both & (np.abs(self.across) <= IN_PATH_LATERAL_M) & (np.abs(self.heading_off) <= IN_PATH_HEADING)
            )

    def before_contact(self) -> np.ndarray:
        """bool [n]: the steps before the two agents' first contact (all of them without one)."""
        out = np.ones(self.steps, bool)
        if self.contact_step is not None:
            out[self.contact_step :] = False
        return out


def pair_view(scene: Scenario, agent: int, other: int) -> PairView:
    """Track `agent` seen from track `other` in the played `scene` (`PairView`; NaN throughout when the two are never
    valid together after the current step, `not_seen`); InputError when either is not in the scene."""
    a, o = track(scene, agent), track(scene, other)
    n = len(a.valid)
    if not (a.valid & o.valid).any():
        nan = np.full(n, np.nan)
        return PairView(a, o, nan, nan.copy(), nan.copy(), np.zeros(n, bool), None)
    path = driven_path(o)
    arc = arc_lengths(path)
    station_a, station_o, across = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    if a.valid.any():
        found = project_on_polyline(a.xy[a.valid], path)
        station_a[a.valid], across[a.valid] = found.station, found.offset
    station_o[o.valid] = project_on_polyline(o.xy[o.valid], path).station
    both = a.valid & o.valid
    along = np.where(both, station_a - station_o, np.nan)
    across = np.where(both, across, np.nan)
    heading_off = np.full(n, np.nan)
    if both.any():
        s = station_a[both]
        ahead = point_at(path, np.minimum(s + PATH_HEADING_SPAN_M, arc[-1]))
        behind = point_at(path, np.maximum(s - PATH_HEADING_SPAN_M, 0.0))
        path_heading = np.arctan2(ahead[:, 1] - behind[:, 1], ahead[:, 0] - behind[:, 0])
        heading_off[both] = wrap_angle(a.heading[both] - path_heading)
    contact = np.zeros(n, bool)
    if both.any():
        contact[both] = boxes_overlap(
            a.xy[both], a.heading[both], a.size[both], o.xy[both], o.heading[both], o.size[both]
        )
    hits = np.flatnonzero(contact)
    return PairView(
        agent=a,
        other=o,
        along=along,
        across=across,
        heading_off=heading_off,
        contact=contact,
        contact_step=int(hits[0]) if hits.size else None,
    )


def not_seen(view: PairView) -> str | None:
    """Why the pair cannot be judged at all (the two never valid together after the current step), or None."""
    if not view.both.any():
        return f"@{view.agent.track_id} and @{view.other.track_id} are never in the scene together after its start"
    return None


FELL_BACK_MPS = 2.0
"""How much the other must change its speed (m/s) for a judge to say so (`how_other_drove`); a cut-in's gap wider than
asked is the other's doing where it had slowed this much by the time the cut-in entered its lane."""


STOOD_MPS = 0.5
"""The speed (m/s) at or under which an agent stands: the other came to a stand (`how_other_drove`), a red-light
runner waited."""


def how_other_drove(view: PairView) -> str | None:
    """One line saying how the other changed its speed over the played steps where it did by `FELL_BACK_MPS` or more
    (sped up, slowed, or came to a stand), else None: a manoeuvre that never came about beside an ego that sped away
    or stopped reads as the ego's doing, measured."""
    speed = view.other.speed
    known = np.flatnonzero(np.isfinite(speed))
    if known.size < 2:
        return None
    first, last, least = float(speed[known[0]]), float(speed[known[-1]]), float(np.nanmin(speed))
    name = f"@{view.other.track_id}"
    if least <= STOOD_MPS < first:
        return f"{name} came to a stand (from {first:.1f} m/s; its own doing)"
    if last >= first + FELL_BACK_MPS:
        return f"{name} sped up from {first:.1f} to {last:.1f} m/s meanwhile (its own doing)"
    if last <= first - FELL_BACK_MPS:
        return f"{name} slowed from {first:.1f} to {last:.1f} m/s meanwhile (its own doing)"
    return None


@dataclass(frozen=True)
class Around:
    """Every agent of a played scene at some played steps, seen from one track's centre along its heading ([A, S]):
    how far its centre is `ahead` (m), how far it is `off` the heading line (m), its `half` length (m), and whether it
    `counts` (valid there, not one of the pair judged); `ids` [A] their track ids."""

    ids: np.ndarray
    ahead: np.ndarray
    off: np.ndarray
    half: np.ndarray
    counts: np.ndarray


def around(scene: Scenario, seen_from: Track, steps: np.ndarray, pair: tuple[int, int]) -> Around:
    """The agents of `scene` at the played `steps` (counted from its current step) seen from `seen_from` (`Around`),
    the two of `pair` not counted: who held a cut-in back in its own lane, who came between a braking lead and its
    follower."""
    agents = scene.agents
    rows = min(int(scene.current_index), scene.num_steps - 1) + steps
    states = agents.states[:, rows].astype(np.float64)  # [A, S, F]
    rel = states[..., [StateField.X, StateField.Y]] - seen_from.xy[steps][None]
    cos, sin = np.cos(seen_from.heading[steps])[None], np.sin(seen_from.heading[steps])[None]
    counts = agents.valid[:, rows] & ~np.isin(agents.ids, pair)[:, None]
    return Around(
        agents.ids,
        rel[..., 0] * cos + rel[..., 1] * sin,
        np.abs(rel[..., 1] * cos - rel[..., 0] * sin),
        0.5 * states[..., StateField.LENGTH],
        counts,
    )
