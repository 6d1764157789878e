"""The run page in a real headless browser (Debian's chromium, driven by Playwright).

The page of a run with contacts is opened from ``file://``: it must load with
no console error, and the scenario picture, the video and both plots must be
decoded, have a size, and come into the viewport when scrolled to.  A
full-page screenshot is kept: in the test's tmp dir and as
``tests/artifacts/run-page.png`` (ignored by git); its path is printed.
Without chromium or Playwright the test is skipped, and says why; with
``SWARMFORM_REQUIRE_BROWSER=1`` (set by ``.ci/run``) it fails instead.
"""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = Path("/usr/bin/chromium")
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ARTIFACTS = ROOT / "tests" / "artifacts"

PARTS = ("#scenario img", "#video img", "#plot-clearance img", "#plot-tracking img")


def _browser_or_skip():
    """Playwright's entry point; a skip saying why when there is no browser (a failure in CI)."""
    why = None
    if not CHROMIUM.is_file():
        why = f"no browser: {CHROMIUM} is missing (Debian: apt-get install chromium; .ci/run does it)"
    else:
        try:
            from playwright.sync_api import sync_playwright
        except ImportError:
            why = "no browser driver: the playwright package is not installed (it is in the dev extra)"
    if why is None:
        return sync_playwright
    if os.environ.get("SWARMFORM_REQUIRE_BROWSER") == "1":
        pytest.fail(why + "; SWARMFORM_REQUIRE_BROWSER=1 asks for the browser test to run")
    pytest.skip(why)


def _page_with_contacts(tmp_path) -> Path:
    """``swarmform run --plan`` of a plan built to collide (two robots swap places)."""
    from planner import Plan
    from sim.runner import run_scenario
    from sim.scenario import build_problem, read_scenario

    scen = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
    sc = read_scenario(scen)
    problem = build_problem(sc, np.random.default_rng(sc.seed))
    mid = problem.start.copy()
    mid[[0, 1]] = problem.start[[1, 0]]
    plan_path = tmp_path / "swap.json"
    Plan.from_waypoints(np.stack([problem.start, mid]), problem.radius, problem.margin, 2.0, 2.0).save(
        plan_path, extra={"seed": sc.seed})
    result = run_scenario(scen, plan_path=plan_path, out_dir=tmp_path, out=None)
    assert result.exit_code == 1 and result.report["sim"]["contacts"] > 0
    return Path(result.report["page"])


def _check(page, errors) -> dict:
    page.wait_for_load_state("load")
    found = {}
    for sel in PARTS:
        el = page.locator(sel)
        assert el.count() == 1, sel
        el.scroll_into_view_if_needed()
        box = el.bounding_box()
        state = el.evaluate(
            """e => { const r = e.getBoundingClientRect();
                      return {complete: e.complete, w: e.naturalWidth, h: e.naturalHeight,
                              inView: r.bottom > 0 && r.right > 0 && r.top < innerHeight && r.left < innerWidth,
                              shown: getComputedStyle(e).visibility !== 'hidden' && e.offsetParent !== null}; }"""
        )
        found[sel] = (box, state)
    return found


def test_run_page_in_a_headless_browser(tmp_path):
    sync_playwright = _browser_or_skip()
    html = _page_with_contacts(tmp_path)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            errors = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("requestfailed", lambda r: errors.append(f"request failed: {r.url}"))
            page.goto(html.as_uri())
            found = _check(page, errors)
            assert page.locator("#verdict").inner_text().startswith("FAILED:")
            assert page.locator("#contacts tr.first").count() == 1
            shot = tmp_path / "run-page.png"
            page.screenshot(path=str(shot), full_page=True)

            # negative control: the same checks see a broken picture and a script error
            broken = tmp_path / "broken.html"
            broken.write_text(html.read_text(encoding="utf-8").replace('src="data:image/png;base64,', 'src="x', 1)
                              .replace("</body>", "<script>undefined_function()</script></body>"),
                              encoding="utf-8")
            page2 = browser.new_page()
            errors2 = []
            page2.on("console", lambda m: errors2.append(m.text) if m.type == "error" else None)
            page2.on("pageerror", lambda e: errors2.append(str(e)))
            page2.goto(broken.as_uri())
            bad = _check(page2, errors2)
            assert errors2
            assert bad["#scenario img"][1]["w"] == 0
        finally:
            browser.close()
    assert errors == []
    for sel, (box, state) in found.items():
        assert box is not None and box["width"] > 50 and box["height"] > 50, (sel, box)
        assert state["complete"] and state["w"] > 0 and state["h"] > 0, (sel, state)
        assert state["inView"] and state["shown"], (sel, state)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    kept = ARTIFACTS / "run-page.png"
    shutil.copyfile(shot, kept)
    print(f"\nrun page screenshot: {kept} (and {shot})")


def test_without_a_browser_the_test_says_why(monkeypatch):
    import sys

    me = sys.modules[__name__]
    monkeypatch.setattr(me, "CHROMIUM", Path("/nonexistent/chromium"))
    monkeypatch.delenv("SWARMFORM_REQUIRE_BROWSER", raising=False)
    with pytest.raises(pytest.skip.Exception, match="no browser: /nonexistent/chromium is missing"):
        _browser_or_skip()
    monkeypatch.setenv("SWARMFORM_REQUIRE_BROWSER", "1")
    with pytest.raises(pytest.fail.Exception, match="asks for the browser test to run"):
        _browser_or_skip()
