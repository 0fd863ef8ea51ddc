"""Hard constraints at inference: project each sample's clean trajectories onto the road and out of overlap.

After SceneDiffuser's generalized hard constraints (arXiv 2412.12129): at the last denoising steps the clean
prediction x0 is rolled out to states, the states are projected onto the constraint set (vehicles inside the
drivable area, agents apart), and the projected states are turned back into actions through the dynamics'
robust inverse (`model.dynamics.Unicycle.inverse`); the sampler continues from the projected x0. Guidance
(`guidance.step`) only pushes down a cost's gradient; a projection moves each offending point to where the
constraint holds, whatever the cost's weight. See docs/simulation.md, 'Hard constraints'.

The state-space projection alternates two steps, `iterations` times, ending with the road:

- apart (`separation`, `held_back`): every two agents whose disks (`guidance.disks`) overlap at a step are
  separated. An agent that ran into the other (the other's centre within 60 degrees of its heading at their
  first contact) is held back along its own path by the headway it lacks, braked into from the start
  (`braking_delay`); head-on, each takes half; side by side, both are pushed apart across the line between their
  nearest disks, half the overlap each. An agent whose partner cannot move (an external ego, a held
  parked car) takes all of it. Pairs that overlap at the current step (the log's own touching pairs, pedestrians
  walking together, a simulation's past) and `exempt` pairs (an adversary and its target) are left alone.
- road (`project_on_road`): every point of a `road` agent (vehicles on the road at the start) whose box reaches
  past a line `road_margin` inside the road edge is moved along the signed distance's gradient until it does
  not; from a path's first point farther than `max_offroad` m off the road on, the rest keeps the correction of
  the point before (far off the road, and past where a map ends, the nearest edge says nothing about where the
  road goes, and a path half pulled in and half left would zigzag).

Headings are then re-derived from the projected path where it moves, and each (sample, agent) path that moved is
refitted, `rounds` times from the refit's own rollout; the others keep their actions exactly.

A unicycle cannot follow a path pushed sideways: the refit lags behind it and gives back much of what the
projection took off the road (one roundabout window of validation maps: box corners off the road at 0.50 of the
kept-on-road points before the projection, 0.20 after it, 0.45 after the refit). So the last step,
`polish_on_road`, works on the actions themselves: `polish` Adam steps on every kept-on-road path whose box still
reaches past its line, against the squared reach of its corners past it, each path keeping the best actions it
reached (docs/simulation.md, 'Hard constraints').
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.base import FinalSteps
from langtraj.guidance.costs import signed_road_distance
from langtraj.guidance.disks import DiskLayout, close_steps
from langtraj.guidance.scene import GuidanceScene
from langtraj.model.diffusion import Guidance

_MOVED = 1e-3  # metres: a point moved less than this counts as unmoved (its actions are kept)
_HEADING_STEP = 0.05  # metres per step below which a path is too still to give its own heading
_AHEAD = 0.5  # cos 60 degrees: another agent whose centre lies within 60 degrees of one's heading lies ahead
# Adam's epsilon in the polish, in the loss's gradient units (m^2 per network unit): a box a few millimetres past its
# line gives a gradient below it and a step in proportion, not a full step of the rate (which, from gradients of
# float noise, parted batched and one-by-one rollouts by 0.6 m).
_POLISH_EPS = 1e-2
# Metres per second below which an agent is standing and its plan is not polished: Adam's steps on its acceleration
# set cars parked over the kerb driving (nuScenes windows of standing cars lost 0.1 of their meta to that).
_POLISH_MIN_SPEED = 0.5


@dataclass(frozen=True)
class HardConstraints:
    """The projection's settings (docs/simulation.md, 'Hard constraints'): at the last `steps` denoising steps,
    `iterations` rounds of (apart, road); vehicles keep their box `road_margin` (m) inside the road edge; agents'
    disks keep `gap` (m) apart; points more than `max_offroad` m off the road are left where they are. With
    `on_choice`, the plan a simulation executes is projected once more after selection: a selector that assembles
    each agent from a different candidate (`per_agent`) undoes the guarantee each candidate had. `polish` Adam
    steps of rate `polish_rate` (network units) then move the actions of paths whose box still reaches past the line
    within the plan's first `polish_steps` steps (None: all of it), anchored to the refit's by `polish_anchor`
    (`polish_on_road`; `polish=0` turns it off). With `steer_prompted`,
    a prompted agent's plans are polished too, on their yaw rate only (braking a clipped corner away undid turns), a
    pull-over's not at all (steering it away from the kerb undid it); False: prompted agents are not polished."""

    steps: int = 1
    iterations: int = 3
    rounds: int = 1
    road_margin: float = 0.2
    gap: float = 0.0
    max_offroad: float = 5.0
    num_disks: int = 5
    on_choice: bool = True
    polish: int = 10
    polish_rate: float = 0.3
    polish_anchor: float = 0.001
    steer_prompted: bool = True
    polish_steps: int | None = 30

    def __post_init__(self) -> None:
        if self.polish < 0:
            raise InputError(f"polish must be >= 0, got {self.polish}", where="hard constraints")
        if self.polish_steps is not None and self.polish_steps < 1:
            raise InputError(f"polish_steps must be >= 1, got {self.polish_steps}", where="hard constraints")
        if min(self.steps, self.iterations, self.rounds, self.num_disks) < 1:
            raise InputError(
                "steps, iterations, rounds and num_disks must be >= 1, got "
                f"{self.steps}, {self.iterations}, {self.rounds}, {self.num_disks}",
                where="hard constraints",
            )
        for name in ("road_margin", "gap", "max_offroad", "polish_rate", "polish_anchor"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"{name} must be finite and >= 0, got {value}", where="hard constraints")


@dataclass(frozen=True)
class ProjectionAgents:
    """Which agents the projection moves and how, over a scene's A agents: `road` (bool [A]) are kept on the
    road, `movable` (bool [A]) may be moved at all (False: an external agent, whose states are given), and
    `exempt` (bool [S, A, A] or [A, A], symmetric) pairs are never pushed apart, per sample row or in all.
    `margin` (float [A], m) is how far inside the road edge each agent's box is kept (None: the config's
    `road_margin` for all; a prompted pull-over is asked to the kerb, nearer than that). `polish` (bool [A]) are the
    agents whose plans `polish_on_road` may move (None: every movable road agent; a prompted pull-over is left out),
    and of them `steer_only` (bool [A]; None: none) those it may only steer, not speed up or slow down (a prompted
    agent, `HardConstraints.steer_prompted`)."""

    road: Tensor
    movable: Tensor
    exempt: Tensor
    margin: Tensor | None = None
    polish: Tensor | None = None
    steer_only: Tensor | None = None


def project_on_road(
    states: Tensor, scene: GuidanceScene, road: Tensor, config: HardConstraints, margin: Tensor | None = None
) -> Tensor:
    """xy [S, A, T, 2] of `states` [S, A, T, 4] with every point of the `road` agents (bool [A]) moved along the
    signed distance's gradient n until its box (at its heading) lies `margin` [A] (m; None: `config.road_margin`
    each) inside the road edge: its centre at least |L/2 h.n| + |W/2 h'.n| in, the box's reach towards the edge
    (one Newton step: exact where the nearest edge is straight)."""
    xy = states[..., :2]
    if scene.road_edges.shape[0] == 0 or not road.any():
        return xy
    rows = road.nonzero()[:, 0]
    points = xy[:, rows].detach().requires_grad_(True)
    with torch.enable_grad():
        signed = signed_road_distance(points, scene)
        (grad,) = torch.autograd.grad(signed.sum(), points)
    signed = signed.detach()
    normal = grad / torch.linalg.vector_norm(grad, dim=-1, keepdim=True).clamp(min=1e-6)
    heading = states[:, rows, :, 2]
    size = scene.agent_size.to(xy)[rows]  # [A_r, 2]: length, width
    along = (torch.cos(heading) * normal[..., 0] + torch.sin(heading) * normal[..., 1]).abs()
    across = (-torch.sin(heading) * normal[..., 0] + torch.cos(heading) * normal[..., 1]).abs()
    reach = size[None, :, None, 0] / 2 * along + size[None, :, None, 1] / 2 * across
    inside = config.road_margin if margin is None else margin.to(xy)[rows][None, :, None]
    excess = (signed + reach + inside).clamp(min=0.0)
    correction = -excess[..., None] * normal  # [S, A_r, T, 2]
    # From a path's first point farther off the road than `max_offroad` on, the nearest edge no longer says where
    # the road is: the rest of the path keeps the correction of the point before (a translation it can follow).
    after = torch.cummax((signed > config.max_offroad).to(torch.uint8), dim=-1).values.bool()
    if bool(after.any()):
        steps = torch.arange(signed.shape[-1], device=xy.device).expand_as(signed)
        last = torch.cummax(torch.where(after, -1, steps), dim=-1).values  # the last step before, or -1
        kept = torch.gather(correction, -2, last.clamp(min=0)[..., None].expand_as(correction))
        kept = torch.where((last >= 0)[..., None], kept, torch.zeros_like(kept))
        correction = torch.where(after[..., None], kept, correction)
    moved = xy.clone()
    moved[:, rows] = points.detach() + correction
    return moved


def current_overlaps(current: Tensor, scene: GuidanceScene, config: HardConstraints) -> Tensor:
    """bool [S, A, A]: per row, the pairs whose disks overlap at the current states `current` [S, A, 4]: a
    simulation cannot undo its past, so such pairs are left to separate as they will."""
    layout = DiskLayout.of(scene, config.num_disks, current)
    rows, num_agents = current.shape[:2]
    first, second = torch.triu(torch.ones(num_agents, num_agents, dtype=torch.bool), diagonal=1).nonzero(as_tuple=True)
    first, second = first.to(current.device), second.to(current.device)
    out = torch.zeros(rows, num_agents, num_agents, dtype=torch.bool, device=current.device)
    for row in range(rows):
        state = current[row]
        near = layout.may_overlap(state[first], state[second], first, second, config.gap)
        i, j = first[near], second[near]
        hit = layout.penalty(state[i], state[j], i, j, config.gap) > 0
        out[row, i[hit], j[hit]] = True
    return out | out.transpose(1, 2)


@dataclass(frozen=True)
class Separation:
    """What keeping a sample's agents apart asks of each path (`separation`): lateral moves `shift` [S, A, T, 2]
    (m) for agents side by side, and `delay` [S, A, T] (m of progress along its own path) for an agent that
    runs into one ahead of it."""

    shift: Tensor
    delay: Tensor


def separation(
    states: Tensor, xy: Tensor, scene: GuidanceScene, agents: ProjectionAgents, config: HardConstraints
) -> Separation | None:
    """How far each agent of xy [S, A, T, 2] (headings from `states` [S, A, T, 4]) must move for every pair not
    exempt to stop overlapping (None: no pair overlaps). For each overlapping (sample, pair, step), with o the
    overlap of their nearest disks (m): an agent with the other within `_AHEAD` of its heading and not the
    other way round ran into it and is held back by o along its path (as a driver brakes; head-on, each by
    o / 2); two agents side by side are pushed apart along the line between those disks, o / 2 each. An agent
    whose partner cannot move takes all of it."""
    device = xy.device
    valid = scene.agent_valid.to(device)
    movable = agents.movable.to(device)
    exempt = agents.exempt.to(device).expand(xy.shape[0], -1, -1)
    pairs = torch.triu(valid[:, None] & valid[None, :], diagonal=1) & ~exempt.all(0)
    pairs &= movable[:, None] | movable[None, :]
    first, second = pairs.nonzero(as_tuple=True)
    if first.numel() == 0:
        return None
    layout = DiskLayout.of(scene, config.num_disks, xy)
    current = torch.cat([xy.detach(), states[..., 2:].detach()], dim=-1).requires_grad_(True)
    with torch.enable_grad():
        close = close_steps(current, layout, first, second, config.gap)
        if close is None:
            return None
        keep = ~exempt[close.sample, close.i, close.j]
        i, j = close.i[keep], close.j[keep]
        state_i, state_j = close.state_i[keep], close.state_j[keep]
        penalty = layout.penalty(state_i, state_j, i, j, config.gap)
        hit = penalty > 0
        if not bool(hit.any()):
            return None
        overlap = penalty * (layout.radius[i] + layout.radius[j] + config.gap)
        # 0.5 overlap^2: its gradient is the overlap along the line that separates the nearest disks.
        grad_i, grad_j = torch.autograd.grad((0.5 * overlap**2).sum(), (close.state_i, close.state_j))
    grad_i, grad_j = grad_i[keep, :2], grad_j[keep, :2]
    gap = (state_j[:, :2] - state_i[:, :2]).detach()

    def ahead(heading: Tensor, towards: Tensor) -> Tensor:
        facing = torch.stack([torch.cos(heading), torch.sin(heading)], -1)
        return (facing * towards).sum(-1) >= _AHEAD * torch.linalg.vector_norm(towards, dim=-1).clamp(min=1e-6)

    # Who ran into whom is read at the pair's first contact in the sample (later the two may have passed
    # through each other), and holds for all its steps.
    sample, step = close.sample[keep], close.step[keep]
    contact = sample * len(close.first) + close.pair[keep]
    first_step = torch.full((xy.shape[0] * len(close.first),), xy.shape[2], device=device, dtype=step.dtype)
    first_step = first_step.scatter_reduce(0, contact, torch.where(hit, step, xy.shape[2]), reduce="amin")
    at_contact = hit & (step == first_step[contact])
    roles = torch.zeros(len(first_step), 2, dtype=torch.bool, device=device)
    roles[contact[at_contact], 0] = ahead(state_i[at_contact, 2].detach(), gap[at_contact])  # i ran into j
    roles[contact[at_contact], 1] = ahead(state_j[at_contact, 2].detach(), -gap[at_contact])
    i_behind, j_behind = roles[contact, 0], roles[contact, 1]
    both = i_behind & j_behind
    share_i = torch.where(movable[j], torch.where(both, 0.5, 1.0), 1.0) * movable[i] * hit  # overlapping steps only
    share_j = torch.where(movable[i], torch.where(both, 0.5, 1.0), 1.0) * movable[j] * hit
    side = ~(i_behind | j_behind)
    side_i = torch.where(movable[j], 0.5, 1.0) * movable[i] * side
    side_j = torch.where(movable[i], 0.5, 1.0) * movable[j] * side
    shift = torch.zeros_like(xy)
    shift.index_put_((sample, i, step), -side_i[:, None] * grad_i, accumulate=True)
    shift.index_put_((sample, j, step), -side_j[:, None] * grad_j, accumulate=True)
    delay = torch.zeros_like(xy[..., 0])
    delay.index_put_(
        (sample, i, step), share_i * i_behind * headway(layout, state_i, state_j, i, j, config.gap), accumulate=True
    )
    delay.index_put_(
        (sample, j, step), share_j * j_behind * headway(layout, state_j, state_i, j, i, config.gap), accumulate=True
    )
    return Separation(shift=shift, delay=delay)


def headway(layout: DiskLayout, state_i: Tensor, state_j: Tensor, i: Tensor, j: Tensor, gap: float) -> Tensor:
    """How far back along its heading agent i (states [K, 4]) must be for its front to clear agent j's extent
    along that heading by `gap` (m, 0 when it does): right for one that ran into another however deep (even
    through it), where the overlap of the nearest disks would say little."""
    facing = torch.stack([torch.cos(state_i[:, 2]), torch.sin(state_i[:, 2])], -1)
    along = ((state_j[:, :2] - state_i[:, :2]) * facing).sum(-1)
    extent_j = layout.reach[j] * torch.cos(state_j[:, 2] - state_i[:, 2]).abs() + layout.radius[j]
    return (layout.reach[i] + layout.radius[i] + extent_j + gap - along).clamp(min=0.0)


def braking_delay(delay: Tensor) -> Tensor:
    """The delay profile [..., T] (m) that meets every delay asked at step c (`delay` [..., T]) from c on, built up
    as a constant extra deceleration from the start: max over c of delay[c] min(1, (t + 1) / (c + 1))^2. A step
    profile (all of it at c) would ask an agent to stop dead; this one brakes it smoothly, as the unicycle can
    follow."""
    asked = delay > 0
    if not bool(asked.any()):
        return delay
    rows = asked.any(-1)
    steps = delay.shape[-1]
    t = torch.arange(1, steps + 1, dtype=delay.dtype, device=delay.device)
    ramp = (t[:, None] / t[None, :]).clamp(max=1.0) ** 2  # [t, c]
    out = delay.clone()
    out[rows] = (delay[rows][:, None, :] * ramp[None]).amax(-1)
    return out


def held_back(start: Tensor, xy: Tensor, delay: Tensor) -> Tensor:
    """Paths xy [S, A, T, 2] from `start` [S, A, 2] with each point moved back along its own path by the delays
    `delay` [S, A, T] (m) asked, braked into (`braking_delay`: a driver who brakes stays behind), and never ahead
    of a later point (progress never decreases); a point is never moved back past the start."""
    path = torch.cat([start[..., None, :], xy], dim=-2)  # [S, A, T + 1, 2]
    length = torch.linalg.vector_norm(path[..., 1:, :] - path[..., :-1, :], dim=-1)
    station = torch.cat([torch.zeros_like(length[..., :1]), torch.cumsum(length, -1)], dim=-1)  # [S, A, T + 1]
    wanted = (station[..., 1:] - braking_delay(delay)).clamp(min=0.0)
    wanted = torch.flip(torch.cummin(torch.flip(wanted, [-1]), dim=-1).values, [-1])
    index = torch.searchsorted(station.contiguous(), wanted.contiguous(), right=True).clamp(1, xy.shape[-2])
    low = torch.gather(station, -1, index - 1)
    high = torch.gather(station, -1, index)
    fraction = ((wanted - low) / (high - low).clamp(min=1e-9)).clamp(0.0, 1.0)[..., None]
    gather = lambda at: torch.gather(path, -2, at[..., None].expand(*at.shape, 2))  # noqa: E731
    return gather(index - 1) + fraction * (gather(index) - gather(index - 1))


def derived_heading(xy: Tensor, heading: Tensor) -> Tensor:
    """Headings [..., T] along the path xy [..., T, 2] (central differences) where it moves at least
    `_HEADING_STEP` m per step, else `heading`'s."""
    padded = torch.cat([xy[..., :1, :], xy, xy[..., -1:, :]], dim=-2)
    delta = (padded[..., 2:, :] - padded[..., :-2, :]) / 2
    moving = torch.linalg.vector_norm(delta, dim=-1) >= _HEADING_STEP
    course = torch.atan2(delta[..., 1], delta[..., 0])
    # Keep the angle nearest the given heading (a path that moves backwards still faces forwards).
    backwards = torch.cos(course - heading) < 0
    course = torch.where(backwards, course + math.pi, course)
    return torch.where(moving, course, heading)


def project_states(
    initial: Tensor, states: Tensor, scene: GuidanceScene, agents: ProjectionAgents, config: HardConstraints
) -> tuple[Tensor, Tensor]:
    """Projected states [S, A, T, 3] (x, y, heading) of `states` [S, A, T, 4] planned from `initial` [S, A, 4],
    and bool [S, A]: the paths that moved."""
    xy = states[..., :2].detach()
    start = initial[..., :2].to(xy)
    for _ in range(config.iterations):
        apart = separation(states, xy, scene, agents, config)
        if apart is not None:
            xy = held_back(start, xy + apart.shift, apart.delay)
        xy = project_on_road(torch.cat([xy, states[..., 2:]], dim=-1), scene, agents.road, config, agents.margin)
    moved = (torch.linalg.vector_norm(xy - states[..., :2], dim=-1) > _MOVED).any(-1)
    heading = torch.where(moved[..., None], derived_heading(xy, states[..., 2]), states[..., 2])
    return torch.cat([xy, heading[..., None]], dim=-1), moved


def projection_hook(
    config: HardConstraints,
    scene: GuidanceScene,
    agents: ProjectionAgents,
    initial: Tensor,
    rollout: Callable[[Tensor], Tensor],
    invert: Callable[[Tensor, Tensor], Tensor],
    *,
    num_steps: int,
    sampler_steps: int,
    then: Guidance | None = None,
    drive: Callable[[Tensor, Tensor], Tensor] | None = None,
) -> Guidance:
    """The sampler hook (x0 [S, A, N, 2], k, x_k) -> x0 that runs `then` (guidance; None: none) and, at the last
    `config.steps` of the `sampler_steps` denoising steps, projects the plans from `initial` [S, A, 4]:
    `rollout` maps network-unit actions to states [S, A, T, 4], `invert` maps states [K, T, 3] of the (row, agent)
    paths a mask (bool [S, A]) picks back to their network-unit actions [K, N, 2]; only the paths the projection
    moved are refitted (the refit is the projection's costliest part), the others keep their actions exactly;
    `drive`, the polish's integrator of picked paths (`polish_on_road`)."""
    when = FinalSteps(min(config.steps, sampler_steps), sampler_steps)
    here = scene

    def hook(x0: Tensor, k: Tensor | int, x_k: Tensor) -> Tensor:
        if then is not None:
            x0 = then(x0, k, x_k)
        rows = x0.shape[0]
        steps = torch.as_tensor(k, dtype=torch.long, device=x0.device).reshape(-1).expand(rows)
        if not bool(when(steps, num_steps).any()):
            return x0
        return project_plans(config, here, agents, initial, rollout, invert, x0, drive)

    return hook


def project_plans(
    config: HardConstraints,
    scene: GuidanceScene,
    agents: ProjectionAgents,
    initial: Tensor,
    rollout: Callable[[Tensor], Tensor],
    invert: Callable[[Tensor, Tensor], Tensor],
    x0: Tensor,
    drive: Callable[[Tensor, Tensor], Tensor] | None = None,
) -> Tensor:
    """Network-unit actions x0 [S, A, N, 2] planned from `initial` [S, A, 4], projected (`project_states`),
    refitted `config.rounds` times (`rollout` and `invert` as `projection_hook` takes them) and polished
    (`polish_on_road`, `drive` as it takes it); a path the projection does not move and whose box stays inside its
    line keeps its actions exactly."""
    scene = scene.to(x0.device)
    with torch.no_grad():
        for _ in range(config.rounds):
            states = rollout(x0)
            projected, moved = project_states(initial, states, scene, agents, config)
            if not bool(moved.any()):
                break
            x0 = x0.clone()
            x0[moved] = invert(projected[moved], moved).to(x0)
    return polish_on_road(config, scene, agents, initial, rollout, x0, drive)


def corner_reach(states: Tensor, scene: GuidanceScene, rows: Tensor) -> Tensor:
    """[S, len(rows), T]: how far (m, positive off the road) the most off-road corner of the box of each agent in
    `rows` lies past the road edge along `states` [S, A, T, >= 3], as the off-road metric judges a box."""
    size = scene.agent_size.to(states)[rows][None, :, None]
    return box_reach(states[:, rows, :, :2], states[:, rows, :, 2], size, scene)


def box_reach(xy: Tensor, heading: Tensor, size: Tensor, scene: GuidanceScene) -> Tensor:
    """[...]: how far (m, positive off the road) the most off-road corner of a box of `size` (length, width; [..., 2],
    broadcasting) centred at xy [..., 2] with `heading` [...] lies past the road edge of `scene`."""
    half_length, half_width = size[..., 0] / 2, size[..., 1] / 2
    cos, sin = torch.cos(heading), torch.sin(heading)
    reach = None
    for along, across in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        x = xy[..., 0] + along * half_length * cos - across * half_width * sin
        y = xy[..., 1] + along * half_length * sin + across * half_width * cos
        corner = signed_road_distance(torch.stack([x, y], dim=-1), scene)
        reach = corner if reach is None else torch.maximum(reach, corner)
    assert reach is not None
    return reach


def polish_on_road(
    config: HardConstraints,
    scene: GuidanceScene,
    agents: ProjectionAgents,
    initial: Tensor,
    rollout: Callable[[Tensor], Tensor],
    x0: Tensor,
    drive: Callable[[Tensor, Tensor], Tensor] | None = None,
) -> Tensor:
    """Network-unit actions x0 [S, A, N, 2] planned from `initial` [S, A, 4] after `config.polish` Adam steps (rate
    `polish_rate`) on the (row, agent) paths of movable road agents (`agents.polish` of them, when given) moving at
    `_POLISH_MIN_SPEED` or more whose box reaches past its line within the plan's first `config.polish_steps` steps
    (the others keep x0 exactly; later steps are the replans' to come: judged over all 8 s, Adam braked whole
    highways for a corner seconds ahead, docs/experiments.md 'Traffic that flows'); the paths of
    `agents.steer_only` are stepped on their yaw rate only. A box's line lies `margin` inside the road edge, or where
    the box reaches at the start if that is farther out: a car over the kerb may stay there, not be driven off it.
    Each path's loss is the squared reach past its line, summed over those steps, plus `polish_anchor` times the squared
    change of its actions; each path ends at the lowest-loss actions it reached, so none ends worse than it began.
    Adam steps every action of a path by about the rate, whatever its gradient's size: it slows a car as readily as it
    steers it, and braking is what keeps roundabout plans on the ring (validation maps: steering alone left 0.41 of
    roundabout vehicles off the road, normalized gradient steps 0.32, Adam 0.15; 0.41 without the polish);
    docs/experiments.md, 'Polished onto the road'. `drive` maps actions [K, N, 2] of the K paths a mask (bool [S, A])
    picks to their states [K, T, 4] (they are movable: no pinned or held agent among them), so that only those are
    integrated; None: through `rollout`, every path each step."""
    rows = agents.road & agents.movable
    rows = (rows if agents.polish is None else rows & agents.polish.to(rows.device)).nonzero()[:, 0]
    if config.polish == 0 or len(rows) == 0 or scene.road_edges.shape[0] == 0:
        return x0
    margin = torch.full(x0.shape[1:2], config.road_margin) if agents.margin is None else agents.margin
    with torch.no_grad():
        start = corner_reach(initial[:, :, None], scene, rows)[..., 0]  # [S, rows]: the box's reach at the start
        line = torch.zeros(x0.shape[:2], dtype=x0.dtype, device=x0.device)  # [S, A]: how far inside the edge
        line[:, rows] = torch.minimum(margin.to(x0)[rows][None], -start)
        judged = config.polish_steps  # the plan's first steps the polish judges (None: all)
        reach = corner_reach(rollout(x0)[:, :, :judged], scene, rows) + line[:, rows, None]
    polished = torch.zeros(x0.shape[:2], dtype=torch.bool, device=x0.device)
    polished[:, rows] = (reach > 0).any(-1) & (initial[:, rows, 3] >= _POLISH_MIN_SPEED)
    if not bool(polished.any()):
        return x0
    if drive is None:

        def drive(paths: Tensor, mask: Tensor) -> Tensor:
            return rollout(x0.detach().masked_scatter(mask[..., None, None].expand_as(x0), paths))[mask]

    slot = polished.nonzero()[:, 1]
    size, inside = scene.agent_size.to(x0)[slot][:, None], line[polished][:, None]
    anchor = x0.detach()[polished]  # [K, N, 2]
    steer_only = None if agents.steer_only is None else agents.steer_only.to(slot.device)[slot]  # [K]

    def loss_of(actions: Tensor) -> Tensor:
        """Each path's loss [K]."""
        states = drive(actions, polished)[:, :judged]
        past = (box_reach(states[..., :2], states[..., 2], size, scene) + inside).clamp(min=0)
        return past.pow(2).sum(-1) + config.polish_anchor * (actions - anchor).pow(2).sum((-2, -1))

    best, best_loss = anchor, torch.full(anchor.shape[:1], math.inf, dtype=x0.dtype, device=x0.device)
    actions = anchor.clone().requires_grad_(True)  # the first step's loss is the anchor's own
    optimizer = torch.optim.Adam([actions], lr=config.polish_rate, eps=_POLISH_EPS)
    with torch.enable_grad():
        for _ in range(config.polish):
            loss = loss_of(actions)
            lower = loss.detach() < best_loss
            best = torch.where(lower[:, None, None], actions.detach(), best)
            best_loss = torch.where(lower, loss.detach(), best_loss)
            (grad,) = torch.autograd.grad(loss.sum(), actions)
            if steer_only is not None:  # no acceleration step: Adam leaves an action with no gradient where it is
                grad[steer_only, :, 0] = 0.0
            actions.grad = grad
            optimizer.step()
    with torch.no_grad():
        last = actions.detach().clamp(-4.0, 4.0)
        best = torch.where((loss_of(last) < best_loss)[:, None, None], last, best)
    out = x0.clone()
    out[polished] = best.to(x0)
    return out
