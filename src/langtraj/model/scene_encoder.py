"""Query-centric scene encoder: each agent history and map polyline in its own frame, then
relative-pose attention between them (paper 'LangTraj'; docs/design.md, 'The model'). See docs/model.md."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from langtraj.model.batch import SceneBatch
from langtraj.model.config import LocalAttention, ModelConfig
from langtraj.model.features import LANE_TYPES
from langtraj.model.layers import AttentionBlock, mlp, recomputing, run_block

_AGENT_TYPES = 5  # padding + AgentType 1..4
_MAP_TYPES = 40  # padding + MapFeatureType values (< 40)


@dataclass
class MapContext:
    """Encoded map: polyline tokens with their poses and mask."""

    tokens: Tensor  # [B, M, D]
    pose: Tensor  # [B, M, 3]
    mask: Tensor  # bool [B, M]


@dataclass
class Neighbours:
    """The keys of each agent under local attention (`LocalAttention`): its nearest agents, and its scene
    tokens (those agents, then its nearest map pieces, as indices into agents followed by map pieces),
    each with whether it is a real token."""

    agents: Tensor  # long [B, A, Ka]
    agents_valid: Tensor  # bool [B, A, Ka]
    context: Tensor  # long [B, A, Ka + Km]
    context_valid: Tensor  # bool [B, A, Ka + Km]


def nearest_neighbours(batch: SceneBatch, local: LocalAttention) -> Neighbours:
    """Each agent's `local.agents` nearest valid agents (by current position, itself included) and
    `local.map_pieces` nearest valid map pieces (by their nearest valid point)."""
    xy = batch.current_state[..., :2]
    b, a = batch.agent_valid.shape
    far = torch.tensor(torch.inf, device=xy.device)
    to_agents = torch.where(batch.agent_valid[:, None, :], torch.cdist(xy, xy), far)
    near, agents = to_agents.topk(min(local.agents, a), dim=-1, largest=False)
    points = batch.map_points  # [B, M, P, 2]
    m, p = points.shape[1:3]
    to_points = torch.cdist(xy, points.reshape(b, m * p, 2)).view(b, a, m, p)
    to_map = torch.where(batch.map_valid[:, None], to_points, far).amin(-1)  # [B, A, M]
    near_map, pieces = to_map.topk(min(local.map_pieces, m), dim=-1, largest=False)
    return Neighbours(
        agents=agents,
        agents_valid=near.isfinite(),
        context=torch.cat([agents, pieces + a], dim=-1),
        context_valid=torch.cat([near.isfinite(), near_map.isfinite()], dim=-1),
    )


@dataclass
class SceneContext:
    """Encoded scene: agent and map tokens with their poses and masks, and each agent's neighbours when
    attention is local (None: every agent attends to every token)."""

    agent_tokens: Tensor  # [B, A, D]
    agent_pose: Tensor  # [B, A, 3]
    agent_mask: Tensor  # bool [B, A]
    map_tokens: Tensor  # [B, M, D]
    map_pose: Tensor  # [B, M, 3]
    map_mask: Tensor  # bool [B, M]
    neighbours: Neighbours | None = None

    def repeat(self, times: int) -> SceneContext:
        """Every scene repeated `times` times, sample-major (all scenes, then again)."""
        if times == 1:
            return self

        def rows(t: Tensor) -> Tensor:
            return t.repeat(times, *([1] * (t.dim() - 1)))

        tensors = {name: rows(t) for name, t in vars(self).items() if isinstance(t, Tensor)}
        nb = self.neighbours
        return SceneContext(
            **tensors, neighbours=None if nb is None else Neighbours(*(rows(t) for t in vars(nb).values()))
        )

    @property
    def tokens(self) -> Tensor:
        return torch.cat([self.agent_tokens, self.map_tokens], dim=1)

    @property
    def pose(self) -> Tensor:
        return torch.cat([self.agent_pose, self.map_pose], dim=1)

    @property
    def mask(self) -> Tensor:
        return torch.cat([self.agent_mask, self.map_mask], dim=1)


def rotate(xy: Tensor, angle: Tensor) -> Tensor:
    """Rotate [..., 2] vectors by `angle` [...] (broadcast)."""
    c, s = torch.cos(angle), torch.sin(angle)
    return torch.stack([c * xy[..., 0] - s * xy[..., 1], s * xy[..., 0] + c * xy[..., 1]], dim=-1)


def agent_local_history(batch: SceneBatch) -> Tensor:
    """History [B, A, H, 7] re-expressed in each agent's current frame (position, heading and velocity
    relative to it), zero where invalid."""
    hist = batch.agent_history
    pose = batch.current_state[..., :3]
    heading = pose[..., 2][..., None]  # [B, A, 1]
    rel_xy = rotate(hist[..., 0:2] - pose[..., None, 0:2], -heading)
    hist_heading = torch.atan2(hist[..., 3], hist[..., 2])
    dh = hist_heading - heading
    vel = rotate(hist[..., 4:6], -heading)
    valid = batch.history_valid.float()
    local = torch.cat([rel_xy, torch.cos(dh)[..., None], torch.sin(dh)[..., None], vel, valid[..., None]], dim=-1)
    return local * valid[..., None]


LANE_FEATURES = 4
"""Per history step: lateral offset to the nearest lane (m / 2, within +-4 m), the cos and sin of the heading
error to it, and whether a lane is within `LANE_REACH` m (the others zero when not)."""

LANE_REACH = 10.0
LANE_TURN_M = 2.0  # choosing the nearest lane, a heading error of 90 degrees counts as this many metres


def lane_steps(history_steps: int) -> list[int]:
    """The history indices `lane_relative_history` reads: the first, the middle and the current step (the drift,
    at a fraction of the cost of every step; fewer for a history shorter than 3)."""
    return sorted({0, (history_steps - 1) // 2, history_steps - 1})


def lane_relative_history(batch: SceneBatch) -> Tensor:
    """[B, A, len(lane_steps), LANE_FEATURES]: the pose at each of `lane_steps` history steps against the
    nearest lane segment of the scene's map pieces, nearest by distance plus `LANE_TURN_M` x (1 - cos heading
    error), so that at a junction a lane crossing the agent's path loses to the one it follows. Zero where the
    step is invalid or no lane is near."""
    steps = lane_steps(batch.agent_history.shape[2])
    history, history_valid = batch.agent_history[:, :, steps], batch.history_valid[:, :, steps]
    lane = torch.isin(batch.map_type, torch.tensor(LANE_TYPES, device=batch.map_type.device))
    seg_valid = batch.map_valid[..., :-1] & batch.map_valid[..., 1:] & lane[..., None]  # [B, M, P-1]
    start = batch.map_points[..., :-1, :].flatten(1, 2)  # [B, S, 2]
    delta = (batch.map_points[..., 1:, :] - batch.map_points[..., :-1, :]).flatten(1, 2)
    seg_valid = seg_valid.flatten(1, 2)
    b, a, h = history.shape[:3]
    if seg_valid.shape[1] == 0:
        return history.new_zeros(b, a, h, LANE_FEATURES)
    xy = history[..., 0:2].reshape(b, a * h, 2)
    heading = history[..., 2:4].reshape(b, a * h, 2)  # cos, sin
    length2 = (delta * delta).sum(-1).clamp(min=1e-6)  # [B, S]
    rel = xy[:, :, None, :] - start[:, None, :, :]  # [B, N, S, 2]
    along = ((rel * delta[:, None]).sum(-1) / length2[:, None]).clamp(0.0, 1.0)
    offset = rel - along[..., None] * delta[:, None]
    distance = offset.norm(dim=-1)
    direction = delta / length2.sqrt()[..., None]  # [B, S, 2]
    cos_err = (heading[:, :, None, :] * direction[:, None]).sum(-1)
    score = distance + LANE_TURN_M * (1.0 - cos_err)
    score = score.masked_fill(~seg_valid[:, None, :], float("inf"))
    best = score.argmin(-1, keepdim=True)  # [B, N, 1]
    pick = lambda t: t.gather(-1, best)[..., 0]  # noqa: E731
    dirs = direction[:, None].expand(-1, a * h, -1, -1)
    dx, dy = (pick(dirs[..., i]) for i in (0, 1))
    ox, oy = (pick(offset[..., i]) for i in (0, 1))
    lateral = dx * oy - dy * ox  # > 0: left of the lane (the agent's point minus its nearest lane point)
    cos_h, sin_h = heading[..., 0], heading[..., 1]
    near = (pick(distance) <= LANE_REACH) & torch.isfinite(pick(score))
    features = torch.stack(
        [(lateral / 2.0).clamp(-2.0, 2.0), cos_h * dx + sin_h * dy, sin_h * dx - cos_h * dy, near.float()], dim=-1
    )
    features = features * near[..., None]
    return features.reshape(b, a, h, LANE_FEATURES) * history_valid[..., None]


def polyline_pose(points: Tensor, valid: Tensor) -> Tensor:
    """Pose [B, M, 3] of each polyline: the mean of its valid points, heading from its first to its last
    valid point (0 for a single point)."""
    w = valid.float()
    count = w.sum(-1).clamp(min=1.0)
    centre = (points * w[..., None]).sum(-2) / count[..., None]
    idx = torch.arange(points.shape[-2], device=points.device)
    first = torch.where(valid, idx, points.shape[-2]).min(-1).values.clamp(max=points.shape[-2] - 1)
    last = torch.where(valid, idx, -1).max(-1).values.clamp(min=0)
    start = torch.gather(points, -2, first[..., None, None].expand(*first.shape, 1, 2))[..., 0, :]
    end = torch.gather(points, -2, last[..., None, None].expand(*last.shape, 1, 2))[..., 0, :]
    d = end - start
    heading = torch.where(d.norm(dim=-1) > 1e-3, torch.atan2(d[..., 1], d[..., 0]), torch.zeros_like(d[..., 0]))
    return torch.cat([centre, heading[..., None]], dim=-1)


class SceneEncoder(nn.Module):
    """Agent histories and map polylines to tokens, each embedded in its own frame, then mixed by
    relative-pose attention: map polylines attend to nearby polylines, agents to agents and the map."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        d = config.hidden_dim
        self.radius = config.map_attention_radius
        self.checkpointing = config.gradient_checkpointing
        self.agent_embed = mlp(config.history_steps * 7, d, d)
        self.lane_embed = None
        if config.lane_inputs:  # added to the agent token; zero at first, so a fine-tune starts from its source
            self.lane_embed = mlp(len(lane_steps(config.history_steps)) * LANE_FEATURES, d, d)
            nn.init.zeros_(self.lane_embed[-1].weight)
            nn.init.zeros_(self.lane_embed[-1].bias)
        self.agent_type = nn.Embedding(_AGENT_TYPES, d)
        self.agent_size = mlp(2, d, d)
        self.point_embed = mlp(4, d, d)
        self.polyline_out = mlp(d, d, d)
        self.map_type = nn.Embedding(_MAP_TYPES, d)
        self.map_layers = nn.ModuleList(
            AttentionBlock(d, config.num_heads, config.dropout) for _ in range(config.encoder_layers)
        )
        self.agent_layers = nn.ModuleList(
            AttentionBlock(d, config.num_heads, config.dropout) for _ in range(config.encoder_layers)
        )

    def encode_map(self, batch: SceneBatch) -> MapContext:
        """The map tokens alone: they depend on the map only, so a simulation, whose map is fixed, encodes
        them once and passes them to every replan (`forward(batch, map_context)`)."""
        map_pose = polyline_pose(batch.map_points, batch.map_valid)
        local = rotate(batch.map_points - map_pose[..., None, :2], -map_pose[..., 2][..., None])
        seg = torch.diff(local, dim=-2, prepend=local[..., :1, :])
        points = self.point_embed(torch.cat([local, seg], dim=-1))
        points = points.masked_fill(~batch.map_valid[..., None], float("-inf")).max(dim=-2).values
        map_mask = batch.map_valid.any(-1)
        polylines = self.polyline_out(torch.where(map_mask[..., None], points, torch.zeros_like(points)))
        polylines = polylines + self.map_type(batch.map_type.clamp(0, _MAP_TYPES - 1))
        near = torch.cdist(map_pose[..., :2], map_pose[..., :2]) < self.radius
        map_attn = near & map_mask[:, None, :] & map_mask[:, :, None]
        recompute = recomputing(self.checkpointing, self)
        for layer in self.map_layers:
            polylines = run_block(recompute, layer, polylines, map_pose, polylines, map_pose, map_attn)
        return MapContext(polylines, map_pose, map_mask)

    def forward(
        self, batch: SceneBatch, map_context: MapContext | None = None, local: LocalAttention | None = None
    ) -> SceneContext:
        """Agent and map tokens of a batch; `map_context`, when given, is `encode_map` of this batch's map
        (rows broadcast: one row serves every scene of a batch that shares its map). With `local`, agents of
        a scene larger than its budgets attend to their neighbourhood only (here and in the denoiser)."""
        b, a = batch.agent_valid.shape
        agent_pose = batch.current_state[..., :3]
        agent = self.agent_embed(agent_local_history(batch).reshape(b, a, -1))
        if self.lane_embed is not None:
            agent = agent + self.lane_embed(lane_relative_history(batch).reshape(b, a, -1))
        agent = agent + self.agent_type(batch.agent_type.clamp(0, _AGENT_TYPES - 1)) + self.agent_size(batch.agent_size)
        encoded = map_context if map_context is not None else self.encode_map(batch)
        polylines, map_pose, map_mask = (
            t.expand(b, *t.shape[1:]) for t in (encoded.tokens, encoded.pose, encoded.mask)
        )
        context_mask = torch.cat([batch.agent_valid, map_mask], dim=1)
        context_pose = torch.cat([agent_pose, map_pose], dim=1)
        neighbours = None
        if local is not None and (a > local.agents or polylines.shape[1] > local.map_pieces):
            neighbours = nearest_neighbours(batch, local)
            agent_attn, index = neighbours.context_valid & batch.agent_valid[:, :, None], neighbours.context
        else:
            agent_attn, index = context_mask[:, None, :].expand(b, a, -1) & batch.agent_valid[:, :, None], None
        recompute = recomputing(self.checkpointing, self)
        for layer in self.agent_layers:
            context = torch.cat([agent, polylines], dim=1)
            agent = run_block(recompute, layer, agent, agent_pose, context, context_pose, agent_attn, None, index)
        agent = agent * batch.agent_valid[..., None]
        return SceneContext(agent, agent_pose, batch.agent_valid, polylines, map_pose, map_mask, neighbours)
