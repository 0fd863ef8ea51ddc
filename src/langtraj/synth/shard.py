"""One shard: build a (kind, seed) network and demand, simulate it, cut windows, write a TFRecord
(zstd-compressed when the shard's name ends in `.zst`).

A shard is the unit of work of the factory: independent of every other shard, deterministic in its
seed (same seed, byte-identical shard), and written atomically with a JSON sidecar of its statistics.

See docs/data.md.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
import zlib
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.fileio import ZSTD_SUFFIX, atomic_open
from langtraj.scenario.ids import synth_window_id
from langtraj.scenario.io import write_scenarios
from langtraj.scenario.model import STEP_SECONDS, BehaviorEvent, RoadMap, Scenario
from langtraj.synth.demand import write_demand
from langtraj.synth.events import NetContext, extract_events
from langtraj.synth.intents import IntentConfig
from langtraj.synth.mapping import NetMap, build_net_map, crop_road_map
from langtraj.synth.network import BuiltNetwork, get_kind
from langtraj.synth.records import Track
from langtraj.synth.runner import SimulationInput, SimulationLog, simulate
from langtraj.synth.sumo import sumo_version
from langtraj.synth.tracks import build_tracks
from langtraj.synth.windows import Rejection, RunData, SignalTable, WindowConfig, WindowCutter

AUTO_SLACK = 1.6
"""Simulated time per wanted window and centre, in window lengths (room for rejected candidates)."""

AUTO_DURATION_S = (150.0, 900.0)
"""Bounds of the automatic simulation length."""


@dataclass(frozen=True)
class ShardConfig:
    """Per-shard settings: simulated seconds, the window cutting rules and the drivers' decisions.

    `duration_s=None` sizes each simulation to its quota: the warm-up plus `AUTO_SLACK` window lengths
    per window wanted from each interest centre (windows of one centre do not overlap), bounded by
    `AUTO_DURATION_S`.
    """

    duration_s: float | None = None
    window: WindowConfig = field(default_factory=WindowConfig)
    intents: IntentConfig = field(default_factory=IntentConfig)

    def duration_for(self, quota: int, centres: int) -> float:
        """Simulated seconds for a shard that wants `quota` windows from `centres` interest centres."""
        if self.duration_s is not None:
            return float(self.duration_s)
        per_centre = math.ceil(quota / max(centres, 1))
        seconds = self.window.warmup_s + per_centre * self.window.length * STEP_SECONDS * AUTO_SLACK
        low, high = AUTO_DURATION_S
        return float(min(max(round(seconds, 1), low), high))


@dataclass(frozen=True)
class ShardTask:
    """Shard `index` of `kind`: its seed, the most windows it may write, and where."""

    kind: str
    index: int
    seed: int
    quota: int
    path: Path

    @property
    def stats_path(self) -> Path:
        """The JSON sidecar beside the shard: `kind-0000.json` for `kind-0000.tfrecord` and `.tfrecord.zst`."""
        return self._plain_path.with_suffix(".json")

    @property
    def other_path(self) -> Path:
        """The shard's file under the other naming (plain for compressed, compressed for plain), where a run
        with the other compression setting wrote it."""
        plain = self._plain_path
        return plain if plain != self.path else plain.with_name(plain.name + ZSTD_SUFFIX)

    @property
    def _plain_path(self) -> Path:
        return Path(str(self.path).removesuffix(ZSTD_SUFFIX))


def shard_seed(base_seed: int, kind: str, index: int) -> int:
    """The seed of one shard, derived from the run seed, the kind name and the shard index."""
    entropy = [int(base_seed) & 0xFFFFFFFF, zlib.crc32(kind.encode()), int(index)]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


def _net_context(net_map: NetMap) -> NetContext:
    crosswalks = {
        edge: net_map.road_map.by_id[fid].points[:, :2].copy() for edge, fid in sorted(net_map.crossing_ids.items())
    }
    sumo_lane = {fid: name for name, fid in net_map.lane_ids.items()}
    columns: dict[str, list[int]] = {}
    for column, link in enumerate(net_map.signals):
        if link.incoming_lane_id >= 0:
            columns.setdefault(sumo_lane[link.incoming_lane_id], []).append(column)
    return NetContext(
        dict(net_map.junction_of_lane),
        crosswalks,
        net_map.walkingareas,
        {lane: tuple(c) for lane, c in sorted(columns.items())},
        link_direction=dict(net_map.link_direction),
        junction_control=dict(net_map.junction_control),
        junction_legs=dict(net_map.junction_legs),
        intersections=net_map.intersections,
        roundabout_junctions=net_map.roundabout_junctions,
        ending_lanes=net_map.ending_lanes,
    )


def _run_data(log: SimulationLog, tracks: tuple[Track, ...], net_map: NetMap, ctx: NetContext) -> RunData:
    ids = {t.sumo_id: t.track_id for t in tracks}
    signals = SignalTable(
        lane_ids=np.array([s.lane_id for s in net_map.signals], np.int64),
        stop_points=np.array([s.stop_point for s in net_map.signals], np.float64).reshape(-1, 3),
        states=log.signal_states,
    )
    return RunData(
        tracks=tracks,
        events=extract_events(log, tracks, ctx),
        num_steps=log.num_steps,
        collisions=tuple((s, ids.get(a, -1), ids.get(b, -1)) for s, a, b in log.collisions),
        teleports=tuple((s, ids.get(a, -1)) for s, a in log.teleports),
        signals=signals,
    )


def _window_map(road_map: RoadMap, xy: np.ndarray, margin: float) -> RoadMap:
    """The map features near the agents' positions during the window."""
    xy = xy.reshape(-1, 2)
    lo = np.nanmin(xy, axis=0) - margin
    hi = np.nanmax(xy, axis=0) + margin
    return crop_road_map(road_map, lo.tolist(), hi.tolist())


@dataclass
class ShardOutcome:
    """Statistics of one finished shard (also its JSON sidecar)."""

    kind: str
    index: int
    seed: int
    quota: int
    settings: dict[str, Any]
    windows: int
    agents_per_window: list[int]
    agent_types: dict[str, int]
    events: dict[str, int]
    rejections: dict[str, int]
    collisions: int
    teleports: int
    network: dict[str, Any]
    demand: dict[str, Any]
    sumo_version: str
    seconds: float
    decisions: dict[str, int] = field(default_factory=dict)
    """Drivers' decisions in the windows, by kind (`langtraj.synth.intents`)."""
    decisions_ahead: int = 0
    """Windows with an executed decision within `decision_lead_s` after the current step."""
    file: str = ""
    """Name of the shard file in `shards/` (`kind-0000.tfrecord.zst` compressed); empty without windows."""
    bytes: int = 0
    """Size of the shard file on disk."""

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True, indent=1)


def _decisions(scenario: Scenario) -> list[BehaviorEvent]:
    return [e for e in scenario.events if e.kind == "decision" and e.attributes.get("executed")]


def _ahead(scenario: Scenario, event: BehaviorEvent, window: WindowConfig) -> bool:
    """Whether a decision falls within `decision_lead_s` after the window's current step."""
    lo, hi = window.decision_lead_s
    lead = (int(event.attributes["decision_step"]) - scenario.current_index) * STEP_SECONDS
    return lo <= lead <= hi


def cut_windows(
    task: ShardTask, network: BuiltNetwork, run: RunData, net_map: NetMap, config: ShardConfig, meta: dict[str, Any]
) -> tuple[list[Scenario], Counter]:
    """Up to `task.quota` windows in time order (centres interleaved), and the rejection counts. Windows
    around drivers' decisions are cut first (`WindowCutter.candidates`); windows of one centre never overlap."""
    cutter = WindowCutter(run, config.window)
    scenarios: list[tuple[int, int, Scenario]] = []
    rejections: Counter = Counter()
    taken: dict[int, list[int]] = {}
    length = config.window.length
    for c, start in cutter.candidates(network.centres):
        if len(scenarios) >= task.quota:
            break
        if any(abs(start - other) < length for other in taken.get(c, ())):  # windows of one centre do not overlap
            continue
        cut = cutter.cut(network.centres[c], start)
        if isinstance(cut, Rejection):
            rejections[cut.reason] += 1
            continue
        members, ooi, event = cut
        road_map = _window_map(net_map.road_map, cutter.window_xy(members, start), config.window.map_margin_m)
        centre = network.centres[c]
        metadata = {
            **meta,
            "centre": {"label": centre.label, "junction": centre.junction_id, "x": centre.x, "y": centre.y},
            "start_step": start,
            "interaction": None if event is None else event.kind,
        }
        scenario_id = synth_window_id(task.kind, task.seed, c, start)
        scenario = cutter.scenario(members, ooi, start, scenario_id, road_map, metadata)
        if isinstance(scenario, Rejection):
            rejections[scenario.reason] += 1
            continue
        scenarios.append((start, c, scenario))
        taken.setdefault(c, []).append(start)
    return [s for _, _, s in sorted(scenarios, key=lambda t: t[:2])], rejections


def run_shard(task: ShardTask, config: ShardConfig) -> ShardOutcome:
    """Build, simulate, cut and write one shard (atomically, shard first, sidecar last)."""
    began = time.perf_counter()
    rng = np.random.default_rng(task.seed)
    with tempfile.TemporaryDirectory(prefix=f"langtraj-{task.kind}-") as tmp:
        workdir = Path(tmp)
        network = get_kind(task.kind).build(rng, workdir)
        duration = config.duration_for(task.quota, len(network.centres))
        demand = write_demand(network, rng, duration, workdir)
        net_map = build_net_map(network.net_file)
        sim = SimulationInput(
            net_file=network.net_file,
            route_files=(demand.route_file,),
            seed=task.seed % (2**31),
            duration_s=duration,
            signal_links=tuple((s.tls_id, s.link_index) for s in net_map.signals),
            additional_files=network.additional_files,
            intents=config.intents,
            sinks=demand.sinks,
        )
        log = simulate(sim, workdir)
        ctx = _net_context(net_map)
    tracks = build_tracks(log.tracks)
    run = _run_data(log, tracks, net_map, ctx)
    meta = {
        "source": "langtraj.synth",
        "kind": task.kind,
        "seed": task.seed,
        "shard": task.index,
        "network": dict(network.params),
        "demand": dict(demand.params),
        "sumo_version": sumo_version(),
        "duration_s": duration,
    }
    scenarios, rejections = cut_windows(task, network, run, net_map, config, meta)
    task.path.parent.mkdir(parents=True, exist_ok=True)
    if scenarios:  # zstd-compressed when the name ends in .zst
        write_scenarios(task.path, scenarios, "womd")
    else:  # no file for a shard without windows: an empty file is not a valid scenario file
        task.path.unlink(missing_ok=True)
    task.other_path.unlink(missing_ok=True)  # this shard from an earlier run, written the other way: replaced
    outcome = ShardOutcome(
        kind=task.kind,
        index=task.index,
        seed=task.seed,
        quota=task.quota,
        settings=asdict(config),
        windows=len(scenarios),
        agents_per_window=[s.num_agents for s in scenarios],
        agent_types=dict(sorted(sum((Counter(s.agents.type_counts()) for s in scenarios), Counter()).items())),
        events=dict(sorted(Counter(e.kind for s in scenarios for e in s.events).items())),
        rejections=dict(sorted(rejections.items())),
        collisions=len(log.collisions),
        teleports=len(log.teleports),
        network=meta["network"],
        demand=meta["demand"],
        sumo_version=meta["sumo_version"],
        seconds=round(time.perf_counter() - began, 3),
        decisions=dict(sorted(Counter(e.attributes["decision"] for s in scenarios for e in _decisions(s)).items())),
        decisions_ahead=sum(any(_ahead(s, e, config.window) for e in _decisions(s)) for s in scenarios),
        file=task.path.name if scenarios else "",
        bytes=task.path.stat().st_size if scenarios else 0,
    )
    with atomic_open(task.stats_path, "w") as fh:
        fh.write(outcome.to_json())
    return outcome
