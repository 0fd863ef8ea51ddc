"""Target marks (`viz.marks`): drawn at their points and nowhere else, kept in cached frames, read from a
prompt report, and refused with the field named when bad."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.viz import RenderConfig, TargetMark, TopDownRenderer, marks_from_prompt, render_frame, style
from viz.helpers import NUM_STEPS, SDC_ID, make_scenario, near_colour, pixel

MARKS = (
    TargetMark(((-25.0, -15.0), (-5.0, -15.0), (15.0, -15.0)), "path"),
    TargetMark(((-2.0, -19.0), (2.0, -19.0)), "stop"),
    TargetMark(((12.0, 14.0),), "goal"),
    TargetMark(((-14.0, 14.0),), "conflict"),
)


def test_marks_are_drawn_at_their_points_and_nowhere_else():
    scenario = make_scenario()
    step = 6
    config = RenderConfig(size_px=400, trail_steps=0)
    with TopDownRenderer(scenario, config, steps=[step]) as plain:
        without = plain.frame(step)
    with TopDownRenderer(scenario, replace(config, marks=MARKS), steps=[step]) as marked:
        assert marked.camera.limits(step) == plain.camera.limits(step)  # marks do not move the view
        image = marked.frame(step)
        changed = np.abs(image.astype(int) - without.astype(int)).max(axis=-1) > 30
        near = np.zeros_like(changed)
        for mark in MARKS:
            rows, cols = zip(*(pixel(marked, step, tuple(p)) for p in mark.points), strict=True)
            near[max(min(rows) - 9, 0) : max(rows) + 10, max(min(cols) - 9, 0) : max(cols) + 10] = True
            assert changed[near].any()
        assert changed.any() and not changed[~near].any()
        for xy, colour in (
            ((-5.0, -15.0), style.MARK_COLOR),
            ((0.0, -19.0), style.MARK_STOP_COLOR),
            ((12.0, 14.0), style.MARK_GOAL_COLOR),
            ((-14.0, 14.0), style.MARK_CONFLICT_COLOR),
        ):
            row, col = pixel(marked, step, xy)
            assert near_colour(image, row, col, colour, radius=4, tol=40)  # the path is a little transparent
            assert not near_colour(without, row, col, colour, radius=4, tol=40)


def test_marks_stay_in_cached_frames_and_move_with_a_following_camera():
    scenario = make_scenario()
    goal = TargetMark(((-14.0, -6.0),), "goal", label="@100 stop")
    fixed = RenderConfig(size_px=320, marks=(goal,))
    with TopDownRenderer(scenario, fixed) as renderer:  # the map and marks are blitted from the cache
        for step in (0, 5, NUM_STEPS - 1):
            assert near_colour(renderer.frame(step), *pixel(renderer, step, (-14.0, -6.0)), style.MARK_GOAL_COLOR)
    follow = replace(fixed, follow_track_id=SDC_ID, view_extent_m=30.0)
    with TopDownRenderer(scenario, follow) as renderer:
        first, last = pixel(renderer, 0, (-14.0, -6.0)), pixel(renderer, NUM_STEPS - 1, (-14.0, -6.0))
        assert last[1] < first[1] - 60  # the camera moved right, so the goal moved left in the image
        assert near_colour(renderer.frame(0), *first, style.MARK_GOAL_COLOR)
        image = renderer.frame(NUM_STEPS - 1)
        assert near_colour(image, *last, style.MARK_GOAL_COLOR)
        assert not near_colour(image, *first, style.MARK_GOAL_COLOR)


def test_marks_from_prompt_reads_the_prompt_report():
    path = [[float(x), 0.0] for x in range(0, 40, 2)]
    report = {
        "read": [],
        "steering": [],
        "targets": [
            {"track_id": 7, "behaviour": "stop", "path": path, "goal": [19.0, 0.0], "stop": True, "conflict": None},
            {"track_id": 7, "behaviour": "turn_left", "path": path, "goal": [30.0, 0.0], "stop": False},
            {"track_id": 7, "behaviour": "yield", "path": path, "goal": [10.0, 0.0], "stop": False,
             "conflict": [10.0, 0.0], "other_id": 4, "first": False},
            {"track_id": 9, "behaviour": "speed_up", "path": [], "goal": None, "stop": False, "conflict": None},
        ],
    }  # fmt: skip
    marks = marks_from_prompt(json.loads(json.dumps(report)))
    assert [m.kind for m in marks] == ["path", "stop", "path", "goal", "path", "conflict"]
    assert marks[0].points == (*((x, y) for x, y in path[:10]), (19.0, 0.0))  # up to the stop, where it is to stay
    assert marks[2].points == tuple((x, y) for x, y in path)
    (x0, y0), (x1, y1) = marks[1].points  # a stop bar across the path at the goal
    assert x0 == x1 == 19.0 and abs(y1 - y0) == pytest.approx(style.MARK_STOP_BAR_M)
    assert marks[1].label == "@7 stop" and marks[3].label == "@7 turn left"
    assert marks[3].points == ((30.0, 0.0),)
    assert marks[5].points == ((10.0, 0.0),) and marks[5].label == "@7 after @4"  # the goal is the conflict
    assert marks_from_prompt(None) == marks_from_prompt({}) == marks_from_prompt({"targets": []}) == ()
    render_frame(make_scenario(), 3, RenderConfig(size_px=64, marks=marks))  # every kind draws


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: TargetMark(((0.0, 0.0), (float("nan"), 1.0)), "path"), r"points\[1\] must be finite"),
        (lambda: TargetMark(((0.0, 0.0), (1.0,)), "path"), r"points\[1\] must be two numbers"),
        (lambda: TargetMark(((0.0, 0.0),), "circle"), r"kind must be one of path, stop, goal, conflict"),
        (lambda: TargetMark(((0.0, 0.0),), "path"), r"points of a path mark must be at least two"),
        (lambda: TargetMark(((0.0, 0.0),) * 3, "stop"), r"points of a stop mark"),
        (lambda: TargetMark(((0.0, 0.0),), "goal", label="x" * 99), r"label must be one line"),
        (lambda: RenderConfig(marks=("goal",)), r"marks\[0\] must be a TargetMark, got str"),
        (lambda: RenderConfig(marks=TargetMark(((0.0, 0.0),), "goal")), r"marks must be a tuple of TargetMark"),
        (lambda: marks_from_prompt({"targets": [{"path": [[0, 0], [float("inf"), 1]]}]}), r"targets\[0\].*path\[1\]"),
        (lambda: marks_from_prompt({"targets": [{"path": [], "goal": [1.0, "a"]}]}), r"targets\[0\].*goal must"),
        (lambda: marks_from_prompt({"targets": {"a": 1}}), r"targets must be a list"),
    ],
)
def test_bad_marks_are_input_errors_naming_the_field(make, field):
    with pytest.raises(InputError, match=field):
        make()
