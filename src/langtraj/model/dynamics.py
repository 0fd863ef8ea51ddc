"""Agent dynamics: the map from the diffusion model's actions to 10 Hz states, and its inverse for training.

LangTraj diffuses over unicycle actions (acceleration, yaw rate) at 2 Hz; each action is held for
`steps_per_action` scenario steps of `dt` seconds (5 x 0.1 s). A state is (x, y, heading, speed).

See docs/model.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar

import torch
from torch import Tensor, nn

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.registry import Registry


class Dynamics(nn.Module, ABC):
    """Actions [..., N, action_dim] held for `steps_per_action` steps of `dt` s each -> states [..., N*steps, 4]."""

    name: ClassVar[str]
    action_dim: ClassVar[int]

    def __init__(self, steps_per_action: int = 5, dt: float = 0.1):
        super().__init__()
        if steps_per_action < 1 or dt <= 0:
            raise InputError(f"need steps_per_action >= 1 and dt > 0, got {steps_per_action} and {dt}")
        self.steps_per_action = int(steps_per_action)
        self.dt = float(dt)

    @abstractmethod
    def forward(self, initial: Tensor, actions: Tensor, max_curvature: Tensor | None = None) -> Tensor:
        """initial [..., 4] (x, y, heading, speed) at the current step; actions [..., N, action_dim]
        -> states [..., N*steps_per_action, 4] at the 10 Hz steps after the current one. `max_curvature`
        [...] (1/m), where given, is each agent's tightest turn (a model may ignore it)."""

    @abstractmethod
    def inverse(self, initial: Tensor, states: Tensor, valid: Tensor) -> tuple[Tensor, Tensor]:
        """Logged future states [..., T, 3 or 4] (x, y, heading[, speed]) with valid [..., T] ->
        (actions [..., T//steps_per_action, action_dim], action_valid [..., T//steps_per_action]) whose
        forward() reproduces the log as closely as the model allows."""


DYNAMICS: Registry[Dynamics] = Registry("dynamics")


@DYNAMICS.register
class Unicycle(Dynamics):
    """Unicycle with actions (acceleration m/s^2, yaw rate rad/s); speed is clamped at 0 (no reversing).

    Per substep of `dt`: v' = max(v + a dt, 0); h' = h + w dt; x' = x + v' cos(h') dt; y' = y + v' sin(h') dt
    (semi-implicit Euler: the new speed and heading move the position). `forward` does not clip actions to
    the bounds, so guidance gradients never vanish there; `inverse` returns actions within them and `clip`
    applies them. Bounds: |a| <= 8 m/s^2 (about emergency braking) and |w| <= 1.5 rad/s (a 3 m radius
    turn at 4.5 m/s). Unbounded fits to real WOMD and nuScenes logs (docs/model.md) gave vehicle |w| <= 0.76 rad/s
    and |a| p99 of 6-14 m/s^2, the excess being track glitches that the bounds rightly refuse; pedestrian
    heading flips reach 15 rad/s and are cut to 1.5 (their positions still fit within 0.6 m).

    Reversing agents (rare in WOMD) cannot be represented: their reconstruction stops at speed 0.
    """

    name = "unicycle"
    action_dim = 2

    def __init__(
        self,
        steps_per_action: int = 5,
        dt: float = 0.1,
        max_accel: float = 8.0,
        max_yaw_rate: float = 1.5,
        heading_weight: float = 1.0,
        speed_weight: float = 0.1,
        iterations: int = 5,
    ):
        super().__init__(steps_per_action, dt)
        self.max_accel = float(max_accel)
        self.max_yaw_rate = float(max_yaw_rate)
        # Weights of the inverse fit's residuals relative to position (m): heading in m/rad, speed in s.
        self.heading_weight = float(heading_weight)
        self.speed_weight = float(speed_weight)
        self.iterations = int(iterations)

    def clip(self, actions: Tensor) -> Tensor:
        """Actions [..., 2] clipped to (+-max_accel, +-max_yaw_rate)."""
        accel = actions[..., 0].clamp(-self.max_accel, self.max_accel)
        yaw_rate = actions[..., 1].clamp(-self.max_yaw_rate, self.max_yaw_rate)
        return torch.stack([accel, yaw_rate], dim=-1)

    def forward(self, initial: Tensor, actions: Tensor, max_curvature: Tensor | None = None) -> Tensor:
        """`max_curvature` [...] (1/m, per agent; inf for none) bounds the yaw rate by curvature x speed, so
        an agent with that bound cannot turn on the spot (a car's heading only changes while it moves)."""
        if initial.shape[-1] != 4 or actions.shape[-1] != 2 or actions.shape[:-2] != initial.shape[:-1]:
            raise InputError(f"expected initial [..., 4] and actions [..., N, 2], got {initial.shape}, {actions.shape}")
        dt = self.dt
        sub = actions.repeat_interleave(self.steps_per_action, dim=-2)  # [..., T, 2]
        x0, y0, h0, v0 = initial.unbind(-1)
        # v_t = max(v_{t-1} + a_t dt, 0) in closed form (Lindley recursion): S_t - min(0, min_{s<=t} S_s).
        unclamped = v0.clamp(min=0)[..., None] + torch.cumsum(sub[..., 0] * dt, dim=-1)
        speed = unclamped - torch.cummin(unclamped, dim=-1).values.clamp(max=0)
        yaw_rate = sub[..., 1]
        if max_curvature is not None:
            # No inf inside the product: inf x 0 m/s is NaN, and so is its gradient even where unselected.
            unbounded = torch.isinf(max_curvature)[..., None]
            finite = torch.where(unbounded, 0.0, max_curvature[..., None])
            bound = torch.where(unbounded, torch.inf, finite * speed)
            yaw_rate = torch.minimum(torch.maximum(yaw_rate, -bound), bound)
        heading = h0[..., None] + torch.cumsum(yaw_rate * dt, dim=-1)
        x = x0[..., None] + torch.cumsum(speed * torch.cos(heading) * dt, dim=-1)
        y = y0[..., None] + torch.cumsum(speed * torch.sin(heading) * dt, dim=-1)
        return torch.stack([x, y, heading, speed], dim=-1)

    @torch.no_grad()
    def inverse(self, initial: Tensor, states: Tensor, valid: Tensor) -> tuple[Tensor, Tensor]:
        """Greedy closed-loop fit, block by block, against the simulated state (so errors do not accumulate).

        Each block's (a, w) is a least-squares fit (a few Gauss-Newton steps, the speed clamp modelled) of
        the state at the block's last step to the log's position, heading (and speed when given); an
        invalid last step between valid ones (the initial state counts as valid) is linearly interpolated;
        after the log's last valid step, the block holding it fits that step at its own substep and later
        blocks get zero actions.
        `action_valid` marks blocks holding a valid log step. Trailing steps past the last whole block are
        ignored. Actions are clipped to the bounds. Runs without autograd (a data-preparation step).
        """
        steps = self.steps_per_action
        if initial.shape[-1] != 4 or states.shape[-1] not in (3, 4) or valid.shape != states.shape[:-1]:
            raise InputError(
                f"expected initial [..., 4], states [..., T, 3|4], valid [..., T]; "
                f"got {initial.shape}, {states.shape}, {valid.shape}"
            )
        if states.shape[:-2] != initial.shape[:-1]:
            raise InputError(f"leading dims of initial {initial.shape} and states {states.shape} differ")
        num_blocks = states.shape[-2] // steps
        total = num_blocks * steps
        valid = valid[..., :total].bool()
        action_valid = valid.reshape(*valid.shape[:-1], num_blocks, steps).any(-1)
        if num_blocks == 0:
            return initial.new_zeros(*initial.shape[:-1], 0, 2), action_valid
        # Work relative to the initial position so float32 world coordinates keep their precision.
        rel = torch.cat([states[..., :total, :2] - initial[..., None, :2], states[..., :total, 2:]], dim=-1)
        rel = torch.where(valid[..., None], rel, torch.zeros_like(rel))  # invalid values may be NaN
        start = torch.cat([torch.zeros_like(initial[..., :2]), initial[..., 2:]], dim=-1)
        targets, known = self._targets(start[..., None, : rel.shape[-1]], rel, valid)
        # Fit each block at its last known substep only (fitting all substeps chased noise no better).
        known = known.reshape(*known.shape[:-1], num_blocks, steps)
        last = (known * torch.arange(1, steps + 1, device=known.device)).argmax(-1, keepdim=True)
        weights = torch.zeros(known.shape, dtype=rel.dtype, device=rel.device).scatter(-1, last, 1.0)
        weights = weights * known.any(-1, keepdim=True)
        targets = targets.reshape(*targets.shape[:-2], num_blocks, steps, targets.shape[-1])

        state = start
        actions = []
        for b in range(num_blocks):
            action = self._fit_block(state, targets[..., b, :, :], weights[..., b, :])
            action = torch.where(weights[..., b, :].sum(-1, keepdim=True) > 0, action, torch.zeros_like(action))
            actions.append(action)
            state = self.forward(state, action[..., None, :])[..., -1, :]
        return torch.stack(actions, dim=-2), action_valid

    @staticmethod
    def _targets(start: Tensor, rel: Tensor, valid: Tensor) -> tuple[Tensor, Tensor]:
        """Per step: the target state [..., T, C] (logged, or interpolated in a gap) and whether it is known."""
        total = rel.shape[-2]
        index = torch.arange(total, device=rel.device)
        # Index -1 stands for the initial state; `total` for "no valid step after".
        prev = torch.cummax(torch.where(valid, index, -1), dim=-1).values
        nxt = torch.where(valid, index, total).flip(-1).cummin(-1).values.flip(-1)
        padded = torch.cat([start, rel], dim=-2)  # position p + 1 holds step p, 0 the initial state
        channels = rel.shape[-1]
        before = torch.gather(padded, -2, (prev + 1)[..., None].expand(*prev.shape, channels))
        after = torch.gather(padded, -2, (nxt.clamp(max=total - 1) + 1)[..., None].expand(*nxt.shape, channels))
        frac = ((index - prev) / (nxt - prev).clamp(min=1)).to(rel.dtype)[..., None]
        delta = after - before
        delta = torch.cat([delta[..., :2], wrap_angle(delta[..., 2:3]), delta[..., 3:]], dim=-1)
        targets = torch.where(valid[..., None], rel, before + frac * delta)
        return targets, valid | (nxt < total)

    def _fit_block(self, state: Tensor, target: Tensor, weight: Tensor) -> Tensor:
        """(a, w) [..., 2] whose substeps from `state` [..., 4] best fit `target` [..., S, 3|4], weighted [..., S]."""
        dt, steps = self.dt, self.steps_per_action
        x, y, h, v = state.unbind(-1)
        v = v.clamp(min=0)
        j = torch.arange(1, steps + 1, device=state.device, dtype=state.dtype)
        dx, dy = target[..., 0] - x[..., None], target[..., 1] - y[..., None]
        heading_error = wrap_angle(target[..., 2] - h[..., None])
        # Start: the yaw rate reaching the last weighted substep's heading, the accel fitting positions.
        last = (weight > 0).to(state.dtype) * j
        m = last.amax(-1).clamp(min=1)
        end_error = torch.gather(heading_error, -1, (m.long() - 1)[..., None])[..., 0]
        w = (end_error / (m * dt)).clamp(-self.max_yaw_rate, self.max_yaw_rate)
        heading = h[..., None] + j * w[..., None] * dt
        cum_cos, cum_sin = torch.cumsum(torch.cos(heading), -1), torch.cumsum(torch.sin(heading), -1)
        cum_jcos, cum_jsin = torch.cumsum(j * torch.cos(heading), -1), torch.cumsum(j * torch.sin(heading), -1)
        base_x, base_y = dt * v[..., None] * cum_cos, dt * v[..., None] * cum_sin
        gain_x, gain_y = dt * dt * cum_jcos, dt * dt * cum_jsin
        numerator = (weight * ((dx - base_x) * gain_x + (dy - base_y) * gain_y)).sum(-1)
        a = numerator / (weight * (gain_x**2 + gain_y**2)).sum(-1).clamp(min=1e-12)
        a = a.clamp(-self.max_accel, self.max_accel)

        lam, mu = self.heading_weight, self.speed_weight
        has_speed = target.shape[-1] == 4
        for _ in range(self.iterations):
            heading = h[..., None] + j * w[..., None] * dt
            cos, sin = torch.cos(heading), torch.sin(heading)
            raw = v[..., None] + j * a[..., None] * dt
            moving = (raw > 0).to(state.dtype)
            speed = raw * moving
            # Residuals per substep: position (m), weighted heading (and speed); Jacobian columns d/da, d/dw.
            r_x = dt * torch.cumsum(speed * cos, -1) - dx
            r_y = dt * torch.cumsum(speed * sin, -1) - dy
            r_h = lam * wrap_angle(j * w[..., None] * dt - heading_error)
            jx_a = dt * dt * torch.cumsum(j * moving * cos, -1)
            jy_a = dt * dt * torch.cumsum(j * moving * sin, -1)
            jx_w = -dt * dt * torch.cumsum(j * speed * sin, -1)
            jy_w = dt * dt * torch.cumsum(j * speed * cos, -1)
            jh_w = lam * j * dt
            g_a = (weight * (jx_a * r_x + jy_a * r_y)).sum(-1)
            g_w = (weight * (jx_w * r_x + jy_w * r_y + jh_w * r_h)).sum(-1)
            h_aa = (weight * (jx_a**2 + jy_a**2)).sum(-1)
            h_aw = (weight * (jx_a * jx_w + jy_a * jy_w)).sum(-1)
            h_ww = (weight * (jx_w**2 + jy_w**2 + jh_w**2)).sum(-1)
            if has_speed:
                r_v = mu * (speed - target[..., 3])
                jv_a = mu * j * dt * moving
                g_a = g_a + (weight * jv_a * r_v).sum(-1)
                h_aa = h_aa + (weight * jv_a**2).sum(-1)
            # Levenberg-Marquardt step with a tiny damping (the 2x2 system solved in closed form).
            h_aa = h_aa + 1e-9 + 1e-6 * h_aa
            h_ww = h_ww + 1e-9 + 1e-6 * h_ww
            det = h_aa * h_ww - h_aw**2
            a = (a - (h_ww * g_a - h_aw * g_w) / det).clamp(-self.max_accel, self.max_accel)
            w = (w - (h_aa * g_w - h_aw * g_a) / det).clamp(-self.max_yaw_rate, self.max_yaw_rate)
        # Below -v/dt the speed clamps at 0 after the first substep whatever a is: keep the mildest such a.
        a = torch.maximum(a, -v / dt).clamp(-self.max_accel, self.max_accel)
        return torch.stack([a, w], dim=-1)


def initial_state_from_log(
    xy: Tensor, heading: Tensor, valid: Tensor, velocity: Tensor | None = None, *, window: int = 5, dt: float = 0.1
) -> Tensor:
    """Current (x, y, heading, speed) [..., 4] from a history [..., H, 2|1] whose last step is the current one.

    WOMD velocity fields can be noisy, so the speed is the displacement from the earliest valid position
    up to `window` steps back to the current one, projected on the mean of the two headings (the chord
    direction of a circular arc) and clamped at 0; with no earlier valid position it is |velocity| at the
    current step when given, else 0. Values where the current step is invalid are undefined (zeros).
    """
    if xy.shape[-1] != 2 or heading.shape != xy.shape[:-1] or valid.shape != heading.shape:
        raise InputError(f"expected xy [..., H, 2], heading and valid [..., H]; got {xy.shape}, {heading.shape}")
    hist = xy.shape[-2]
    valid = valid.bool()
    xy = torch.where(valid[..., None], xy, torch.zeros_like(xy))
    heading = torch.where(valid, heading, torch.zeros_like(heading))
    current_xy, current_heading = xy[..., -1, :], heading[..., -1]
    speed = torch.zeros_like(current_heading)
    if velocity is not None:
        speed = torch.where(valid[..., -1], torch.linalg.vector_norm(velocity[..., -1, :], dim=-1), speed)
        speed = torch.nan_to_num(speed)
    found = torch.zeros_like(valid[..., -1])
    for k in range(min(window, hist - 1), 0, -1):  # the longest available baseline wins
        ok = valid[..., -1 - k] & valid[..., -1] & ~found
        disp = current_xy - xy[..., -1 - k, :]
        mean_heading = heading[..., -1 - k] + 0.5 * wrap_angle(current_heading - heading[..., -1 - k])
        along = disp[..., 0] * torch.cos(mean_heading) + disp[..., 1] * torch.sin(mean_heading)
        speed = torch.where(ok, (along / (k * dt)).clamp(min=0), speed)
        found = found | ok
    state = torch.stack([current_xy[..., 0], current_xy[..., 1], current_heading, speed], dim=-1)
    return torch.where(valid[..., -1, None], state, torch.zeros_like(state))
