"""One SUMO simulation through libsumo, recorded at every 0.1 s step into per-agent tracks.

The runner only records what SUMO says (positions, angles, speeds, lanes, leaders, junction foes,
signal states, collisions, teleports, lane-change output); turning that into box centres, smooth
headings and behaviour events is left to `tracks`, `smoothing` and `events`, which are pure numpy and
testable without SUMO. libsumo holds one simulation per process, so a process runs one at a time.

See docs/data.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from langtraj.scenario.types import AgentType
from langtraj.synth.intents import AppliedDecision, IntentConfig, IntentController
from langtraj.synth.records import LaneChangeRecord, RawTrack
from langtraj.synth.sumo import STEP_LENGTH, SynthError, simulation_options

# TraCI variable ids (traci.constants); spelled out so the runner does not import the TraCI client.
_VAR_SPEED = 0x40
_VAR_POSITION = 0x42
_VAR_ANGLE = 0x43
_VAR_LANE_ID = 0x51
_VAR_LEADER = 0x68
_TL_RED_YELLOW_GREEN_STATE = 0x20

_AGENT_VARS = (_VAR_POSITION, _VAR_ANGLE, _VAR_SPEED, _VAR_LANE_ID)

LEADER_RANGE_M = 60.0
"""Leaders further ahead than this are not recorded."""

FOE_RANGE_M = 50.0
"""Junction foes are looked up for conflicts at most this far ahead of a vehicle."""


@dataclass(frozen=True)
class FoeObservation:
    """At `step`, vehicle `ego` has to respond to (yield to) `foe` at a junction conflict point.

    Distances are to the conflict area entry along each route (negative once inside). `mutual` is True
    when the foe has to respond to the ego as well (equal-rank links such as all-way stops).
    """

    step: int
    ego: str
    foe: str
    ego_lane: str
    foe_lane: str
    ego_dist: float
    foe_dist: float
    mutual: bool


@dataclass(frozen=True)
class SimulationLog:
    """Everything recorded during one simulation; steps are global (step k is at time k * 0.1 s)."""

    tracks: tuple[RawTrack, ...]
    lane_names: tuple[str, ...]
    num_steps: int
    signal_states: np.ndarray  # uint8 [num_steps + 1, num_links] SUMO state characters as bytes
    collisions: tuple[tuple[int, str, str], ...]
    teleports: tuple[tuple[int, str], ...]
    foe_observations: tuple[FoeObservation, ...]
    lane_changes: tuple[LaneChangeRecord, ...]
    decisions: tuple[AppliedDecision, ...] = ()


@dataclass(frozen=True)
class SimulationInput:
    """What to simulate: files, seed, length, the (tls id, link index) pairs to record, and the drivers'
    decisions (`intents`, None for none; `sinks` are the edges where trips of each vehicle class may end)."""

    net_file: Path
    route_files: tuple[Path, ...]
    seed: int
    duration_s: float
    signal_links: tuple[tuple[str, int], ...] = ()
    additional_files: tuple[Path, ...] = ()
    intents: IntentConfig | None = None
    sinks: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


def _agent_type(vclass: str) -> AgentType:
    if vclass == "pedestrian":
        return AgentType.PEDESTRIAN
    if vclass == "bicycle":
        return AgentType.CYCLIST
    return AgentType.VEHICLE


class _Recorder:
    """Subscribes new agents as they depart and appends their subscription results every step."""

    def __init__(self, libsumo, signal_links: Sequence[tuple[str, int]]):
        self.ls = libsumo
        self.tracks: dict[str, RawTrack] = {}
        self.lane_index: dict[str, int] = {}
        self.signal_links = tuple(signal_links)
        self.signal_rows: list[bytes] = []
        self.collisions: list[tuple[int, str, str]] = []
        self.teleports: list[tuple[int, str]] = []
        self.foes: list[FoeObservation] = []
        for tls in sorted({t for t, _ in self.signal_links}):
            libsumo.trafficlight.subscribe(tls, [_TL_RED_YELLOW_GREEN_STATE])

    def _lane(self, name: str) -> int:
        index = self.lane_index.get(name)
        if index is None:
            index = self.lane_index[name] = len(self.lane_index)
        return index

    def _add_vehicle(self, vid: str) -> None:
        v = self.ls.vehicle
        vclass = v.getVehicleClass(vid)
        self.tracks[vid] = RawTrack(
            vid, _agent_type(vclass), vclass, v.getTypeID(vid), v.getLength(vid), v.getWidth(vid), v.getHeight(vid)
        )
        v.subscribe(vid, list(_AGENT_VARS))
        v.subscribeLeader(vid, LEADER_RANGE_M)

    def _add_person(self, pid: str) -> None:
        p = self.ls.person
        self.tracks[pid] = RawTrack(
            pid,
            AgentType.PEDESTRIAN,
            "pedestrian",
            p.getTypeID(pid),
            p.getLength(pid),
            p.getWidth(pid),
            p.getHeight(pid),
        )
        p.subscribe(pid, list(_AGENT_VARS))

    def record(self, step: int) -> None:
        ls = self.ls
        for vid in ls.simulation.getDepartedIDList():
            self._add_vehicle(vid)
        for pid in ls.simulation.getDepartedPersonIDList():
            self._add_person(pid)
        for vid, res in ls.vehicle.getAllSubscriptionResults().items():
            self._append(self.tracks[vid], step, res, res[_VAR_LEADER] or ("", -1.0))
            self._record_foes(step, vid)
        for pid, res in ls.person.getAllSubscriptionResults().items():
            self._append(self.tracks[pid], step, res, ("", -1.0))
        self._record_signals()
        for c in ls.simulation.getCollisions():
            self.collisions.append((step, c.collider, c.victim))
        for vid in ls.simulation.getStartingTeleportIDList():
            self.teleports.append((step, vid))

    def _append(self, track: RawTrack, step: int, res: dict, leader: tuple[str, float]) -> None:
        x, y = res[_VAR_POSITION]
        track.steps.append(step)
        track.rows.append((x, y, res[_VAR_ANGLE], res[_VAR_SPEED]))
        track.lanes.append(self._lane(res[_VAR_LANE_ID]))
        track.leaders.append(leader[0])
        track.gaps.append(leader[1])

    def _record_foes(self, step: int, vid: str) -> None:
        for (
            foe,
            ego_d,
            foe_d,
            _ego_exit,
            foe_exit,
            ego_lane,
            foe_lane,
            ego_resp,
            foe_resp,
        ) in self.ls.vehicle.getJunctionFoes(vid, FOE_RANGE_M):
            if ego_resp and foe_exit > 0.0:
                self.foes.append(FoeObservation(step, vid, foe, ego_lane, foe_lane, ego_d, foe_d, bool(foe_resp)))

    def _record_signals(self) -> None:
        results = self.ls.trafficlight.getAllSubscriptionResults() if self.signal_links else {}
        row = bytes(ord(results[tls][_TL_RED_YELLOW_GREEN_STATE][index]) for tls, index in self.signal_links)
        self.signal_rows.append(row)


def _parse_lane_changes(path: Path) -> tuple[LaneChangeRecord, ...]:
    import xml.etree.ElementTree as ET

    if not path.exists():
        return ()
    records = []
    try:
        for _, elem in ET.iterparse(path):
            if elem.tag in ("changeStarted", "change", "changeEnded"):
                a = elem.attrib
                records.append(
                    LaneChangeRecord(
                        elem.tag,
                        a["id"],
                        round(float(a["time"]) / STEP_LENGTH) + 1,  # the state after the step made at "time"
                        a["from"],
                        a["to"],
                        int(a["dir"]),
                        a["reason"],
                    )
                )
            elem.clear()
    except ET.ParseError as exc:
        raise SynthError(f"{path}: unreadable lane-change output: {exc}") from None
    return tuple(records)


def simulate(sim: SimulationInput, workdir: Path) -> SimulationLog:
    """Run one simulation for `sim.duration_s` seconds and return what was recorded at each step."""
    import libsumo

    lc_path = workdir / "lanechanges.xml"
    options = simulation_options(
        sim.net_file,
        sim.route_files,
        seed=sim.seed,
        end_s=sim.duration_s,
        lanechange_output=lc_path,
        additional_files=sim.additional_files,
    )
    num_steps = round(sim.duration_s / STEP_LENGTH)
    try:
        libsumo.start(["sumo", *options])
    except (libsumo.TraCIException, libsumo.FatalTraCIError) as exc:
        raise SynthError(f"SUMO could not start on {sim.net_file}: {exc}") from None
    try:
        recorder = _Recorder(libsumo, sim.signal_links)
        recorder.signal_rows.append(bytes(len(sim.signal_links)))  # step 0: before the first step, unknown
        intents = sim.intents if sim.intents is not None and sim.intents.enabled else None
        controller = None if intents is None else IntentController(libsumo, intents, sim.seed, sim.sinks)
        for step in range(1, num_steps + 1):
            libsumo.simulationStep()
            recorder.record(step)
            if controller is not None:
                controller.step(step)
    except (libsumo.TraCIException, libsumo.FatalTraCIError) as exc:
        raise SynthError(f"SUMO failed on {sim.net_file}: {exc}") from None
    finally:
        libsumo.close()
    signal_states = np.frombuffer(b"".join(recorder.signal_rows), np.uint8).reshape(
        len(recorder.signal_rows), len(sim.signal_links)
    )
    return SimulationLog(
        tracks=tuple(recorder.tracks.values()),
        lane_names=tuple(recorder.lane_index),
        num_steps=num_steps,
        signal_states=signal_states,
        collisions=tuple(recorder.collisions),
        teleports=tuple(recorder.teleports),
        foe_observations=tuple(recorder.foes),
        lane_changes=_parse_lane_changes(lc_path),
        decisions=() if controller is None else tuple(controller.applied),
    )
