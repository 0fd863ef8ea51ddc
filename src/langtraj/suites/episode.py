"""One episode of a suite case: the planner drives the ego of the LangTraj environment for one seed, the case's
criteria judge what the ego did, and the labelers whether the case's prompts happened (`suites.happened`;
docs/testing.md, 'Scenario suites').

`run_episode` never raises for what a planner or the environment does: a planner that raises, hangs, or answers
with an action of the wrong shape or non-finite values fails the episode with a one-line reason; an exception in
the environment (LangTraj's side) makes it an error, its traceback kept in the result. An InputError the env raises
before the episode starts (the case refused at reset: a prompt naming an agent the model does not drive) is an error
marked `input_error`, which makes the suite's run bad input (`suites.runner`). Each call builds its own
planner and environment from the picklable `EpisodeTask`, so episodes run in any worker process.

Time limits: an in-process planner (`--planner`) gets `step_timeout` seconds per call (construction, reset, each
act) through SIGALRM (`langtraj.suites.deadline`, which says where that cannot interrupt); a planner command
(`--planner-cmd`) gets the same limit per reply from `SubprocessPlanner`, its first reply (the hello)
`START_TIMEOUT_S` at least, for planners that load a model.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.cases import Case
from langtraj.env.spaces import ActionError, checked_action
from langtraj.errors import InputError, one_line
from langtraj.registry import import_object
from langtraj.sim.staging import starts_of
from langtraj.suites.deadline import StepTimeout, deadline
from langtraj.suites.happened import PromptVerdict, judge_prompts, not_happened
from langtraj.suites.traffic import ego_failures, follows_traffic_fault, traffic_faults
from langtraj.suites.verdict import StepRecord, episode_figures, judge

DEFAULT_ENV = "langtraj.env:LangTrajEnv"
"""The environment class episodes run in ("module:Class"); tests swap in a fake with the same interface."""
START_TIMEOUT_S = 30.0
"""The least time a planner command gets for its first reply (it may load a model then)."""
VIDEO_FOLDER = "videos"
LOG_FOLDER = "planner-logs"
"""Under the output folder: the videos of the episodes that did not pass or had a collision, and the stderr of
planner commands."""
CAPTION_CHARS = 120


@dataclass(frozen=True)
class EpisodeTask:
    """Everything one episode needs, picklable for any executor: the suite's name, the case and seed, the planner
    as a spec (`load_planner`) or a command (`SubprocessPlanner`; exactly one of the two), the per-call time limit
    in seconds, the output folder, whether to write a video when the episode does not pass or has a collision, and
    the environment class ("module:Class")."""

    suite: str
    case: Case
    seed: int
    planner: str | None
    planner_cmd: str | None
    step_timeout: float
    out: Path
    video: bool = True
    env: str = DEFAULT_ENV

    @property
    def label(self) -> str:
        """`<case>-seed<k>`: the stem of the episode's video and planner log."""
        return f"{self.case.name}-seed{self.seed}"


@dataclass
class EpisodeResult:
    """What one episode gave (one entry of results.json's `episodes`).

    case, seed: which episode. status: "pass" (every criterion held and every prompt judged was followed), "fail" (a
    criterion failed, or the planner raised, hung or answered a bad action), "not_happened" (every criterion held
    but a prompt was not followed: the case's scenario did not happen, not a pass; `suites.happened`) or "error"
    (LangTraj's environment raised). reasons: one line per failed criterion, prompt not followed, or the failure /
    error (empty when it passed). prompts: each prompt's `PromptVerdict.to_json()` (its reading and whether the
    played episode followed it). prompt_warnings: what the simulation's reading of the prompts asks in vain of the
    map. ego: the ego's track id (None when the env was never
    reset). criteria: each checked criterion's `CriterionResult.to_json()` (empty when the episode did not run to
    its end). figures: `verdict.episode_figures` plus `planner_seconds` (all its calls) and
    `planner_max_step_seconds`. steps: the per-step record (`StepRecord.to_json()`). seconds: the episode's wall
    time. reads_log: whether the planner declared itself a log-replay baseline and was given the ego's logged
    future (`planners.planner_reads_log`). video: the video's path relative to the output folder, or None.
    video_error: why the video could not be written, or None. traceback: the traceback of an error, or of the
    planner's exception that failed the episode, or None. input_error: (message, the case's key or None) of an
    InputError the env raised before the episode started, the case refused as bad input; None otherwise (not in
    results.json: the run stops as bad input).
    """

    case: str
    seed: int
    status: str
    reasons: list[str] = field(default_factory=list)
    prompts: list[dict[str, Any]] = field(default_factory=list)
    prompt_warnings: list[str] = field(default_factory=list)
    ego: int | None = None
    criteria: list[dict[str, Any]] = field(default_factory=list)
    figures: dict[str, Any] = field(default_factory=dict)
    steps: dict[str, list] = field(default_factory=dict)
    seconds: float = 0.0
    reads_log: bool = False
    traffic: dict[str, Any] | None = None
    traffic_fault: bool = False
    traffic_fault_reason: str | None = None
    video: str | None = None
    video_error: str | None = None
    traceback: str | None = None
    input_error: tuple[str, str | None] | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "case": self.case,
            "seed": self.seed,
            "status": self.status,
            "reasons": list(self.reasons),
            "prompts": list(self.prompts),
            "prompt_warnings": list(self.prompt_warnings),
            "ego": self.ego,
            "criteria": list(self.criteria),
            "figures": dict(self.figures),
            "steps": dict(self.steps),
            "seconds": round(self.seconds, 3),
            "reads_log": self.reads_log,
            "traffic": self.traffic,
            "traffic_fault": self.traffic_fault,
            "traffic_fault_reason": self.traffic_fault_reason,
            "video": self.video,
            "video_error": self.video_error,
            "traceback": self.traceback,
        }


class _Failed(Exception):
    """The planner failed the episode (`reason`: one line; `trace`: the planner's traceback, when it raised)."""

    def __init__(self, reason: str, trace: str | None = None):
        super().__init__(reason)
        self.reason, self.trace = reason, trace


class _Episode:
    """The state of one running episode, so that its parts (planner calls, the env, the video) stay small."""

    def __init__(self, task: EpisodeTask):
        self.task = task
        self.record = StepRecord()
        self.planner: Any = None
        self.env: Any = None
        self.ego: int | None = None
        self.planner_seconds = 0.0
        self.planner_max = 0.0
        self.reads_log = False
        self.prompts: list[str] = []
        self.prompt_warnings: list[str] = []
        self.staged: set[int] = set()  # the prompted agents and the adversary

    def call_planner(self, fn: Callable[[], Any], when: str) -> Any:
        """`fn()` (a planner call) under the step limit; whatever goes wrong fails the episode, naming `when`."""
        from langtraj.planners.base import PlannerError, PlannerTimeout

        limit = self.task.step_timeout
        start = time.perf_counter()
        try:
            with deadline(limit if self.task.planner_cmd is None else None):
                return fn()
        except (StepTimeout, PlannerTimeout):
            raise _Failed(f"planner timed out after {limit:g} s {when}") from None
        except PlannerError as error:
            raise _Failed(f"planner failed {when}: {str(error).splitlines()[0] if str(error) else error}") from None
        except Exception as error:
            raise _Failed(f"planner raised {one_line(error)} {when}", traceback.format_exc()) from None
        finally:
            spent = time.perf_counter() - start
            self.planner_seconds += spent
            self.planner_max = max(self.planner_max, spent)

    def make_planner(self) -> Any:
        from langtraj.planners import SubprocessPlanner, load_planner

        task = self.task
        if task.planner_cmd is not None:
            log = task.out / LOG_FOLDER / f"{task.label}.log"
            log.parent.mkdir(parents=True, exist_ok=True)
            start = max(task.step_timeout, START_TIMEOUT_S)
            return self.call_planner(
                lambda: SubprocessPlanner(task.planner_cmd, task.step_timeout, start_timeout_s=start, stderr_path=log),
                "when started",
            )
        cls = load_planner(task.planner)  # checked before the run: errors here are the machine's
        return self.call_planner(cls, "when created")

    def run(self) -> None:
        """Plan and step until the episode ends; raises `_Failed` for the planner's failures, anything else for
        the environment's."""
        from langtraj.planners import planner_action_kind, planner_reads_log, reset_planner

        task, case = self.task, self.task.case
        self.planner = self.make_planner()
        self.reads_log = planner_reads_log(self.planner)
        try:
            kind = planner_action_kind(self.planner)
        except Exception as error:
            raise _Failed(f"planner has a bad action_kind ({one_line(error)})") from None
        self.env = import_object(task.env, "env")(
            case=case, action=kind, terminate_on_collision=case.criteria.terminate_on_collision
        )
        observation, info = self.env.reset(seed=task.seed)
        self.ego = int(info["ego_id"])
        self.prompts = [str(p) for p in info.get("prompts", [])]
        self.prompt_warnings = [str(w) for w in info.get("prompt_warnings", [])]
        adversary = info.get("adversary")
        self.staged = {int(i) for i in info.get("prompted_ids", [])} | (
            {int(adversary)} if adversary is not None else set()
        )
        self.call_planner(lambda: reset_planner(self.planner, observation, info), "in reset")
        for step in range(1, case.steps + 1):
            action = self.call_planner(lambda obs=observation: self.planner.act(obs), f"at step {step}")
            action = check_action(action, kind, step)
            observation, _, terminated, truncated, info = self.env.step(action)
            self.record.add(info)
            if terminated or truncated:
                break

    def judge_prompts(self) -> list[PromptVerdict]:
        """Each prompt judged on the episode as played (none before the first step)."""
        if self.env is None or not self.record.steps or not self.prompts:
            return []
        report = getattr(self.env, "simulation_report", None)  # an env of another make may keep none
        return judge_prompts(self.env.played(), self.prompts, starts_of(report() if callable(report) else {}))

    def judge_traffic(self, result: EpisodeResult) -> None:
        """Record the other agents' collisions and off-road in `result`, and flag an ego failure that follows one
        (`suites.traffic`); nothing before the first step."""
        if self.env is None or self.ego is None or not self.record.steps:
            return
        traffic = traffic_faults(self.env.played(), self.ego, self.record.collided_with)
        result.traffic = traffic.to_json()
        reason = follows_traffic_fault(traffic, ego_failures(result.figures, result.criteria), self.staged)
        result.traffic_fault, result.traffic_fault_reason = reason is not None, reason

    def close(self) -> None:
        """Close the planner (its failures to close are ignored) and the env."""
        if self.planner is not None and callable(getattr(self.planner, "close", None)):
            try:
                with deadline(self.task.step_timeout if self.task.planner_cmd is None else None):
                    self.planner.close()
            except (Exception, StepTimeout):
                pass
        if self.env is not None:
            self.env.close()

    def video(self, caption: str) -> str:
        """Write the episode so far to `videos/<case>-seed<k>.mp4`; its path relative to the output folder."""
        from langtraj.viz import RenderConfig, save_video

        played = self.env.played()
        relative = f"{VIDEO_FOLDER}/{self.task.label}.mp4"
        render = RenderConfig(
            highlight_ids=tuple(int(i) for i in self.env.highlight_ids),
            follow_track_id=self.ego,
            show_ids=True,
            caption=caption[:CAPTION_CHARS],
        )
        start = min(int(played.current_index), played.num_steps - 1)  # from the last logged step on
        save_video(played, self.task.out / relative, render, start=start, progress=False)
        return relative


def check_action(action: Any, kind: str, step: int) -> np.ndarray:
    """`action` as a float32 array of the `kind` action space (`env.spaces.checked_action`); one that is not fails
    the episode."""
    try:
        return checked_action(action, kind).astype(np.float32)
    except ActionError as error:
        raise _Failed(f"planner returned {error} at step {step}") from None


def run_episode(task: EpisodeTask, watch: Callable[[Any], None] | None = None) -> EpisodeResult:
    """Run one (case, seed) episode and judge it; never raises for what the planner or the env does. `watch`, when
    given, is called with the env once the episode has run (before it closes): the studio keeps its rollout."""
    start = time.perf_counter()
    episode = _Episode(task)
    result = EpisodeResult(case=task.case.name, seed=task.seed, status="pass")
    try:
        episode.run()
    except _Failed as failure:
        result.status, result.reasons, result.traceback = "fail", [failure.reason], failure.trace
    except Exception as error:
        steps = episode.record.steps
        where = f"at step {steps + 1}" if episode.ego is not None else "before the episode started"
        result.status, result.reasons = "error", [f"LangTraj raised {one_line(error)} {where}"]
        result.traceback = traceback.format_exc()
        if isinstance(error, InputError) and episode.ego is None:  # the case, refused at reset: bad input
            result.reasons = [f"bad input {where}: {error}"]
            result.input_error = (error.detail, error.where) if error.path is None else (str(error), None)
    figures = episode_figures(episode.record)
    if result.status == "pass":
        verdicts = judge(task.case.criteria, figures)
        result.criteria = [v.to_json() for v in verdicts]
        failed = [v.reason for v in verdicts if not v.passed]
        if failed:
            result.status, result.reasons = "fail", [r or "" for r in failed]
    if result.status in ("pass", "fail"):
        try:
            prompts = episode.judge_prompts()
        except Exception as error:
            result.status = "error"
            result.reasons.append(f"LangTraj raised {one_line(error)} when judging the prompts")
            result.traceback = traceback.format_exc()
        else:
            result.prompts = [p.to_json() for p in prompts]
            missed = not_happened(prompts, episode.prompt_warnings)
            if result.status == "pass" and missed:
                result.status, result.reasons = "not_happened", missed
    result.prompt_warnings = episode.prompt_warnings
    result.ego, result.reads_log = episode.ego, episode.reads_log
    result.figures = figures | {
        "planner_seconds": round(episode.planner_seconds, 4),
        "planner_max_step_seconds": round(episode.planner_max, 4),
    }
    result.steps = episode.record.to_json()
    try:
        episode.judge_traffic(result)
    except Exception as error:
        if result.status != "error":
            result.status = "error"
            result.reasons.append(f"LangTraj raised {one_line(error)} when judging the other agents' traffic")
            result.traceback = traceback.format_exc()
    if (
        task.video
        and (result.status != "pass" or figures["collision"])
        and episode.env is not None
        and episode.record.steps
    ):
        first = figures["collisions"][0] if figures["collisions"] else None
        what = result.reasons[0] if result.reasons else f"collision with {first['with']} at step {first['step']}"
        caption = f"{task.case.name} seed {task.seed}: {what}"
        try:
            result.video = episode.video(caption)
        except Exception as error:
            result.video_error = one_line(error)
    if watch is not None and episode.env is not None and episode.record.steps:
        watch(episode.env)
    try:
        episode.close()
    except Exception as error:
        if result.status != "error":
            result.status = "error"
            result.reasons.append(f"LangTraj raised {one_line(error)} when closing the env")
            result.traceback = traceback.format_exc()
    result.seconds = time.perf_counter() - start
    return result
