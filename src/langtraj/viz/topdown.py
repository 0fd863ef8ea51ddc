"""TopDownRenderer: draws one scenario step as an RGB image, reusing one figure for every frame.

The map and the target marks (`RenderConfig.marks`) are added once as grouped collections. Per frame only
the agent boxes, heading ticks, trails, labels, signal markers and caption change. The rasterised map is
cached and blitted while the camera holds still; a moving camera redraws it, marks included, so they move
with a following camera. Overlays (caption, scale bar, legend) go on top; the caption is wrapped to the
width of the image. docs/benchmarks.md measures the renderer's speed and docs/simulation.md describes the
demo video made of its frames.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from types import TracebackType

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import to_rgba, to_rgba_array
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.text import Text
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

from langtraj.errors import InputError
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField
from langtraj.viz import style
from langtraj.viz.camera import Camera, Limits
from langtraj.viz.config import RenderConfig
from langtraj.viz.maplayer import add_map
from langtraj.viz.marks import TargetMark


def box_corners(xy: np.ndarray, heading: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Corners [N, 4, 2] of oriented boxes (rear-left, rear-right, front-right, front-left)."""
    c, s = np.cos(heading), np.sin(heading)
    fwd = np.stack([c, s], axis=-1) * (length / 2.0)[:, None]
    left = np.stack([-s, c], axis=-1) * (width / 2.0)[:, None]
    return np.stack([xy - fwd + left, xy - fwd - left, xy + fwd - left, xy + fwd + left], axis=1)


def nice_length(span_m: float) -> float:
    """A round scale-bar length (1, 2 or 5 times a power of ten) of about a fifth of the view."""
    target = max(span_m / 5.0, 1e-6)
    power = 10.0 ** math.floor(math.log10(target))
    return max(m * power for m in (1.0, 2.0, 5.0) if m * power <= target)


CAPTION_INSET = 0.012
"""Gap between the caption's text and the image's top and left edges, as a fraction of the image."""

CAPTION_PAD = 0.35
"""Padding of the caption's box around its text, as a fraction of the font size."""


def wrap_caption(text: str, width: int) -> str:
    """`text` with each of its lines wrapped at spaces to at most `width` characters (a longer word is
    broken); lines already short enough are kept as they are."""
    width = max(int(width), 1)
    return "\n".join(textwrap.fill(line, width) or line for line in text.split("\n"))


def _check_step(scenario: Scenario, step: int) -> int:
    if not 0 <= int(step) < scenario.num_steps:
        raise InputError(f"step {step} is outside [0, {scenario.num_steps})", where=scenario.scenario_id)
    return int(step)


def _agent_indices(scenario: Scenario, track_ids: Sequence[int]) -> list[int]:
    out = []
    for tid in track_ids:
        try:
            out.append(scenario.agents.index_of(tid))
        except KeyError:
            raise InputError(f"track id {tid} is not in the scene", where=scenario.scenario_id) from None
    return out


class TopDownRenderer:
    """Renders steps of one scenario to uint8 RGB arrays [H, W, 3]; reuse it across a video's frames.

    `steps` are the steps that will be rendered; a fixed camera frames the agents over them
    (default: all steps). Use as a context manager, or call `close()`, to free the figure.
    """

    def __init__(
        self,
        scenario: Scenario,
        config: RenderConfig | None = None,
        steps: Sequence[int] | None = None,
    ):
        self.scenario = scenario
        self.config = config = config if config is not None else RenderConfig()
        steps = range(scenario.num_steps) if steps is None else [_check_step(scenario, s) for s in steps]
        follow = None
        if config.follow_track_id is not None:
            follow = _agent_indices(scenario, [config.follow_track_id])[0]
        self._highlight = np.zeros(scenario.num_agents, bool)
        self._highlight[_agent_indices(scenario, config.highlight_ids)] = True
        self.camera = Camera(
            scenario, steps, follow_index=follow, view_extent_m=config.view_extent_m, margin_m=config.margin_m
        )
        self._prepare_agents()
        self._min_box_m = style.MIN_BOX_PX * self.camera.span / config.size_px

        dpi = config.effective_dpi
        inches = config.size_px / dpi
        self._fig = Figure(figsize=(inches, inches), dpi=dpi, facecolor=style.BACKGROUND)
        self._canvas = FigureCanvasAgg(self._fig)
        ax = self._ax = self._fig.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_axis_off()
        ax.set_autoscale_on(False)
        add_map(ax, scenario.road_map)
        add_marks(ax, config.marks)
        self._overlays: list = []  # scale bar and legend: fixed, but drawn over the agents each frame
        self._add_dynamic_artists()
        self._add_scale_bar()
        if config.show_legend:
            self._add_legend()
        self._background = None
        self._background_limits: Limits | None = None

    # ------------------------------------------------------------------ setup
    def _prepare_agents(self) -> None:
        """Per-agent colours and fallback sizes, computed once."""
        agents = self.scenario.agents
        face = to_rgba_array([style.agent_color(t) for t in agents.types]) if agents.num_agents else np.zeros((0, 4))
        if self.scenario.sdc_index >= 0:
            face[self.scenario.sdc_index] = to_rgba(style.SDC_COLOR)
        self._face = face
        self._default_size = np.array(
            [style.DEFAULT_SIZE_M.get(AgentType(int(t)), (1.0, 1.0)) for t in agents.types], np.float64
        ).reshape(-1, 2)
        self._edge = np.where(
            self._highlight[:, None], to_rgba(style.HIGHLIGHT_EDGE), to_rgba(style.AGENT_EDGE)
        ).reshape(-1, 4)
        self._edge_width = np.where(self._highlight, style.HIGHLIGHT_EDGE_WIDTH, style.AGENT_EDGE_WIDTH)

    def _add_dynamic_artists(self) -> None:
        ax = self._ax
        self._trails = LineCollection(
            [], linewidths=style.TRAIL_WIDTH, capstyle="round", zorder=style.TRAIL_ZORDER, animated=True
        )
        self._boxes = PolyCollection([], closed=True, zorder=style.AGENT_ZORDER, animated=True)
        self._ticks = LineCollection(
            [], colors=style.HEADING_COLOR, linewidths=style.HEADING_WIDTH, zorder=style.HEADING_ZORDER,
            animated=True,
        )  # fmt: skip
        self._light_bars = LineCollection(
            [], linewidths=style.LIGHT_BAR_WIDTH, capstyle="butt", zorder=style.LIGHT_ZORDER, animated=True
        )
        self._light_dots = ax.scatter(
            np.zeros(0), np.zeros(0), s=style.LIGHT_SIZE, edgecolors=style.LIGHT_EDGE, linewidths=0.8,
            zorder=style.LIGHT_ZORDER, animated=True,
        )  # fmt: skip
        ax.add_collection(self._light_bars, autolim=False)
        for coll in (self._trails, self._boxes, self._ticks):
            ax.add_collection(coll, autolim=False)
        self._labels: dict[int, Text] = {}
        self._caption = ax.text(
            CAPTION_INSET, 1.0 - CAPTION_INSET, "", transform=ax.transAxes, ha="left", va="top", color=style.TEXT,
            fontsize=style.CAPTION_SIZE, family="monospace", zorder=style.CAPTION_ZORDER, animated=True,
            bbox={"boxstyle": f"round,pad={CAPTION_PAD}", "facecolor": style.TEXT_BOX, "alpha": 0.55,
                  "edgecolor": "none"},
        )  # fmt: skip
        self.caption_chars = self._caption_chars()
        """How many characters of the caption fit on one line of the image; longer lines are wrapped."""
        lights = self.scenario.traffic_lights
        assert lights is not None
        self._light_xy = lights.stop_points[:, :2]
        self._light_across = _stop_bar_directions(self.scenario)
        self._light_rgba = to_rgba_array([style.light_color(s) for s in range(9)])

    def _caption_chars(self) -> int:
        """Characters of the caption's monospace font that fit across the image between its insets,
        inside the caption's box (measured with the figure's renderer, so any size and dpi fit)."""
        probe = "0" * 40
        renderer = self._canvas.get_renderer()
        probe_px = renderer.get_text_width_height_descent(probe, self._caption.get_fontproperties(), ismath=False)[0]
        font_px = self._caption.get_fontsize() * self._fig.dpi / 72.0
        width_px = self._ax.bbox.width * (1.0 - 2.0 * CAPTION_INSET) - 2.0 * CAPTION_PAD * font_px
        return max(int(width_px / (probe_px / len(probe))), 1)

    def _add_scale_bar(self) -> None:
        length = nice_length(self.camera.span)
        label = f"{length:g} m"
        bar = AnchoredSizeBar(
            self._ax.transData, length, label, "lower right", pad=0.6, borderpad=0.5, sep=3,
            color=style.TEXT, frameon=True, size_vertical=0, fontproperties={"size": style.CAPTION_SIZE},
        )  # fmt: skip
        bar.size_bar.get_children()[0].set_linewidth(1.5)
        bar.patch.set(facecolor=style.TEXT_BOX, alpha=0.55, edgecolor="none", boxstyle="round,pad=0.2")
        bar.set(zorder=style.CAPTION_ZORDER, animated=True)  # drawn over the agents
        self._ax.add_artist(bar)
        self._overlays.append(bar)

    def _add_legend(self) -> None:
        def swatch(color: str, name: str) -> Line2D:
            return Line2D([], [], ls="none", marker="s", markersize=7, markerfacecolor=color,
                          markeredgecolor=style.AGENT_EDGE, label=name)  # fmt: skip

        handles = [swatch(style.AGENT_COLORS[t], t.name.lower()) for t in AgentType]
        if self.scenario.sdc_index >= 0:
            handles.append(swatch(style.SDC_COLOR, "sdc"))
        legend = self._ax.legend(
            handles=handles, loc="lower left", fontsize=style.CAPTION_SIZE * 0.85, frameon=True,
            facecolor=style.TEXT_BOX, edgecolor="none", framealpha=0.55, labelcolor=style.TEXT,
            handletextpad=0.3, borderpad=0.4,
        )  # fmt: skip
        legend.set(zorder=style.CAPTION_ZORDER, animated=True)
        self._overlays.append(legend)

    # ------------------------------------------------------------------ per frame
    def _update_agents(self, step: int, limits: Limits) -> list:
        agents = self.scenario.agents
        idx = np.flatnonzero(agents.valid[:, step])
        idx = idx[np.argsort(self._highlight[idx], kind="stable")]  # highlighted boxes draw last, on top
        st = agents.states[idx, step].astype(np.float64)
        size = st[:, StateField.LENGTH : StateField.WIDTH + 1]
        bad = ~(np.isfinite(size) & (size > 0.05)).all(axis=1)
        size[bad] = self._default_size[idx[bad]]
        np.maximum(size, self._min_box_m, out=size)
        xy, heading = st[:, : StateField.Y + 1], st[:, StateField.HEADING]
        self._boxes.set_verts(box_corners(xy, heading, size[:, 0], size[:, 1]))
        self._boxes.set_facecolor(self._face[idx])
        self._boxes.set_edgecolor(self._edge[idx])
        self._boxes.set_linewidth(self._edge_width[idx])
        front = xy + np.stack([np.cos(heading), np.sin(heading)], axis=-1) * (size[:, :1] / 2.0)
        self._ticks.set_segments(np.stack([xy, front], axis=1))
        artists: list = [self._trails, self._boxes, self._ticks]
        self._update_trails(step, idx)
        if self.config.show_ids:
            artists += self._update_labels(idx, xy, size, limits)
        return artists

    def _update_trails(self, step: int, idx: np.ndarray) -> None:
        n = self.config.trail_steps
        lo = max(0, step - n)
        if n == 0 or step == lo or len(idx) == 0:
            self._trails.set_segments([])
            return
        xy = self.scenario.agents.xy[idx, lo : step + 1]
        valid = self.scenario.agents.valid[idx, lo : step + 1]
        segs = np.stack([xy[:, :-1], xy[:, 1:]], axis=2)  # [n_agents, K, 2, 2]
        ok = valid[:, :-1] & valid[:, 1:]
        age = step - np.arange(lo + 1, step + 1)  # 0 for the newest segment
        alpha = style.TRAIL_MAX_ALPHA * (1.0 - age / n)
        colors = np.broadcast_to(self._face[idx][:, None], (*ok.shape, 4)).copy()
        colors[..., 3] = alpha[None, :]
        self._trails.set_segments(segs[ok])
        self._trails.set_color(colors[ok])

    def _label(self, agent: int) -> Text:
        text = self._labels.get(agent)
        if text is None:
            text = self._ax.text(
                0.0, 0.0, str(int(self.scenario.agents.ids[agent])), color=style.TEXT,
                fontsize=style.LABEL_SIZE, ha="left", va="bottom", zorder=style.LABEL_ZORDER,
                animated=True, clip_on=True,
            )  # fmt: skip
            self._labels[agent] = text
        return text

    def _update_labels(self, idx: np.ndarray, xy: np.ndarray, size: np.ndarray, limits: Limits) -> list:
        x0, x1, y0, y1 = limits
        inside = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
        shown = []
        for agent, (x, y), half, keep in zip(idx, xy, size.max(axis=1) / 2.0, inside, strict=True):
            if keep:
                text = self._label(int(agent))
                text.set_position((x + half * 0.5, y + half * 0.5))
                shown.append(text)
        return shown

    def _update_lights(self, step: int) -> list:
        """Signal states as bars across each controlled lane at its stop point (a dot where the lane's
        direction is unknown), coloured by the state at `step`; lanes without a valid state are hidden."""
        lights = self.scenario.traffic_lights
        assert lights is not None
        if lights.num_lanes == 0:
            return []
        valid = lights.valid[step]
        colors = self._light_rgba[np.clip(lights.states[step].astype(np.int64), 0, 8)]
        has_bar = np.isfinite(self._light_across).all(axis=1)
        bars, dots = valid & has_bar, valid & ~has_bar
        half = self._light_across[bars] * (style.LIGHT_BAR_LENGTH_M / 2.0)
        centre = self._light_xy[bars]
        self._light_bars.set_segments(np.stack([centre - half, centre + half], axis=1))
        self._light_bars.set_color(colors[bars])
        self._light_dots.set_offsets(self._light_xy[dots])
        self._light_dots.set_facecolor(colors[dots])
        return [self._light_bars, self._light_dots]

    def _caption_text(self, step: int) -> str:
        s = self.scenario
        title = self.config.caption if self.config.caption is not None else f"scenario {s.scenario_id}"
        t = s.timestamps[step] - s.timestamps[0]
        phase = "history" if step < s.current_index else "current" if step == s.current_index else "future"
        clock = f"step {step:>{len(str(s.num_steps - 1))}}/{s.num_steps - 1}  t={t:5.1f} s  {phase}"
        return wrap_caption(f"{title}\n{clock}", self.caption_chars)

    def frame(self, step: int) -> np.ndarray:
        """The image of `step`: uint8 [size_px, size_px, 3]."""
        step = _check_step(self.scenario, step)
        limits = self.camera.limits(step)
        canvas = self._canvas
        if self._background is None or limits != self._background_limits:
            self._ax.set_xlim(limits[0], limits[1])
            self._ax.set_ylim(limits[2], limits[3])
            canvas.draw()  # animated (per-frame) artists are skipped here
            self._background = canvas.copy_from_bbox(self._fig.bbox)
            self._background_limits = limits
        else:
            canvas.restore_region(self._background)
        artists = self._update_agents(step, limits) + self._update_lights(step)
        self._caption.set_text(self._caption_text(step))
        artists += [self._caption, *self._overlays]
        for artist in sorted(artists, key=lambda a: a.get_zorder()):
            self._ax.draw_artist(artist)
        rgba = np.asarray(canvas.buffer_rgba())
        return _fit(np.ascontiguousarray(rgba[..., :3]), self.config.size_px)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Release the figure (the renderer cannot draw afterwards)."""
        self._fig.clear()
        self._background = None

    def __enter__(self) -> TopDownRenderer:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def add_marks(ax: Axes, marks: Sequence[TargetMark]) -> list:
    """Draw target marks as static world-frame artists (cached with the map, under the agents): paths as dashed
    polylines over a dark halo, stops as white-edged bars or octagons, goals as stars, conflict points as crosses,
    and each label beside the mark's last point (a stop bar's middle). Returns the artists added."""
    z = style.MARK_ZORDER
    added: list = []
    paths = [m.xy for m in marks if m.kind == "path"]
    if paths:
        for width, color, dashes, alpha, dz in (
            (style.MARK_PATH_UNDERLAY_WIDTH, style.MARK_UNDERLAY, "solid", 0.5, 0.0),
            (style.MARK_PATH_WIDTH, style.MARK_COLOR, (0.0, style.MARK_PATH_DASHES), style.MARK_PATH_ALPHA, 0.01),
        ):
            coll = LineCollection(
                paths, colors=color, linewidths=width, linestyles=dashes, alpha=alpha, zorder=z + dz,
                capstyle="round", joinstyle="round",
            )  # fmt: skip
            added.append(ax.add_collection(coll, autolim=False))
    bars = [m.xy for m in marks if m.kind == "stop" and len(m.points) == 2]
    if bars:
        for width, color, dz in (
            (style.MARK_STOP_BAR_WIDTH + 3 * style.MARK_EDGE_WIDTH, style.MARK_COLOR, 0.02),  # unlike a signal's bar
            (style.MARK_STOP_BAR_WIDTH, style.MARK_STOP_COLOR, 0.03),
        ):
            coll = LineCollection(bars, colors=color, linewidths=width, capstyle="butt", zorder=z + dz)
            added.append(ax.add_collection(coll, autolim=False))
    dots = (
        ("stop", "8", style.MARK_STOP_COLOR, style.MARK_STOP_SIZE, style.MARK_COLOR),
        ("goal", "*", style.MARK_GOAL_COLOR, style.MARK_GOAL_SIZE, style.MARK_EDGE),
        ("conflict", "X", style.MARK_CONFLICT_COLOR, style.MARK_CONFLICT_SIZE, style.MARK_EDGE),
    )
    for kind, marker, color, size, edge in dots:
        points = [m.xy for m in marks if m.kind == kind and not (kind == "stop" and len(m.points) == 2)]
        if points:
            xy = np.concatenate(points)
            dot = ax.scatter(
                xy[:, 0], xy[:, 1], s=size, marker=marker, c=color, edgecolors=edge,
                linewidths=style.MARK_EDGE_WIDTH, zorder=z + 0.04,
            )  # fmt: skip
            added.append(dot)
    for mark in marks:
        if mark.label:
            x, y = mark.xy.mean(axis=0) if mark.kind == "stop" else mark.xy[-1]
            text = ax.text(
                x, y, f" {mark.label}", color=style.TEXT, fontsize=style.MARK_LABEL_SIZE, ha="left",
                va="bottom", zorder=z + 0.05, clip_on=True,
                bbox={"boxstyle": "round,pad=0.2", "facecolor": style.TEXT_BOX, "alpha": 0.45, "edgecolor": "none"},
            )  # fmt: skip
            added.append(text)
    return added


def _stop_bar_directions(scenario: Scenario) -> np.ndarray:
    """Unit vectors [L, 2] across each signal-controlled lane at its stop point (NaN when the lane is
    missing from the map or has fewer than two points)."""
    lights = scenario.traffic_lights
    assert lights is not None
    out = np.full((lights.num_lanes, 2), np.nan)
    by_id = scenario.road_map.by_id
    for n, (lane_id, stop) in enumerate(zip(lights.lane_ids, lights.stop_points[:, :2], strict=True)):
        lane = by_id.get(int(lane_id))
        if lane is None or len(lane.points) < 2:
            continue
        pts = lane.points[:, :2]
        k = int(np.argmin(np.linalg.norm(pts - stop, axis=1)))
        a, b = pts[max(k - 1, 0)], pts[min(k + 1, len(pts) - 1)]
        d = b - a
        norm = float(np.hypot(*d))
        if norm > 1e-6:
            out[n] = (-d[1] / norm, d[0] / norm)
    return out


def _fit(image: np.ndarray, size: int) -> np.ndarray:
    """Crop or edge-pad to exactly size x size (guards against figure-size rounding)."""
    image = image[:size, :size]
    pad_h, pad_w = size - image.shape[0], size - image.shape[1]
    if pad_h or pad_w:
        image = np.pad(image, ((0, pad_h), (0, pad_w), (0, 0)), mode="edge")
    return image


def render_frame(scenario: Scenario, step: int, config: RenderConfig | None = None) -> np.ndarray:
    """One step of `scenario` as uint8 RGB [H, W, 3]; a fixed camera frames the agents at that step."""
    with TopDownRenderer(scenario, config, steps=[step]) as renderer:
        return renderer.frame(step)
