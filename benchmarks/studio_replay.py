"""Median frame interval of the studio's replay while it plays, in Debian's Chromium (headless, Playwright): the issue's
target is at most 33 ms on the 257-agent Waymo scene. One job (IDM planner, --rollouts rollouts, compared with the
unprompted run, so twice as many panels) runs first through the real API (not timed); then the page opens it, plays
for --seconds in --layout (the large view and thumbnails, or every panel side by side), following the first agent
of the Follow list with --follow (the map redrawn every frame), and the frame timestamps `window.studioStats.frames`
give the intervals. --prompt adds a prompt (and so the prompted agent's plots, redrawn every frame). Repeated
--repeats times (the same job, the page reloaded), the median of the medians reported, and how long painting a
frame takes (`window.studioStats.paint`: the margin under the display's 16.7 ms, which caps the interval).

    python benchmarks/studio_replay.py [--scene 637f20cafde22ff8] [--rollouts 2] [--seconds 3] [--repeats 3]
        [--layout focus|all] [--follow] [--prompt "@1016 slows down"]
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import socket
import statistics
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

import uvicorn
from playwright.sync_api import sync_playwright

from langtraj.studio.app import StudioConfig, create_app

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
CHROMIUM = "/usr/bin/chromium"


def _call(url: str, body: dict | None = None) -> dict:
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url, data, {"content-type": "application/json"} if data else {})
    with urllib.request.urlopen(request, timeout=30) as response:
        return json.loads(response.read())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="637f20cafde22ff8", help="scenario id among ../shared/data/real")
    parser.add_argument("--rollouts", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--real-data", type=Path, default=REAL)
    parser.add_argument("--layout", choices=("focus", "all"), default="focus")
    parser.add_argument("--follow", action="store_true", help="follow the first agent of the Follow list")
    parser.add_argument("--prompt", default=None, help="a prompt for the job (its agent's plots are drawn too)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        app = create_app(StudioConfig((args.real_data,), data=Path(tmp)))
        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        url = f"http://127.0.0.1:{sock.getsockname()[1]}"
        server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
        threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True).start()
        time.sleep(2)
        try:
            scene = next(s for s in _call(f"{url}/api/scenes")["scenes"] if s["scenario_id"] == args.scene)
            job = _call(
                f"{url}/api/jobs",
                {
                    "scene": scene["key"],
                    "prompts": [args.prompt] if args.prompt else [],
                    "adversary": None,
                    "rollouts": args.rollouts,
                    "compare": bool(args.prompt),
                },
            )["job"]
            while (state := _call(f"{url}/api/jobs/{job['id']}"))["status"] in ("queued", "running"):
                time.sleep(1)
            if state["status"] != "done":
                raise SystemExit(f"the job {state['status']}: {state['error']}")
            medians: list[float] = []
            paints: list[float] = []
            with sync_playwright() as playwright:
                browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=["--no-sandbox"])
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                for _ in range(args.repeats):
                    page.goto(f"{url}/#job={job['id']}")
                    page.wait_for_selector("#replay-grid canvas")
                    page.select_option("#layout", args.layout)
                    if args.follow:
                        page.select_option("#follow", index=1)
                    page.evaluate("() => { window.studioStats.frames = []; window.studioStats.paint = []; }")
                    page.click("#play")
                    page.wait_for_timeout(args.seconds * 1000)
                    page.click("#play")
                    frames = page.evaluate("() => window.studioStats.frames")
                    medians.append(statistics.median(b - a for a, b in itertools.pairwise(frames)))
                    paints.extend(page.evaluate("() => window.studioStats.paint"))
                panels = page.locator("#replay-grid canvas").count()
                plots = page.locator("#replay-plots canvas").count()
                followed = page.evaluate("() => window.studio.replayView().follow")
                browser.close()
        finally:
            server.should_exit = True
    print(
        f"scene {args.scene} ({scene['agents']} agents, {scene['sim_agents']} simulated), {panels} panels "
        f"(layout {args.layout}), {plots} plots, following {('@' + followed) if followed else 'no agent'}"
    )
    print(
        f"median frame interval {statistics.median(medians):.1f} ms over {args.repeats} plays "
        f"({', '.join(f'{m:.1f}' for m in medians)}); target <= 33 ms"
    )
    p95 = statistics.quantiles(paints, n=20)[-1]
    print(
        f"painting a frame: median {statistics.median(paints):.2f} ms, "
        f"95th percentile {p95:.2f} ms ({len(paints)} frames)"
    )
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, headless Chromium")


if __name__ == "__main__":
    main()
