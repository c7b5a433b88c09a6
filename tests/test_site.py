"""The offline course website (``make site``) opens in headless Chromium (issue 13, item 6).

Builds the site into a temporary folder, serves it on 127.0.0.1 and opens every page through
the Chrome DevTools protocol: formulas typeset by the local MathJax (no TeX left in the text, no
MathJax error), every image and animation frame loaded, no console error, no failed request and
no request leaving the local server. A screenshot of one lesson is kept as an artefact. Skipped,
with the reason, where Chromium, a local MathJax or the websocket client is missing.
"""

from __future__ import annotations

import base64
import importlib.util
import json
import shutil
import subprocess
import threading
import time
import urllib.request
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome")
SCREENSHOT_PAGE = "lessons/05_dahlquist_stability.html"

CHECK_PAGE = r"""
(() => {
  const text = el => { const c = el.cloneNode(true);
    c.querySelectorAll('pre, code, script, style, .jp-InputArea, .jp-OutputArea').forEach(n => n.remove());
    return c.textContent; };
  const prose = [...document.querySelectorAll('.jp-RenderedMarkdown, main')].map(text).join('\n');
  const leftover = prose.match(/\$\$[^$]+\$\$|\$[^$\s][^$\n]*?\$/g) || [];
  const images = [...document.images];
  return JSON.stringify({
    typeset: document.querySelectorAll('.MathJax_CHTML, .MathJax_Display, mjx-container').length,
    mathErrors: document.querySelectorAll('.MathJax_Error, merror, .mjx-merror').length,
    leftover: leftover.slice(0, 3),
    images: images.length,
    broken: images.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => (i.id || i.src).slice(0, 60)),
    // to_jshtml players, or animated PNG images (mslab.plots.animation_image: an acTL chunk)
    animations: document.querySelectorAll('.animation').length + images.filter(i =>
      i.src.startsWith('data:image/png') && atob(i.src.slice(22, 4022)).includes('acTL')).length,
  });
})()
"""


def _browser() -> str | None:
    return next((path for name in BROWSERS if (path := shutil.which(name))), None)


class _QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:   # no line per request in the test output
        pass


class DevTools:
    """The few Chrome DevTools protocol calls the test needs, over one page's websocket."""

    def __init__(self, ws_url: str):
        import websocket

        self.ws = websocket.create_connection(ws_url, timeout=300, suppress_origin=True)
        self.next_id = 0
        self.events: list[dict] = []

    def call(self, method: str, **params) -> dict:
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv())
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self.events.append(message)

    def wait_for(self, event: str, timeout: float = 300.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(e.get("method") == event for e in self.events):
                return
            self.events.append(json.loads(self.ws.recv()))
        raise TimeoutError(event)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    pytest.importorskip("websocket", reason="websocket-client (a jupyter dependency) is not installed")
    if _browser() is None:
        pytest.skip("no Chromium on this machine (Debian: apt-get install chromium; .ci/run does it)")
    spec = importlib.util.spec_from_file_location("build_site", ROOT / "tools" / "build_site.py")
    build_site = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build_site)
    try:
        build_site.find_mathjax()
    except build_site.SiteError as err:
        pytest.skip(f"site not built: {err}")
    out = tmp_path_factory.mktemp("site") / "site"
    build_site.build(out)      # any other build problem is a failure
    return out


@pytest.fixture(scope="module")
def server(site):
    handler = partial(_QuietHandler, directory=str(site))
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()


@pytest.fixture(scope="module")
def page(tmp_path_factory, server):
    profile = tmp_path_factory.mktemp("chromium-profile")
    proc = subprocess.Popen(
        [_browser(), "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
         "--no-first-run",
         "--disable-extensions", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-default-apps", "--remote-debugging-port=0",
         "--remote-allow-origins=*", f"--user-data-dir={profile}", "--window-size=1280,900",
         "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + 600  # readiness is the port file; the deadline only catches a hang
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > deadline or proc.poll() is not None:
                pytest.fail("Chromium did not open its DevTools port within 600 s")
            time.sleep(0.1)
        port = port_file.read_text().split()[0]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as answer:
            targets = json.load(answer)
        devtools = DevTools(next(t for t in targets if t["type"] == "page")["webSocketDebuggerUrl"])
        for domain in ("Page", "Runtime", "Log", "Network"):
            devtools.call(f"{domain}.enable")
        yield devtools
        devtools.ws.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def _pages(site: Path) -> list[str]:
    return sorted(str(p.relative_to(site)) for p in site.rglob("*.html") if "mathjax" not in p.parts)


def _open(devtools: DevTools, url: str) -> dict:
    """Load one page, wait for MathJax, return the page check and the problems seen on the way."""
    devtools.events.clear()
    devtools.call("Page.navigate", url=url)
    devtools.wait_for("Page.loadEventFired")
    devtools.call("Runtime.evaluate", awaitPromise=True, expression=(
        "new Promise(done => window.MathJax ? MathJax.Hub.Queue(() => done(true)) : done(false))"))
    result = json.loads(devtools.call("Runtime.evaluate", expression=CHECK_PAGE)["result"]["value"])
    server = url.split("/")[2]
    problems = []
    for e in devtools.events:
        method, params = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            problems.append(f"console: {[a.get('value') for a in params.get('args', [])]}")
        elif method == "Runtime.exceptionThrown":
            problems.append(f"exception: {params['exceptionDetails'].get('text')}")
        elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
            problems.append(f"log: {params['entry'].get('text')}")
        elif method == "Network.requestWillBeSent":
            target = params["request"]["url"]
            if not target.startswith(("data:", "blob:", "about:")) and target.split("/")[2] != server:
                problems.append(f"external request: {target}")
        elif method == "Network.responseReceived" and params["response"]["status"] >= 400:
            problems.append(f"HTTP {params['response']['status']}: {params['response']['url']}")
        elif method == "Network.loadingFailed" and not params.get("canceled"):
            problems.append(f"failed: {params.get('errorText')}")
    result["problems"] = problems
    return result


def test_every_page_renders_offline(site, server, page, tmp_path_factory):
    pages = _pages(site)
    lessons = [p for p in pages if p.startswith("lessons/")]
    assert "index.html" in pages and len(lessons) >= 10, pages
    index = (site / "index.html").read_text()
    missing = [p for p in pages if p != "index.html" and f'href="{p}"' not in index]
    assert not missing, f"pages missing from the table of contents: {missing}"
    start = time.monotonic()
    reports = {p: _open(page, server + p) for p in pages}
    bad = {p: r for p, r in reports.items()
           if r["problems"] or r["mathErrors"] or r["leftover"] or r["broken"]}
    assert not bad, json.dumps(bad, indent=1)[:3000]
    for p in lessons:     # every lesson has formulas and figures
        assert reports[p]["typeset"] > 0 and reports[p]["images"] > 0, (p, reports[p])
    animated = [p for p, r in reports.items() if r["animations"]]
    assert animated, "no page carries an animation"
    shot = page.call("Page.navigate", url=server + SCREENSHOT_PAGE)
    assert shot.get("frameId")
    _open(page, server + SCREENSHOT_PAGE)
    png = base64.b64decode(page.call("Page.captureScreenshot", format="png")["data"])
    artefact = tmp_path_factory.mktemp("artefacts") / "site_lesson05.png"
    artefact.write_bytes(png)
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    print(f"{len(pages)} pages checked in {time.monotonic() - start:.1f} s; animations on {animated}; "
          f"screenshot {artefact}")
