"""'What this scene can stage' in a real browser (Playwright driving Debian's Chromium against the real app over the
shipped real scenes, as tests/studio/test_browser.py; skipped with the reason without them): pick the Waymo scene
8a34, see the list for the planner's ego, pick another ego and the ego again, see the list the API gives in its
order, filter it by behaviour, click a staging: its prompt (the ego by @id) is in the prompt box and read, and its
agent outlined; a typed prompt is never overwritten. Set LANGTRAJ_SCREENSHOTS to a folder to keep screenshots."""

from __future__ import annotations

import base64
import io
import json
import os
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from browser_harness import chromium, serve

from langtraj.studio.app import StudioConfig, create_app
from langtraj.studio.catalog import Catalog

try:
    import numpy as np
    from PIL import Image
    from playwright.sync_api import Browser, Page, expect
except ImportError as exc:
    pytest.skip(f"the browser tests need pillow: {exc}", allow_module_level=True)

SCENE_ID = "8a346109094cd5aa"  # WOMD: its self-driving car faces cut-ins and braking leads
EGO = 1101
SCREENSHOTS = os.environ.get("LANGTRAJ_SCREENSHOTS")
TARGET_RGB = np.array([224, 27, 143])  # the prompt target's and staged agent's colour (#e01b8f)


@pytest.fixture(scope="module")
def site(catalog: Catalog, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The real app over the real scenes (no job runs here: the worker is not started), served by uvicorn."""
    data = tmp_path_factory.mktemp("studio-stagings-browser") / "data"
    with serve(create_app(StudioConfig((), data=data), catalog, start_worker=False), "/api/jobs") as url:
        yield url


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as browser:
        yield browser


def get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=60) as response:
        return json.loads(response.read())


def shot(page: Page, step: str) -> None:
    if SCREENSHOTS:
        Path(SCREENSHOTS).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(SCREENSHOTS) / f"stagings-{step}.png"), full_page=True)


def target_pixels_near(page: Page, point: dict[str, float], radius: int = 40) -> int:
    """How many pixels of the scene canvas within `radius` CSS pixels of `point` (client pixels) have the target's
    colour."""
    canvas = page.locator("#scene-canvas")
    url = canvas.evaluate("c => c.toDataURL('image/png')")
    rgb = np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB")).astype(int)
    box = canvas.bounding_box()
    assert box is not None
    scale = rgb.shape[1] / box["width"]  # device pixels per CSS pixel
    cx, cy = (point["x"] - box["x"]) * scale, (point["y"] - box["y"]) * scale
    r = int(radius * scale)
    patch = rgb[max(0, int(cy) - r) : int(cy) + r, max(0, int(cx) - r) : int(cx) + r]
    return int((np.abs(patch - TARGET_RGB).sum(axis=2) < 40).sum())


def items(page: Page) -> list[tuple[str, str]]:
    """(behaviour, agent) of each staging listed, in the page's order."""
    buttons = page.locator("#stagings button.staging")
    return [(b.get_attribute("data-behaviour") or "", b.get_attribute("data-agent") or "") for b in buttons.all()]


def test_pick_the_ego_see_what_it_can_stage_and_write_one(site: str, browser: Browser) -> None:
    context = browser.new_context(viewport={"width": 1400, "height": 950})
    page = context.new_page()
    page.set_default_timeout(30_000)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(f"{site}/")
    page.fill("#scene-search", SCENE_ID)
    expect(page.locator("#scene-list button.scene")).to_have_count(1)
    page.locator("#scene-list button.scene").click()
    expect(page.locator("#scene-title")).to_contain_text(SCENE_ID)
    key = next(s["key"] for s in get(f"{site}/api/scenes?q={SCENE_ID}")["scenes"])
    expected = get(f"{site}/api/scenes/{key}/stagings?ego={EGO}")["stagings"]
    wanted = [(s["behaviour"], str(s["agent"])) for s in expected]

    # the planner's ego (the self-driving car) first; another ego gets its own list, and the ego again its own
    expect(page.locator("#staging-count")).to_contain_text(f"against @{EGO}")
    expect(page.locator("#staging-ego")).to_have_value(str(EGO))
    other = next(a for _, a in wanted)
    page.select_option("#staging-ego", other)
    expect(page.locator("#staging-count")).to_contain_text(f"@{other}")
    page.select_option("#staging-ego", str(EGO))
    expect(page.locator("#staging-count")).to_contain_text(f"{len(expected)} stagings against @{EGO}")
    assert items(page) == wanted
    first = page.locator("#stagings button.staging").first
    expect(first).to_contain_text(expected[0]["reason"])
    shot(page, "1-list")

    # filtered by behaviour: the braking leads only, in the list's order
    page.select_option("#staging-behaviour", "brake_hard")
    assert items(page) == [w for w in wanted if w[0] == "brake_hard"] != []
    expect(page.locator("#stagings")).to_contain_text("4 m/s²")
    page.select_option("#staging-behaviour", "")

    # click a cut-in: its prompt, the ego named by its @id, is in the prompt box and read; its agent outlined
    k = next(i for i, s in enumerate(expected) if s["behaviour"] == "cut_in" and s["parameters"]["gap"] == 10)
    staging = expected[k]
    agent = staging["agent"]
    point = page.evaluate(f"() => window.studio.agentPoint({agent})")
    before = target_pixels_near(page, point)
    button = page.locator(f'#stagings button.staging[data-index="{k}"]')
    expect(button).to_contain_text("10 m gap")
    button.click()
    assert staging["typed_prompt"] == f"@{agent} cuts in front of @{EGO} with a 10 m gap"
    expect(page.locator("#prompt-0")).to_have_value(staging["typed_prompt"])
    expect(button).to_have_attribute("aria-pressed", "true")
    expect(page.locator("#reading-0")).to_contain_text(f"read as: @{agent} cut_in @{EGO}")
    expect(page.locator("#reading-0 .pill")).to_have_text("feasible")
    deadline = time.monotonic() + 5  # redrawn on the next animation frame
    while target_pixels_near(page, point) <= before + 20:
        assert time.monotonic() < deadline, "the staging's agent is not outlined"
        page.wait_for_timeout(100)
    shot(page, "2-staged")

    # another staging replaces the one written; a typed prompt is kept and the staging goes into a new box
    brake = next(s for s in expected if s["behaviour"] == "brake_hard")
    page.locator("#stagings button.staging", has_text="brake hard").first.click()
    expect(page.locator("#prompt-0")).to_have_value(brake["typed_prompt"])
    expect(page.locator("#prompts textarea")).to_have_count(1)
    page.locator("#prompt-0").fill(f"@{brake['agent']} slows down")
    page.locator(f'#stagings button.staging[data-index="{k}"]').click()
    expect(page.locator("#prompt-0")).to_have_value(f"@{brake['agent']} slows down")
    expect(page.locator("#prompt-1")).to_have_value(staging["typed_prompt"])
    assert errors == [], errors
    context.close()
