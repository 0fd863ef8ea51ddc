"""LangTraj Studio in a real browser: Playwright drives Debian's Chromium against the real app (uvicorn on a free
port, the real simulation) over the shipped real scenes. Pick the Waymo scene, click an agent on the canvas to
insert its @id, write a prompt and see it read and its target drawn, run two rollouts, watch the replay (play,
scrub, its frame times), judge (followed per rollout), save the case and read the suite file; bad prompts show
a message and start no job; two tabs each start a job, both finish, a reload lists them. Every canvas is checked
for being drawn (not one colour). Set LANGTRAJ_SCREENSHOTS to a folder to keep a screenshot of every step.
"""

from __future__ import annotations

import base64
import io
import itertools
import json
import math
import os
import re
import statistics
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser_harness import chromium, serve

from langtraj.rollouts.container import Rollouts
from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog

try:
    import numpy as np
    from PIL import Image
    from playwright.sync_api import Browser, Page, expect
except ImportError as exc:
    pytest.skip(f"the browser tests need pillow: {exc}", allow_module_level=True)

SCENE_ID = "2a1e44d405a6833f"  # the real WOMD scene: 66 sim agents
WOMD_SCENE_ID = "637f20cafde22ff8"  # another real scene, to switch to
SMALL_SCENE_ID = "scene-0757_w0"  # nuScenes, few agents: the two tabs' quick jobs
SCREENSHOTS = os.environ.get("LANGTRAJ_SCREENSHOTS")
JOB_TIMEOUT_MS = 100_000
MEDIAN_FRAME_MS = 50.0
INFEASIBLE_ASKS = ("turns left", "turns right", "pulls over", "changes lane to the left", "changes lane to the right")


# ---------------------------------------------------------------- the server and the browser


@dataclass(frozen=True)
class Site:
    url: str
    data: Path

    def get(self, path: str) -> Any:
        with urllib.request.urlopen(f"{self.url}{path}", timeout=30) as response:
            return json.loads(response.read())

    def post(self, path: str, body: Any) -> Any:
        request = urllib.request.Request(
            f"{self.url}{path}", json.dumps(body).encode(), {"Content-Type": "application/json"}, method="POST"
        )
        with urllib.request.urlopen(request, timeout=60) as response:
            return json.loads(response.read())

    def scene_key(self, scenario_id: str) -> str:
        return next(s["key"] for s in self.get("/api/scenes")["scenes"] if s["scenario_id"] == scenario_id)

    def job_ids(self) -> list[str]:
        return [j["id"] for j in self.get("/api/jobs")["jobs"]]


@pytest.fixture(scope="module")
def site(catalog: Catalog, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    """The real app (the real simulation) over the real scenes and a corrupt file, served by uvicorn in a thread."""
    data = tmp_path_factory.mktemp("studio-browser") / "data"
    with serve(create_app(StudioConfig((), data=data), catalog), "/api/jobs") as url:
        yield Site(url, data)


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as browser:
        yield browser


def drawn(png: bytes) -> float:
    """The share of pixels that differ from the image's most common colour (0: blank, one colour)."""
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3)
    colours, counts = np.unique(rgb, axis=0, return_counts=True)
    return 1.0 - counts.max() / len(rgb) if len(colours) > 1 else 0.0


@dataclass
class Visit:
    """One page in a fresh browser context, with what it reported: dialogs and script errors (CSP included)."""

    page: Page
    name: str
    dialogs: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def shot(self, step: str, *canvases: str) -> None:
        """Screenshot the page (kept under LANGTRAJ_SCREENSHOTS) and check each canvas in it is drawn."""
        png = self.page.screenshot(full_page=True)
        if SCREENSHOTS:
            Path(SCREENSHOTS).mkdir(parents=True, exist_ok=True)
            (Path(SCREENSHOTS) / f"{self.name}-{step}.png").write_bytes(png)
        assert drawn(png) > 0.05, f"{step}: the page is blank"
        for selector in canvases:
            for k in range(self.page.locator(selector).count()):
                share = drawn(canvas_png(self.page, selector, k))
                assert share > 0.02, f"{step}: {selector} [{k}] is blank ({share:.3f} drawn)"

    def doc_shots(self) -> None:
        """Under LANGTRAJ_SCREENSHOTS, the main flow as docs/studio.md shows it: the page at 1280x800, its top (the
        scene, the prompt read, the job) and its replay."""
        if not SCREENSHOTS:
            return
        size = self.page.viewport_size
        self.page.set_viewport_size({"width": 1280, "height": 800})
        self.page.evaluate("() => window.scrollTo(0, 0)")
        self.page.screenshot(path=str(Path(SCREENSHOTS) / "studio-compose.png"))
        self.page.locator("#replay-title").scroll_into_view_if_needed()
        self.page.evaluate("() => document.getElementById('replay').scrollIntoView({ block: 'start' })")
        self.page.screenshot(path=str(Path(SCREENSHOTS) / "studio-replay.png"))
        if size:
            self.page.set_viewport_size(size)

    def check_clean(self) -> None:
        assert self.dialogs == [], f"dialogs fired: {self.dialogs}"
        assert self.errors == [], f"script errors or CSP violations: {self.errors}"


def canvas_png(page: Page, selector: str, k: int = 0) -> bytes:
    """The canvas's own pixels (`toDataURL`), as PNG bytes."""
    url = page.locator(selector).nth(k).evaluate("c => c.toDataURL('image/png')")
    return base64.b64decode(url.split(",", 1)[1])


def new_context(browser: Browser) -> Any:
    return browser.new_context(viewport={"width": 1400, "height": 950})


def visit(browser: Browser, site: Site, name: str, fragment: str = "", context: Any = None) -> Visit:
    """A new page (a tab of `context`, by default of a fresh browser context) on the studio at `fragment`."""
    page = (context or new_context(browser)).new_page()
    page.set_default_timeout(15_000)
    v = Visit(page, name)

    def on_dialog(dialog: Any) -> None:
        v.dialogs.append(dialog.message)
        dialog.dismiss()

    def on_console(message: Any) -> None:
        # "Failed to load resource" reports an HTTP error status: the 400s of the refused prompts
        if message.type == "error" and not message.text.startswith("Failed to load resource"):
            v.errors.append(message.text)

    page.on("dialog", on_dialog)
    page.on("console", on_console)
    page.on("pageerror", lambda error: v.errors.append(str(error)))
    page.goto(f"{site.url}/{fragment}")
    expect(page.locator("#scene-list button.scene").first).to_be_visible()
    return v


def open_scene(v: Visit, scenario_id: str) -> None:
    v.page.fill("#scene-search", scenario_id)
    expect(v.page.locator("#scene-list button.scene")).to_have_count(1)
    v.page.locator("#scene-list button.scene", has_text=scenario_id).click()
    expect(v.page.locator("#scene-title")).to_contain_text(scenario_id)


def set_prompt(v: Visit, text: str, k: int = 0) -> None:
    box = v.page.locator(f"#prompt-{k}")
    box.fill(text)
    if text.strip():
        expect(v.page.locator(f"#reading-{k}")).not_to_contain_text("Reading…", timeout=30_000)


def moving_vehicles(scene: dict[str, Any]) -> list[dict[str, Any]]:
    """The scene's sim vehicles moving at the current step, fastest first (each with its position)."""
    cur = scene["current_step"]
    out = []
    for a in scene["agents"]:
        p, q = a["track"][cur], a["track"][cur - 1]
        if a["sim"] and not a["sdc"] and a["type"] == "vehicle" and p and q:
            speed = math.hypot(p[0] - q[0], p[1] - q[1]) / scene["step_seconds"]
            if speed > 3.0:
                out.append({**a, "speed": speed, "at": p})
    return sorted(out, key=lambda a: -a["speed"])


def target_pixels(png: bytes) -> int:
    """How many pixels have the prompt target's colour (#e01b8f)."""
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    return int((np.abs(rgb - np.array([224, 27, 143])).sum(axis=2) < 40).sum())


def wait_done(page: Page, count: int) -> None:
    """Until the first `count` jobs of the list are done (each failing job fails the test with its error)."""
    badges = page.locator("#jobs .job .status-badge")
    deadline = time.monotonic() + JOB_TIMEOUT_MS / 1000
    while True:
        states = badges.all_text_contents()[:count]
        failed = [s for s in states if s in ("failed", "interrupted")]
        assert not failed, page.locator("#jobs").inner_text()
        if len(states) == count and all(s == "done" for s in states):
            return
        assert time.monotonic() < deadline, f"jobs not done in time: {states}"
        time.sleep(0.25)


# ---------------------------------------------------------------- the tests


def test_pick_prompt_run_watch_judge_keep(site: Site, browser: Browser) -> None:
    v = visit(browser, site, "main")
    page = v.page
    errors = page.locator("#scene-errors")
    expect(errors).to_be_visible()
    expect(errors).to_contain_text("corrupt.tfrecord")
    open_scene(v, SCENE_ID)
    v.shot("1-scene", "#scene-canvas")

    # click an agent on the canvas: its @id goes where the caret is
    key = site.scene_key(SCENE_ID)
    scene = site.get(f"/api/scenes/{key}")
    agent = moving_vehicles(scene)[0]
    page.locator("#prompt-0").click()
    point = page.evaluate(f"() => window.studio.agentPoint({agent['id']})")
    page.mouse.move(point["x"], point["y"])
    expect(page.locator("#hover-info")).to_contain_text(f"@{agent['id']}: vehicle")
    page.mouse.click(point["x"], point["y"])
    expect(page.locator("#prompt-0")).to_have_value(f"@{agent['id']} ")
    expect(page.locator("#prompt-0")).to_be_focused()
    blank_targets = target_pixels(canvas_png(page, "#scene-canvas"))

    # type the rest of the prompt: its reading and its target appear
    page.keyboard.type("slows down")
    reading = page.locator("#reading-0")
    expect(reading).to_contain_text(f"read as: @{agent['id']} slow_down", timeout=30_000)
    expect(reading.locator(".pill")).to_have_text("feasible")
    deadline = time.monotonic() + 5  # the canvas is redrawn on the next animation frame
    while target_pixels(canvas_png(page, "#scene-canvas")) <= blank_targets + 50:
        assert time.monotonic() < deadline, "the prompt's target is not drawn"
        page.wait_for_timeout(100)
    v.shot("2-prompt-read", "#scene-canvas")

    # run 2 rollouts: the job appears queued or running with its progress, then finishes
    page.fill("#rollouts", "2")
    page.fill("#seed", "3")
    jobs_before = site.job_ids()
    page.click("#run")
    job = page.locator("#jobs .job").first
    expect(job.locator(".status-badge")).to_have_text(re.compile("queued|running|done"))
    assert len(site.job_ids()) == len(jobs_before) + 1
    v.shot("3-job-started", "#scene-canvas")
    page.locator("#prompt-0").fill(f"@{agent['id']} slows down gently")  # the page stays usable meanwhile
    wait_done(page, 1)
    v.shot("4-job-done", "#scene-canvas")

    # watch: the replay, one large view with the other rollouts (and the unprompted run's) as thumbnails
    job.locator("button.open").click()
    expect(page.locator("#replay")).to_be_visible()
    canvases = page.locator("#replay-grid canvas")
    expect(canvases).to_have_count(4)  # 2 rollouts x (prompted, unprompted): 1 large, 3 thumbnails
    expect(page.locator("#replay-grid .thumbs canvas")).to_have_count(3)
    main = "#replay-grid .main-view canvas"
    expect(page.locator("#step-info")).to_contain_text("logged history")
    start_frame = canvas_png(page, main)
    page.evaluate("() => { window.studioStats.frames = []; }")
    page.click("#play")
    page.wait_for_timeout(2000)
    page.click("#play")
    frames = page.evaluate("() => window.studioStats.frames")
    intervals = [b - a for a, b in itertools.pairwise(frames)]
    assert len(intervals) >= 10, f"too few frames drawn in 2 s: {len(frames)}"
    median = statistics.median(intervals)
    result = site.get(f"/api/jobs/{site.job_ids()[0]}")["result"]
    agents = len(result["runs"]["prompted"]["rollouts"][0]["x"])
    assert agents >= 32, agents
    print(f"replay of {agents} agents x 4 panels: {len(frames)} frames in 2 s, median interval {median:.1f} ms")
    assert median < MEDIAN_FRAME_MS, f"median frame interval {median:.1f} ms"
    expect(page.locator("#step-info")).to_contain_text("simulated step")
    assert canvas_png(page, main) != start_frame  # the agents moved
    v.shot("5-replay-playing", "#replay-grid canvas", "#replay-plots canvas")

    # scrub by keyboard: the first and the last step
    page.focus("#scrub")
    page.keyboard.press("Home")
    expect(page.locator("#step-info")).to_contain_text("logged history, step 1 of")
    page.keyboard.press("End")
    expect(page.locator("#step-info")).to_contain_text("simulated step 80 of 80")
    v.shot("6-replay-end", "#replay-grid canvas")
    v.doc_shots()
    plots_follow_the_replay(page, result, str(agent["id"]))

    # a thumbnail clicked is the large view; the rollout list picks one too; all side by side shows every panel
    page.locator('#replay-grid .thumbs button[data-pick="1:0"]').click()
    expect(page.locator("#replay-grid .main-view figcaption")).to_have_text("without prompts · rollout 1")
    assert page.evaluate("() => window.studio.replayView()")["run"] == "unprompted"
    page.select_option("#layout", "all")
    expect(page.locator("#replay-grid .thumbs")).to_have_count(0)
    expect(canvases).to_have_count(4)
    page.select_option("#layout", "focus")
    page.select_option("#which-rollout", "0:1")
    expect(page.locator("#replay-grid .main-view figcaption")).to_have_text("with the prompts · rollout 2")
    expect(canvases).to_have_count(4)

    # zoom, pan and follow (every panel together), and the ego first in the Follow list
    fitted = page.evaluate("() => window.studio.replayView()")
    box = page.locator(main).bounding_box()
    assert box is not None
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.wheel(0, -200)
    zoomed = page.evaluate("() => window.studio.replayView()")
    assert zoomed["s"] == pytest.approx(fitted["s"] * 1.25, rel=1e-6)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2 + 50, box["y"] + box["height"] / 2)
    page.mouse.up()
    panned = page.evaluate("() => window.studio.replayView()")
    assert panned["cx"] == pytest.approx(zoomed["cx"] - 50 / zoomed["s"], abs=1e-6)
    follow = page.locator("#follow option").nth(1)
    expect(follow).to_contain_text("(ego)")
    ego = int(follow.get_attribute("value") or "0")
    page.select_option("#follow", str(ego))
    page.focus("#scrub")
    page.keyboard.press("End")
    followed = page.evaluate("() => window.studio.replayView()")
    watched = result["runs"]["prompted"]["rollouts"][1]  # the large view shows rollout 2
    assert (followed["cx"], followed["cy"]) == (
        pytest.approx(watched["x"][str(ego)][-1], abs=0.01),
        pytest.approx(watched["y"][str(ego)][-1], abs=0.01),
    )
    v.shot("6b-follow-ego", "#replay-grid canvas")
    page.click("#replay-fit")
    assert page.evaluate("() => window.studio.replayView()")["s"] == pytest.approx(fitted["s"], rel=1e-6)

    # judge: followed or not per rollout, the base rate, the realism figures
    table = page.locator("#followed-table")
    row = table.locator("tbody tr").first
    expect(row.locator("th")).to_have_text(f"@{agent['id']} slows down")
    verdicts = row.locator("td").all_text_contents()[1:3]
    assert all(t in ("followed", "not followed") for t in verdicts), verdicts
    expect(row.locator("td").last).to_contain_text(re.compile(r"\d+ of \d+|not judged"))
    expect(page.locator("#realism-table")).to_contain_text("meta metric")
    expect(page.locator(".events-table").first.locator("tbody")).to_contain_text(f"@{agent['id']}")
    events_agree(page, result)
    v.shot("7-results", "#replay-grid canvas")

    # keep: save the case, the suite file holds it; the downloads are there
    page.fill("#case-suite", "studio-e2e")
    page.fill("#case-name", "slows-down")
    page.fill("#case-ttc", "0.5")
    page.check("#case-nocollision")
    page.locator("#case-form button[type=submit]").click()
    expect(page.locator("#case-result")).to_contain_text("slows-down")
    saved = page.locator("#case-result").inner_text()
    suite_file = site.data / "suites" / "studio-e2e.yaml"
    assert suite_file.is_file(), f"no {suite_file} ({saved})"
    text = suite_file.read_text()
    assert "slows-down" in text and f"@{agent['id']} slows down" in text, text[:2000]
    assert "min_ttc" in text and "no_collision" in text, text[:2000]
    page.locator("#case-form button[type=submit]").click()  # the same name again: the server's error, in the page
    expect(page.locator("#case-error")).to_contain_text("slows-down")
    expect(page.locator("#case-result")).to_contain_text("--planner idm")
    npz = page.request.get(site.url + (page.locator("#dl-npz").get_attribute("href") or ""))
    assert npz.ok and npz.body()[:2] == b"PK", npz.status
    watched_file = site.data / "watched.npz"
    watched_file.write_bytes(npz.body())
    followed = result["runs"]["prompted"]["prompts"][0]["followed"][0]
    replays_watched(suite_file, Rollouts.load(watched_file), site.data / "replay", followed)
    assert (page.locator("#dl-video").get_attribute("href") or "").endswith("/video.mp4")
    v.shot("8-saved", "#replay-grid canvas")
    v.check_clean()
    page.context.close()


def events_agree(page: Page, result: dict[str, Any]) -> None:
    """The page's events are the job's: every contact and off-road of the prompted run is a tick on the scrubber
    (a contact labelled with its partner); WOSAC's collision rate shown equals the events table's own count over
    the agents WOSAC scores; an event's button shows its run and rollout at its moment in the large view."""
    prompted = result["runs"]["prompted"]
    hist = result["start_step"] + 1
    ticks = page.locator("#scrub-events option")
    wanted = sorted(
        [
            (hist + c["step"], f"@{a['id']} × @{c['with']}, rollout {c['rollout'] + 1}")
            for a in prompted["agents"]
            for c in a["collisions"]
        ]
        + [
            (hist + o["step"], f"@{a['id']} off-road, rollout {o['rollout'] + 1}")
            for a in prompted["agents"]
            for o in a["offroads"]
        ]
    )
    shown = sorted((int(t.get_attribute("value") or -1), t.get_attribute("label") or "") for t in ticks.all())
    assert shown == wanted
    table = page.locator('.events-table[data-run="prompted"]')
    n = len(prompted["rollouts"])
    rows = [r for r in table.locator("tbody tr").all() if r.locator("th").count()]
    scored = [r for r in rows if not (r.locator("th").inner_text()).endswith("·")]
    hits = sum("collision with" in c for r in scored for c in r.locator("td").all_text_contents())
    evaluated = prompted["realism"]["evaluated"]
    wosac = page.locator("#realism-table tr", has_text="collision rate").first.locator("td").first.inner_text()
    # shown to 3 decimals: within half a unit of the last, inclusive (1 hit of 16 is 0.0625, shown as 0.063)
    assert float(wosac) == pytest.approx(hits / (evaluated * n), abs=5e-4 + 1e-9), (wosac, hits, evaluated, n)
    jumps = page.locator(".events-table button.event-jump")
    assert jumps.count() > 0, "no collision or off-road in the job to jump to"
    jump = jumps.last
    run, k, step = (jump.get_attribute(a) for a in ("data-run", "data-rollout", "data-step"))
    jump.click()
    view = page.evaluate("() => window.studio.replayView()")
    assert (view["run"], view["rollout"], view["step"]) == (run, int(k or 0), hist + int(step or 0))


def plots_follow_the_replay(page: Page, result: dict[str, Any], agent: str) -> None:
    """The prompted agent's plots show the job's own series: at the last step the cursor reads the large view's
    rollout's value; a click on a plot moves the replay to that time."""
    series = result["runs"]["prompted"]["series"][agent]
    expect(page.locator(f'#replay-plots canvas[data-agent="{agent}"][data-quantity="speed"]')).to_be_visible()
    quantities = ["speed"] + (["to_target"] if series["to_target"] else [])
    expect(page.locator(f'#replay-plots canvas[data-agent="{agent}"]')).to_have_count(len(quantities))
    for key in quantities:
        shown = page.evaluate(f"() => window.studio.plotValue({agent}, '{key}')")
        assert shown == pytest.approx(series[key][0][-1], abs=1e-9), (key, shown)
    plot = page.locator(f'#replay-plots canvas[data-agent="{agent}"][data-quantity="speed"]')
    box = plot.bounding_box()
    assert box is not None
    plot.click(position={"x": box["width"] * 0.75, "y": box["height"] / 2})
    step = page.evaluate("() => window.studio.replayView()")["step"]
    total = page.evaluate("() => window.studio.replayFrames")
    assert 0.55 * total < step < 0.85 * total, (step, total)
    expect(page.locator("#step-info")).to_contain_text("simulated step")


def find_infeasible(site: Site, key: str, scene: dict[str, Any]) -> tuple[str, str]:
    """A prompt the map rules out in this scene (read, runnable with a warning, as `simulate` runs it), and its
    warning."""
    for agent in moving_vehicles(scene):
        asks = [f"@{agent['id']} {ask}" for ask in INFEASIBLE_ASKS]
        checks = [site.post(f"/api/scenes/{key}/prompts", {"prompts": [t]})["prompts"][0] for t in asks]
        for text, check in zip(asks, checks, strict=True):
            if check["ok"] and check["feasible"] is False and check["warning"]:
                return text, check["warning"]
    raise AssertionError("no prompt the map rules out found in the scene")


def clause_by_clause(v: Visit, slower: int, infeasible: str, warning: str, three: list[int]) -> None:
    """A prompt of two clauses shows both readings, the one the map rules out with its warning, none dropped; a
    prompt naming three agents before one verb reads as each of them doing it, one line each."""
    page = v.page
    set_prompt(v, f"@{slower} slows down. {infeasible}.")
    clauses = page.locator("#reading-0 .clauses li")
    expect(clauses).to_have_count(2)
    expect(clauses.nth(0)).to_contain_text(f"read as: @{slower} slow_down")
    expect(clauses.nth(1)).to_have_attribute("data-clause", infeasible)
    expect(clauses.nth(1)).to_contain_text(f"read as: {infeasible.split()[0]} ")
    expect(page.locator("#reading-0 .pill")).to_have_text("the map rules it out")
    expect(page.locator("#reading-0")).to_contain_text(warning)
    set_prompt(v, " ".join(f"@{i}" for i in three) + " stop")
    expect(clauses).to_have_count(3)
    for k, i in enumerate(three):
        expect(clauses.nth(k)).to_contain_text(f"read as: @{i} stop")
    expect(page.locator("#reading-0 .pill")).to_have_text("feasible")


def replays_watched(suite_file: Path, watched: Rollouts, out: Path, followed: bool) -> None:
    """The kept case run as `langtraj test --planner idm` runs it (its first seed, one process) gives the rollout
    the page showed, to 1e-4 m, and judges its prompt as the page did (`followed`: its "prompt followed" verdict,
    without which a suite reports the scenario as not happened)."""
    from langtraj.suites.config import load_suite
    from langtraj.suites.episode import EpisodeTask, run_episode

    (case,) = load_suite(suite_file).cases
    kept: list[Rollouts] = []
    task = EpisodeTask("e2e", case, case.seeds[0], "idm", None, 10.0, out, video=False)
    result = run_episode(task, lambda env: kept.append(env.rollout()))
    assert result.status != "error", result.reasons
    (replayed,) = kept
    assert list(replayed.object_id) == list(watched.object_id)
    gap = max(np.abs(replayed.x[0] - watched.x[0]).max(), np.abs(replayed.y[0] - watched.y[0]).max())
    assert gap < 1e-4, f"the kept case replays rollout 0 {gap:.2e} m away"
    assert [p["followed"] for p in result.prompts] == [followed], result.prompts
    if not followed:  # a case whose scenario did not happen never passes
        assert result.status != "pass", (result.status, result.reasons)
    else:
        assert result.status != "not_happened", (result.status, result.reasons)


def test_bad_prompts_show_a_message_and_start_no_job(site: Site, browser: Browser) -> None:
    key = site.scene_key(SCENE_ID)
    scene = site.get(f"/api/scenes/{key}")
    infeasible, warning = find_infeasible(site, key, scene)
    known = moving_vehicles(scene)[0]["id"]
    v = visit(browser, site, "bad", f"#scene={key}")
    page = v.page
    expect(page.locator("#scene-title")).to_contain_text(SCENE_ID)  # the scene of the address
    jobs = site.job_ids()
    set_prompt(v, infeasible)  # runnable, with the map's warning: a suite reports it as not happened
    expect(page.locator("#reading-0 .pill")).to_have_text("the map rules it out")
    expect(page.locator("#reading-0")).to_contain_text(warning)
    other = moving_vehicles(scene)[1]["id"]
    movers = [a["id"] for a in moving_vehicles(scene)]
    slower = next(i for i in movers if f"@{i}" != infeasible.split()[0])  # one behaviour per agent
    clause_by_clause(v, slower, infeasible, warning, movers[:3])
    ego = next(a["id"] for a in scene["agents"] if a["sdc"])
    cases = [
        ("ego", f"@{ego} slows down", "asks something of the ego, which the planner drives"),
        ("unknown", "@987654 slows down", "987654"),
        ("typo", f"@{known} yeilds to @{other}", f"did you mean '@{known} yields to @{other}'?"),
        ("self", f"@{known} yields to @{known}", f"names @{known} twice"),
        ("empty", "   ", "Prompt 1 is empty"),
        ("long", f"@{known} slows down " + "x" * (10_000 - len(f"@{known} slows down ")), "10000 characters"),
    ]
    for name, text, message in cases:
        set_prompt(v, text)
        assert len(page.locator("#prompt-0").input_value()) == len(text)
        page.click("#run")
        error = page.locator("#run-error")
        expect(error).to_be_visible()
        expect(error).to_contain_text(message)
        if name in ("ego", "unknown", "long", "typo", "self"):
            expect(page.locator("#reading-0 .pill")).to_have_text("cannot run")
        v.shot(f"{name}", "#scene-canvas")
        assert site.job_ids() == jobs, f"{name}: a job was created"
    expect(page.locator("#jobs .job")).to_have_count(len(jobs))
    v.check_clean()
    page.context.close()


@pytest.mark.slow  # about 40 s: two real jobs
def test_two_tabs_each_start_a_job_and_reload_shows_them(site: Site, browser: Browser) -> None:
    key = site.scene_key(SMALL_SCENE_ID)
    scene = site.get(f"/api/scenes/{key}")
    movers = moving_vehicles(scene)
    assert len(movers) >= 2, f"{SMALL_SCENE_ID}: fewer than two moving sim vehicles"
    ids = [a["id"] for a in movers[:2]]
    context = new_context(browser)  # two tabs of one browser window
    tabs = []
    before = len(site.job_ids())
    for k, agent in enumerate(ids):
        v = visit(browser, site, f"tab{k + 1}", f"#scene={key}", context)
        expect(v.page.locator("#scene-title")).to_contain_text(SMALL_SCENE_ID)
        tabs.append(v)
        set_prompt(v, f"@{agent} slows down")
        v.page.fill("#rollouts", "1")
        v.page.uncheck("#compare")
        v.page.click("#run")
        expect(v.page.locator("#jobs .job", has_text=f"@{agent} slows down")).to_have_count(1)
        expect(v.page.locator("#run-error")).to_be_hidden()
    assert len(site.job_ids()) == before + 2
    for v in tabs:  # each tab lists both jobs (the other tab's by polling) and sees both finish
        expect(v.page.locator("#jobs .job")).to_have_count(before + 2, timeout=10_000)
        wait_done(v.page, 2)
        v.shot("done", "#scene-canvas")
    page = tabs[0].page
    page.reload()
    expect(page.locator("#jobs .job")).to_have_count(before + 2)
    expect(page.locator("#jobs .job .status-badge")).to_have_text(["done"] * (before + 2))
    expect(page.locator("#jobs .job").first).to_contain_text(f"@{ids[1]} slows down")
    expect(page.locator("#prompt-0")).to_have_value(f"@{ids[0]} slows down")  # the tab's prompts are kept
    tabs[0].shot("reloaded", "#scene-canvas")
    for v in tabs:
        v.check_clean()
    context.close()


def test_a_scene_switch_clears_the_old_prompts_and_a_fixed_cause_its_error(site: Site, browser: Browser) -> None:
    """@ids name agents of one scene: typed on one and carried to another they would steer other agents (or none);
    a refused run's message goes once its cause is fixed."""
    key = site.scene_key(SCENE_ID)
    known = moving_vehicles(site.get(f"/api/scenes/{key}"))[0]["id"]
    v = visit(browser, site, "switch")
    page = v.page
    open_scene(v, SCENE_ID)
    set_prompt(v, "@987654 slows down")
    page.click("#run")
    expect(page.locator("#run-error")).to_contain_text("987654")
    set_prompt(v, f"@{known} slows down")
    expect(page.locator("#run-error")).to_be_hidden()
    open_scene(v, WOMD_SCENE_ID)
    expect(page.locator("#prompt-0")).to_have_value("")
    expect(page.locator("#prompts textarea")).to_have_count(1)
    v.check_clean()
    page.context.close()


def test_a_nuscenes_job_says_what_offroad_is_measured_against(site: Site, browser: Browser) -> None:
    """nuScenes maps have no road edges: the page says off-road is measured against edges derived from the lanes;
    where a map has neither (the same job's answer with `road_edges` null, as the server sends it for such a map),
    every cell and rate says "not measured" rather than "clear"."""
    key = site.scene_key(SMALL_SCENE_ID)
    agent = moving_vehicles(site.get(f"/api/scenes/{key}"))[0]["id"]
    v = visit(browser, site, "nuscenes", f"#scene={key}")
    page = v.page
    set_prompt(v, f"@{agent} slows down")
    page.fill("#rollouts", "1")
    page.uncheck("#compare")
    before = len(site.job_ids())
    page.click("#run")
    expect(page.locator("#jobs .job")).to_have_count(before + 1)
    wait_done(page, 1)
    job_id = site.job_ids()[0]
    result = site.get(f"/api/jobs/{job_id}")["result"]
    assert result["runs"]["prompted"]["road_edges"].startswith("derived from")
    page.locator("#jobs .job").first.locator("button.open").click()
    expect(page.locator(".events-note").first).to_contain_text("measured against road edges derived from")
    expect(page.locator(".events-table").first).not_to_contain_text("not measured")

    def bare(route: Any) -> None:  # the job as the server answers it for a map with no edges and no lanes
        job = site.get(f"/api/jobs/{job_id}")
        run = job["result"]["runs"]["prompted"]
        run["road_edges"] = None
        run["rates"]["offroad_all"] = run["rates"]["offroad_evaluated"] = None
        for a in run["agents"]:
            a["offroad"], a["offroads"] = [None] * len(a["offroad"]), []
        route.fulfill(json=job)

    page.route(f"**/api/jobs/{job_id}", bare)
    page.locator("#jobs .job").first.locator("button.open").click()
    expect(page.locator(".events-note").first).to_contain_text("Off-road is not measured: this map has no road edges.")
    expect(page.locator(".events-table").first.locator("tbody")).to_contain_text("off-road not measured")
    expect(page.locator(".events-table").first.locator("tbody")).not_to_contain_text("clear")
    row = page.locator("#realism-table tr", has_text="off-road rate, every vehicle measured")
    expect(row.locator("td").first).to_have_text("not measured")
    v.check_clean()
    page.context.close()
