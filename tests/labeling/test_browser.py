"""The labeling page in a real browser: Playwright drives Debian's Chromium against the real app (uvicorn on
a free port). Two annotators label one window and disagree (one by keyboard alone, one clicking an agent in
the video), free text full of markup stays text, a reviewer accepts by keyboard, the admin exports the labels
into the dataset. Set LANGTRAJ_SCREENSHOTS to a folder to keep a screenshot of every step.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from langtraj.interdrive.dataset import iter_records
from langtraj.interdrive.labels import LabelSource
from langtraj.interdrive.taxonomy import InteractionType, subtypes_of
from langtraj.labeling.app import ServerConfig, create_app
from langtraj.labeling.db import Database
from langtraj.labeling.media import nearest_agent
from langtraj.labeling.models import Role
from langtraj.labeling.tasks import add_tasks

try:
    from .builders import PASSWORD, SUGGESTED, add_user, make_label_dataset
except ImportError:  # tests/labeling without __init__.py is itself on sys.path
    from builders import PASSWORD, SUGGESTED, add_user, make_label_dataset  # type: ignore[no-redef]

from browser_harness import chromium, serve
from playwright.sync_api import Browser, Page, expect

USERS = {"ann1": Role.ANNOTATOR, "ann2": Role.ANNOTATOR, "rev": Role.REVIEWER, "admin": Role.ADMIN}
XSS = "<img src=x onerror=alert(1)><script>window.pwned=1</script>"
KINDS = [k.value for k in InteractionType]  # the page's type keys: 1..7 in taxonomy order, 0 for No interaction
SCREENSHOTS = os.environ.get("LANGTRAJ_SCREENSHOTS")


def type_key(kind: str) -> str:
    return str(KINDS.index(kind) + 1)


def subtype_key(subtype_id: str) -> str:
    kind = InteractionType(subtype_id.split("/")[0])
    return str([s.id for s in subtypes_of(kind)].index(subtype_id) + 1)


def subtype_name(subtype_id: str) -> str:
    kind = InteractionType(subtype_id.split("/")[0])
    return next(s.name for s in subtypes_of(kind) if s.id == subtype_id)


# ---------------------------------------------------------------- the server and the browser


@dataclass(frozen=True)
class Site:
    url: str
    dataset: Path


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    """The real app over a one-window dataset (two slots), served by uvicorn in a thread on a free port."""
    dataset = make_label_dataset(tmp_path_factory.mktemp("labeling-browser"), num_scenes=1)
    config = ServerConfig(dataset)
    db = Database(config.url)
    add_tasks(db, dataset, overlap=2)
    for name, role in USERS.items():
        add_user(db, name, role)
    with serve(create_app(config, db), "/healthz", lifespan="off") as url:
        yield Site(url, dataset)


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as browser:
        yield browser


@dataclass
class Visit:
    """One user's page in a fresh browser context, with what it reported: dialogs and script errors."""

    page: Page
    name: str
    dialogs: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def shot(self, step: str) -> None:
        if SCREENSHOTS:
            Path(SCREENSHOTS).mkdir(parents=True, exist_ok=True)
            self.page.screenshot(path=str(Path(SCREENSHOTS) / f"{self.name}-{step}.png"), full_page=True)

    def press(self, *keys: str) -> None:
        for key in keys:
            self.page.keyboard.press(key)

    def heading(self, text: str) -> None:
        expect(self.page.locator("#protocol h2")).to_have_text(text)

    def check_clean(self) -> None:
        assert self.dialogs == [], f"dialogs fired: {self.dialogs}"
        assert self.errors == [], f"script errors or CSP violations: {self.errors}"
        assert self.page.evaluate("() => window.pwned") is None


def visit(browser: Browser, site: Site, name: str, routes: dict[str, Callable[[Any], None]] | None = None) -> Visit:
    """A fresh context on the site's login page; `routes` (glob -> handler) are set on the context before its first
    request, as routes added to a live page once missed a request (CI, stop 52)."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    for pattern, handler in (routes or {}).items():
        context.route(pattern, handler)
    page = context.new_page()
    page.set_default_timeout(10_000)
    v = Visit(page, name)

    def on_dialog(dialog: Any) -> None:
        v.dialogs.append(dialog.message)
        dialog.dismiss()

    def on_console(message: Any) -> None:
        # "Failed to load resource" reports an HTTP error status (401 before login) or an aborted request
        if message.type == "error" and not message.text.startswith("Failed to load resource"):
            v.errors.append(message.text)

    page.on("dialog", on_dialog)
    page.on("console", on_console)
    page.on("pageerror", lambda error: v.errors.append(str(error)))
    page.goto(site.url)
    expect(page.locator("#login-name")).to_be_focused()
    return v


def keyboard_login(v: Visit) -> None:
    v.page.keyboard.type(v.name)
    v.press("Tab")
    v.page.keyboard.type(PASSWORD)
    v.press("Enter")
    expect(v.page.locator("#who-name")).to_contain_text(v.name)


def option(v: Visit, name: str) -> Any:
    return v.page.locator("#protocol .options button", has_text=name)


# ---------------------------------------------------------------- the test


def test_two_annotators_disagree_reviewer_accepts_admin_exports(site: Site, browser: Browser) -> None:
    label_keyboard_only(browser, site)
    label_with_video_click_and_free_text(browser, site)
    accepted = review_by_keyboard(browser, site)
    export_as_admin(browser, site)
    check_exported(site, accepted)


def label_keyboard_only(browser: Browser, site: Site) -> None:
    """ann1 labels the window with the keyboard alone; the first submit meets a network error and the page
    retries it with the same submission id. 7 passes 17, 17 yields (the detector's suggestion, kept)."""
    bodies: list[dict[str, Any]] = []

    def first_attempt_fails(route: Any) -> None:
        bodies.append(route.request.post_data_json)
        if len(bodies) == 1:
            route.abort("connectionreset")
        else:
            route.continue_()

    v = visit(browser, site, "ann1", routes={"**/api/slots/*/submit": first_attempt_fails})
    page = v.page
    v.shot("0-login")
    keyboard_login(v)
    expect(page.locator("#progress")).to_have_text("you: 0 done, overall: 0/2 slots, 0 windows accepted")
    v.press("n")
    v.heading("Step 1 of 3: which two agents interact?")
    for agent in (7, 17):  # objects of interest, pre-selected
        expect(page.locator(f"#agent-{agent}")).to_have_attribute("aria-pressed", "true")
    v.shot("1-pair")
    v.press("Enter")

    v.heading("Step 2 of 3: interaction type of @7 towards @17 (1 of 2)")
    expect(page.locator("#protocol .badge.machine")).to_have_count(0)
    v.press(type_key("passing"))
    expect(option(v, "Passing")).to_have_attribute("aria-pressed", "true")
    v.shot("2-type-7")
    v.press("Enter")

    v.heading("Step 2 of 3: interaction type of @17 towards @7 (2 of 2)")
    suggested = option(v, "Yielding")  # pre-filled from the detector, marked as such
    expect(suggested).to_have_attribute("aria-pressed", "true")
    badge = page.locator("#protocol .options li", has_text="Yielding").locator(".badge.machine")
    expect(badge).to_have_text("machine suggestion")
    v.shot("3-type-17-suggested")
    v.press("Enter")  # keep it

    v.heading("Step 3 of 3: subtype of @7 towards @17 (Passing)")
    v.press(subtype_key("passing/intersection_with_yielding"))
    v.press("Enter")
    v.heading("Step 3 of 3: subtype of @17 towards @7 (Yielding)")
    expect(option(v, subtype_name(SUGGESTED))).to_have_attribute("aria-pressed", "true")
    expect(page.locator("#protocol .options .badge.machine")).to_have_count(1)
    v.shot("4-subtype-17-suggested")
    v.press("Backspace")  # back one page: the earlier choice is still there
    v.heading("Step 3 of 3: subtype of @7 towards @17 (Passing)")
    expect(option(v, subtype_name("passing/intersection_with_yielding"))).to_have_attribute("aria-pressed", "true")
    v.press("Enter")
    expect(page.get_by_role("button", name=re.compile("Submit"))).to_be_visible()

    v.press("Enter")
    expect(page.locator("#protocol .idle")).to_contain_text("Submitted")
    v.shot("5-submitted")
    assert len(bodies) == 2, bodies
    first, retry = bodies
    assert first == retry  # the same submission id, labels and times
    assert re.fullmatch(r"[0-9a-f]{32}", first["submission_id"])
    assert first["pair"] == [7, 17]
    assert first["choices"] == [
        {"track_id": 7, "other_id": 17, "subtype": "passing/intersection_with_yielding", "text": ""},
        {"track_id": 17, "other_id": 7, "subtype": SUGGESTED, "text": ""},
    ]
    assert set(first["step_times_ms"]) == {"pair", "type", "subtype"}
    assert 0 < sum(first["step_times_ms"].values()) <= first["lead_time_ms"]
    expect(page.locator("#progress")).to_have_text("you: 1 done, overall: 1/2 slots, 0 windows accepted")
    v.press("n")  # the only window's other slot is for someone else
    expect(page.locator("#protocol .idle")).to_have_text("Nothing left to label for you right now.")
    v.check_clean()
    page.context.close()


def label_with_video_click_and_free_text(browser: Browser, site: Site) -> None:
    """ann2 picks agent 17 by clicking it in the video, says 7 does something undefined (free text full of
    markup) and 17 does not interact (changing the detector's suggestion)."""
    v = visit(browser, site, "ann2")
    page = v.page
    page.fill("#login-name", "ann2")
    page.fill("#login-password", "not the password")
    page.press("#login-password", "Enter")
    expect(page.locator("#error")).to_have_text("wrong name or password")  # the server's detail
    page.fill("#login-password", PASSWORD)
    page.press("#login-password", "Enter")
    expect(page.locator("#who-name")).to_contain_text("ann2")
    expect(page.locator("#error")).to_be_hidden()
    page.get_by_role("button", name=re.compile("Next task")).click()
    v.heading("Step 1 of 3: which two agents interact?")
    page.wait_for_function("() => document.getElementById('video').readyState >= 1")

    v.press("2")  # the second agent of the list, 17: deselect it
    expect(page.locator("#agent-17")).to_have_attribute("aria-pressed", "false")
    video_src = page.locator("#video").get_attribute("src")
    positions = page.request.get(f"{site.url}{video_src.replace('/video', '/positions')}").json()
    n = positions["size_px"]
    x, y = next(a["px"][0] for a in positions["agents"] if a["id"] == 17)
    assert nearest_agent(positions, 0, x, y) == 17
    box = page.locator("#video").bounding_box()
    assert box is not None and abs(box["width"] - box["height"]) < 1  # square, like the frames
    page.mouse.click(box["x"] + x * box["width"] / n, box["y"] + y * box["height"] / n)
    expect(page.locator("#agent-17")).to_have_attribute("aria-pressed", "true")
    expect(page.locator("#status")).to_have_text("@17 (pedestrian) selected.")
    assert page.evaluate("() => document.getElementById('video').paused")  # the click did not start playback
    v.shot("1-clicked-17")
    v.press("Enter")

    v.press(type_key("other"), "Enter")
    v.heading("Step 2 of 3: interaction type of @17 towards @7 (2 of 2)")
    expect(page.locator("#protocol .badge.machine")).not_to_have_count(0)
    v.press("0")  # No interaction: changes the suggestion, whose badge goes
    expect(option(v, "No interaction")).to_have_attribute("aria-pressed", "true")
    expect(page.locator("#protocol .badge.machine")).to_have_count(0)
    v.press("Enter")

    v.heading("Step 3 of 3: subtype of @7 towards @17 (Other)")
    v.press(subtype_key("other/undefined"))
    box_ = page.locator("#free-text")
    expect(box_).to_be_focused()
    v.press("Enter")  # the description is required
    expect(page.locator("#error")).to_have_text("Describe the undefined behaviour (required).")
    page.keyboard.type(XSS)  # digits and letters in it must not fire shortcuts
    expect(box_).to_have_value(XSS)
    v.heading("Step 3 of 3: subtype of @7 towards @17 (Other)")
    v.shot("2-free-text")
    with page.expect_request("**/api/slots/*/submit") as request:
        v.press("Enter")  # the last page: 17's subtype is set by No interaction
    body = request.value.post_data_json
    assert body["choices"] == [
        {"track_id": 7, "other_id": 17, "subtype": "other/undefined", "text": XSS},
        {"track_id": 17, "other_id": 7, "subtype": "other/no_interaction", "text": ""},
    ]
    expect(page.locator("#protocol .idle")).to_contain_text("Submitted")
    expect(page.locator("#progress")).to_have_text("you: 1 done, overall: 2/2 slots, 0 windows accepted")
    v.check_clean()
    page.context.close()


def review_by_keyboard(browser: Browser, site: Site) -> str:
    """rev sees the disagreement side by side, the free text as literal text, and accepts ann2's labels with
    its key; returns the accepted annotator."""
    v = visit(browser, site, "rev")
    page = v.page
    keyboard_login(v)
    windows = page.locator("#queue .window")
    expect(windows).to_have_count(1)
    expect(windows.locator("h3 code")).to_have_text("win-0")
    expect(windows.locator(".annotation h4")).to_have_text(["ann1", "ann2"])
    expect(windows.locator(".annotation").first).to_contain_text(subtype_name("passing/intersection_with_yielding"))
    expect(windows.locator(".free-text")).to_have_text(XSS)
    assert page.locator("#queue img, #queue script").count() == 0
    expect(page.locator("#agreement")).to_contain_text("disagreement")
    v.shot("1-queue")
    v.check_clean()
    v.press("2")
    expect(page.locator("#queue .idle")).to_have_text("No disagreements waiting for review.")
    expect(page.locator("#agreement tbody tr").first).to_contain_text("accepted (review)")
    expect(page.locator("#progress")).to_contain_text("1 windows accepted")
    v.shot("2-accepted")
    v.check_clean()
    page.context.close()
    return "ann2"


def export_as_admin(browser: Browser, site: Site) -> None:
    v = visit(browser, site, "admin")
    keyboard_login(v)
    v.press("e")
    result = v.page.locator("#export-result")
    expect(result.locator("dt:text-is('Files written') + dd")).to_have_text("1")
    expect(result.locator("dt:text-is('Windows imported') + dd")).to_have_text("1")
    v.shot("1-exported")
    v.check_clean()
    v.page.context.close()


def check_exported(site: Site, accepted_annotator: str) -> None:
    """The export's InterDrive JSON, the dataset's human labels and the audit hold what the page submitted."""
    out = site.dataset / "labeling-export"
    doc = json.loads((out / "interdrive" / "win-0.json").read_text())
    assert doc["agent_0"] == {
        "track_id": 7,
        "interact_with_other_agent": False,
        "interaction_type": "Other",
        "interaction_subtype": "Undefined behavior",
        "no_behavior_description": XSS,
    }
    assert doc["agent_1"]["track_id"] == 17
    assert doc["agent_1"]["interaction_subtype"] == "No interaction"

    records = [r for _, recs in iter_records(site.dataset) for r in recs if r.scenario_id == "win-0"]
    human = {
        (i.track_id, i.other_id): (i.subtype.id, i.text)
        for i in records[0].labels.interactions
        if i.source is LabelSource.HUMAN
    }
    assert human == {(7, 17): ("other/undefined", XSS), (17, 7): ("other/no_interaction", "")}

    audit = json.loads((out / "audit.json").read_text())
    (window,) = audit["windows"]
    assert window["accepted"]["method"] == "review"
    assert window["accepted"]["reviewer"] == "rev"
    by_name = {a["annotator"]: a for a in window["annotations"]}
    assert window["accepted"]["annotation_id"] == by_name[accepted_annotator]["annotation_id"]
    suggestion = {
        name: {(c["track_id"], c["other_id"]): (c["suggested"], c["suggestion"]) for c in a["choices"]}
        for name, a in by_name.items()
    }
    assert suggestion["ann1"] == {(7, 17): (None, None), (17, 7): (SUGGESTED, "kept")}
    assert suggestion["ann2"] == {(7, 17): (None, None), (17, 7): (SUGGESTED, "changed")}
    for a in by_name.values():
        assert set(a["step_times_ms"]) == {"pair", "type", "subtype"}
        assert a["lead_time_ms"] > 0
