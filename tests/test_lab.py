"""The lessons as a student meets them: JupyterLab in headless Chromium (issue 27).

JupyterLab (the venv's) is started on 127.0.0.1 with a random port and token, on a temporary copy
of ``lessons/`` (the repository's notebooks are never touched), with a fresh Jupyter data directory,
so every lesson is *untrusted*, as in a student's clone. Each lesson is opened in headless Chromium
(Debian's ``chromium`` and ``chromium-driver``, driven by selenium). Checked, per lesson:

- opened: not marked modified (the stored kernelspec and language_info are the kernel's), no MathJax
  error and no TeX left untypeset, every stored image shows, every animation shows a frame, no
  traceback, no stderr output and no raw repr (``<function ...>``, ``np.float64(...)``) stored;
- where a live kernel shows more than the stored outputs (``RUN_ALL``: every lesson with a widget,
  and ``PLAIN_RUN``, one without), Kernel > Restart Kernel and Run All Cells, then the same checks
  on the live outputs, every widget a real widget, and every interactive widget moved to every
  corner of its controls' ranges (dropdown: first and last option, slider: Home and End keys)
  redraws without an error or a raw value.

The other lessons' live outputs are held to the stored ones by nbval (``make test`` re-executes
every lesson and compares every output), and lessons/conftest.py checks every re-executed cell,
``NBVAL_IGNORE_OUTPUT`` ones included, for stderr, raw reprs and images that are not pictures
(nbval compares no image); tests/test_lessons_executed.py checks the stored outputs without a
browser. Every wait follows a signal (kernel status, executed cells, output changes); a Run All
fails when no cell finishes within ``CELL_TIMEOUT``, the per-cell budget of lessons/run_all.py,
so a loaded machine slows it and never fails it.

Lesson defects that other changes fix are expected failures naming the lesson (``KNOWN``); remove
an entry when its fix lands. Skipped, with the reason, where Chromium, chromedriver, selenium or
JupyterLab is missing (``.ci/run`` installs the Debian packages). JupyterLab, its kernels and the
browser are stopped by their PIDs in the fixtures' teardown, also when a test fails.
"""

from __future__ import annotations

import base64
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
LESSONS = sorted((ROOT / "lessons").glob("[0-9][0-9]_*.ipynb"))
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
DRIVERS = ("chromedriver", "chromium-driver")
MARKER = "lab-test-root.txt"
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--disable-extensions", "--window-size=1400,1000")

#: lesson -> the defect of issue 27 it still shows; xfail(strict=False) until its fix is merged
KNOWN: dict[str, str] = {}

#: a lesson without widgets that still runs live: images and formulas of a live kernel (the cheapest)
PLAIN_RUN = "02_heun_midpoint_rk4"
#: a cell's budget in a live run, as lessons/run_all.py gives one: the wait restarts at each cell
CELL_TIMEOUT = 300
WIDGET_MIME = "application/vnd.jupyter.widget-view+json"
WIDGET_CODE = re.compile(r"\bexplorer\(|ipywidgets|\binteract")


def _runs_live(path: Path) -> bool:
    """Run All in the browser: ``PLAIN_RUN``, and every lesson with a widget (stored or in its code)."""
    cells = [c for c in nbformat.read(path, as_version=4).cells if c.cell_type == "code"]
    return (path.stem == PLAIN_RUN or any(WIDGET_CODE.search(c.source) for c in cells)
            or any(WIDGET_MIME in o.get("data", {}) for c in cells for o in c.outputs))


RUN_ALL = frozenset(p.name for p in LESSONS if _runs_live(p))

#: the page helpers (window.labTest), injected into JupyterLab
LAB_TEST_JS = Path(__file__).with_name("lab_page.js").read_text()


def _which(names: tuple[str, ...]) -> str | None:
    return next((path for name in names if (path := shutil.which(name))), None)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen, children: list[int], timeout: float = 15.0) -> None:
    """Stop a process group we started (SIGTERM, then SIGKILL), then any child PID still alive."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
            proc.wait(timeout=timeout)
            break
        except ProcessLookupError:
            break
        except subprocess.TimeoutExpired:
            continue
    for child in children:
        try:
            os.kill(child, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _children(pid: int) -> list[int]:
    try:
        import psutil

        return [p.pid for p in psutil.Process(pid).children(recursive=True)]
    except Exception:   # psutil missing or the process gone: nothing more to stop
        return []


@pytest.fixture(scope="module")
def tools() -> dict:
    pytest.importorskip("selenium", reason="selenium is not installed (pip install -e '.[dev]')")
    pytest.importorskip("jupyterlab", reason="JupyterLab is not installed (pip install -e '.[dev]')")
    pytest.importorskip("ipywidgets", reason="ipywidgets is not installed (pip install -e '.[lessons]')")
    browser, driver = _which(BROWSERS), _which(DRIVERS)
    if browser is None or driver is None:
        pytest.skip("no Chromium or no chromedriver on this machine (Debian: apt-get install chromium "
                    "chromium-driver; .ci/run does it)")
    return {"browser": browser, "driver": driver}


@pytest.fixture(scope="module")
def lab(tools, tmp_path_factory):
    """JupyterLab on a copy of lessons/, 127.0.0.1, random port and token; stopped by PID."""
    home = tmp_path_factory.mktemp("lab")
    root = home / "lessons"      # JupyterLab's root is the lessons folder (`make lab`: LAB_ROOT)
    shutil.copytree(ROOT / "lessons", root, ignore=shutil.ignore_patterns("student", ".ipynb_checkpoints"))
    settings = home / "settings" / "@jupyterlab" / "apputils-extension"
    settings.mkdir(parents=True)
    (settings / "notification.jupyterlab-settings").write_text(
        json.dumps({"fetchNews": "false", "checkForUpdates": False}))
    port, token = _free_port(), secrets.token_hex(16)
    venv = Path(sys.prefix)
    if shutil.which("make") is None or not (venv / "bin" / "jupyter").exists():
        pytest.skip(f"`make lab` needs make and {venv}/bin/jupyter")
    (root / MARKER).write_text("JupyterLab's root folder is the test's copy\n")
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
               JUPYTER_CONFIG_DIR=str(home / "config"), JUPYTER_DATA_DIR=str(home / "data"),
               JUPYTER_RUNTIME_DIR=str(home / "runtime"), IPYTHONDIR=str(home / "ipython"),
               JUPYTERLAB_SETTINGS_DIR=str(home / "settings"),
               JUPYTERLAB_WORKSPACES_DIR=str(home / "workspaces"))
    log = (home / "jupyterlab.log").open("w")
    # the students' command, `make lab`, with this venv (installed: no STAMP), on the copy
    # (no --allow-root: as root `make lab` adds it)
    args = ["--ServerApp.open_browser=False", "--ServerApp.ip=127.0.0.1", f"--ServerApp.port={port}",
            "--ServerApp.port_retries=0", f"--IdentityProvider.token={token}",
            "--LabApp.expose_app_in_browser=True", "--LabApp.news_url=None",
            "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate"]  # as root: `make lab` adds
    # --allow-root itself (issue 39: a newcomer's `make lab` as root stopped)
    proc = subprocess.Popen(
        ["make", "-s", "-C", str(ROOT), "lab", f"VENV={venv}", "STAMP=", f"LAB_ROOT={root}",
         f"LAB_RC={home / 'lab.bashrc'}", f"LAB_ARGS={' '.join(args)}"],
        env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
    children: list[int] = []
    try:
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 90
        while True:
            try:
                with urllib.request.urlopen(f"{url}/api/status?token={token}", timeout=5) as answer:
                    if answer.status == 200:
                        break
            except OSError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"JupyterLab did not start: {(home / 'jupyterlab.log').read_text()[-2000:]}")
            time.sleep(0.2)
        with urllib.request.urlopen(f"{url}/api/contents/{MARKER}?token={token}", timeout=10) as answer:
            assert answer.status == 200     # never the repository's own lessons/
        yield {"url": url, "token": token, "root": root, "home": home}
    finally:
        children.extend(_children(proc.pid))   # JupyterLab under make, its kernels and terminals
        _stop(proc, children)
        log.close()


@pytest.fixture(scope="module")
def page(tools, lab, tmp_path_factory):
    """Headless Chromium (started here, stopped by PID) with JupyterLab loaded, driven by selenium."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tmp_path_factory.mktemp("chromium-profile")
    proc = subprocess.Popen([tools["browser"], *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                             "--remote-debugging-port=0", "about:blank"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    service, driver, children = None, None, []
    try:
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + 30
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > deadline or proc.poll() is not None:
                pytest.fail("Chromium did not open its DevTools port within 30 s")
            time.sleep(0.1)
        options = webdriver.ChromeOptions()
        options.debugger_address = f"127.0.0.1:{port_file.read_text().split()[0]}"
        service = Service(executable_path=tools["driver"])
        driver = webdriver.Chrome(service=service, options=options)
        driver.set_script_timeout(CELL_TIMEOUT + 60)
        driver.get(f"{lab['url']}/lab?token={lab['token']}")
        deadline = time.monotonic() + 90
        while not driver.execute_script("return !!(window.jupyterapp && window.jupyterapp.shell)"):
            if time.monotonic() > deadline:
                pytest.fail("JupyterLab did not load in Chromium within 90 s")
            time.sleep(0.2)
        driver.execute_script(LAB_TEST_JS)
        STARTED.clear()
        yield driver
    finally:
        children.extend(_children(proc.pid))
        if service is not None and service.process is not None:
            _stop_driver(service)
        _stop(proc, children)


def _stop_driver(service) -> None:
    pid = service.process.pid
    try:
        os.kill(pid, signal.SIGTERM)
        service.process.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _call(driver, name: str, *args):
    """Run ``labTest.name(*args)`` in the page and return its (awaited) result."""
    result = driver.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        f"Promise.resolve(window.labTest.{name}(...[...arguments].slice(0, -1)))"
        ".then(done, e => done({jsError: String(e)}));", *args)
    if isinstance(result, dict) and "jsError" in result:
        raise RuntimeError(f"{name}: {result['jsError']}")   # the harness failed, not a lesson
    return result


def _problems(report: dict, when: str) -> list[str]:
    found = []
    if report["dirty"] and when == "opened":
        found.append(f"{when}: the notebook is marked modified")
    found += [f"{when}: cell {c}: MathJax error {e!r}" for c, e in report["mathErrors"]]
    found += [f"{when}: cell {c}: TeX left untypeset {t!r}" for c, t in report["leftoverTeX"]]
    for img in report["images"]:
        if not img["shown"]:
            what = "animation shows no frame" if img["animation"] else "image not shown"
            found.append(f"{when}: cell {img['cell']}: {what} (natural width {img['naturalWidth']}, "
                         f"shown width {img['offsetWidth']})")
    found += [f"{when}: cell {c}: {e}" for c, e in report["errors"]]
    found += [f"{when}: cell {c}: raw value printed {r!r}" for c, r in report["raw"]]
    return found


def _exercise_widgets(driver, widget_cells: list[int]) -> list[str]:
    """Move every interactive widget through the corners of its controls' ranges."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.select import Select

    found = []
    boxes = _call(driver, "interacts")
    if len(boxes) < len(widget_cells):
        found.append(f"after Run All: {len(widget_cells)} cells show widgets, {len(boxes)} interactive found")
    for k, box in enumerate(boxes):
        controls = (box.find_elements(By.CSS_SELECTOR, ".widget-dropdown select")
                    + box.find_elements(By.CSS_SELECTOR, ".widget-slider .noUi-handle"))

        def value(c):
            return c.get_attribute("value") if c.tag_name == "select" else c.get_attribute("aria-valuenow")

        def move(c, high: bool):
            driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", c)
            if c.tag_name == "select":
                options = Select(c)
                options.select_by_index(len(options.options) - 1 if high else 0)
            else:
                c.send_keys(Keys.END if high else Keys.HOME)

        corner = [False] * len(controls)
        steps = [(i, False) for i in range(len(controls))]           # every control to its low end
        for n in range(1, 2 ** len(controls)):                         # then every corner (Gray code)
            flip = (n & -n).bit_length() - 1
            corner[flip] = not corner[flip]
            steps.append((flip, corner[flip]))
        for i, high in steps:
            before = value(controls[i])
            driver.execute_script("window.labTest.watch(arguments[0])", box)
            move(controls[i], high)
            if value(controls[i]) == before:
                continue
            state = ", ".join(f"{value(c)}" for c in controls)
            seen = _call(driver, "redrawn", box, CELL_TIMEOUT)
            where = f"widget {k} at ({state})"
            found += [f"{where}: error output ...{e.strip()[-200:]!r}" for e in seen["errors"]]
            found += [f"{where}: raw value printed {r!r}" for r in seen["raw"]]
            if seen["empty"]:
                found.append(f"{where}: the output is empty")
    return found


def _lesson_params() -> list:
    # the longest Run All first (tests/conftest.py: LONGEST_FIRST), the shorter ones run beside it;
    # raises=AssertionError: only a lesson's defect is expected, never a failure of the harness
    from tests.conftest import LONGEST_FIRST

    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    order = sorted(LESSONS, key=lambda p: rank.get(f"lessons/{p.name}", len(rank)))
    return [pytest.param(p, id=p.stem, marks=[pytest.mark.xfail(strict=False, raises=AssertionError,
                                                                reason=KNOWN[p.stem])]
                         if p.stem in KNOWN else []) for p in order]


#: lesson path -> what the lesson showed when opened, for a lesson of ``RUN_ALL`` opened and started
#: (Restart Kernel and Run All Cells) ahead of its test, while the tests before it run
STARTED: dict[str, dict] = {}
#: how many of the next lessons run ahead, each in its tab with its kernel (memory: ~0.3 GB each)
AHEAD = 2


def _open_and_run_all(page, path: str) -> dict:
    """Open a lesson (it becomes the current tab), check it as opened, then Restart & Run All."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    opened = _call(page, "open", path)
    page.execute_script("window.labTest.restartRunAll()")
    WebDriverWait(page, 30).until(
        lambda d: d.find_elements(By.CSS_SELECTOR, ".jp-Dialog .jp-mod-accept"))[0].click()
    return opened


def _wait_run(page, lesson: Path) -> dict:
    """Wait for the current lesson's Run All: it fails when no cell finishes within
    ``CELL_TIMEOUT`` (a stall), so its whole budget is its code cells times that."""
    cells = sum(c.cell_type == "code" and bool(c.source.strip())
                for c in nbformat.read(lesson, as_version=4).cells)
    page.set_script_timeout(cells * CELL_TIMEOUT + 60)
    try:
        return _call(page, "waitRun", CELL_TIMEOUT)
    finally:
        page.set_script_timeout(CELL_TIMEOUT + 60)


def _next_lessons(request, n: int) -> list[Path]:
    """The lessons of the next ``n`` browser tests this session runs (after -k, xdist)."""
    items = request.session.items
    later = items[items.index(request.node) + 1:]
    return [lesson for item in later if getattr(item, "originalname", None) == "test_lesson_in_jupyterlab"
            and (lesson := item.callspec.params["lesson"]).name in RUN_ALL][:n]


@pytest.mark.slow
@pytest.mark.parametrize("lesson", _lesson_params())
def test_lesson_in_jupyterlab(lesson: Path, lab, page, request) -> None:
    """One lesson opened and checked; in ``RUN_ALL``, Restart & Run All and every widget moved.
    The next ``AHEAD`` lessons of ``RUN_ALL`` are opened, checked as opened and started in tabs of
    their own (each its kernel) before this one's checks, so that the kernels share the machine's
    cores; every wait is on a signal (kernel status, messages), never on a time."""
    path = lesson.name
    try:
        if path in RUN_ALL:
            opened = STARTED.pop(path, None) or _open_and_run_all(page, path)
        else:
            opened = _call(page, "open", path)
        found = _problems(opened, "opened")
        for following in _next_lessons(request, AHEAD):
            if (ahead := following.name) not in STARTED:
                try:
                    STARTED[ahead] = _open_and_run_all(page, ahead)
                except Exception:
                    _call(page, "close", ahead)
                    raise
        if path not in RUN_ALL:
            assert not found, f"{lesson.name}:\n  " + "\n  ".join(found)
            return
        _call(page, "show", path)
        ran = _wait_run(page, lesson)
        found += _problems(ran, "after Run All")
        found += [f"after Run All: cell {c}: {e}" for c, e in ran["errors"]]
        found += [f"after Run All: cell {c}: raw value printed {r!r}" for c, r in ran["raw"]]
        found += [f"after Run All: cell {c}: widget not live" for c in ran["deadWidgets"]]
        found += _exercise_widgets(page, ran["widgetCells"])
    finally:
        _call(page, "close", path)
    assert not found, f"{lesson.name}:\n  " + "\n  ".join(found)


def test_animated_png_plays_untrusted(lab, page) -> None:
    """An ``animation_image`` output in an untrusted notebook shows a frame and plays (frames change)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.animation import FuncAnimation

    from mslab.plots import animation_png

    fig, ax = plt.subplots(figsize=(3, 2), dpi=60)
    (dot,) = ax.plot([0.0], [0.0], "o", ms=20)
    ax.set(xlim=(-1.2, 1.2), ylim=(-1.2, 1.2))
    frames = 8
    anim = FuncAnimation(fig, lambda k: dot.set_data([np.cos(k * np.pi / 4)], [np.sin(k * np.pi / 4)]),
                         frames=frames)
    data = animation_png(anim, fps=8)
    plt.close(fig)
    nb = nbformat.v4.new_notebook(metadata={"kernelspec": {"name": "python3", "display_name": ""}})
    nb.cells = [nbformat.v4.new_code_cell("display(animation_image(anim))", outputs=[
        nbformat.v4.new_output("display_data", data={"image/png": base64.b64encode(data).decode(),
                                                     "text/plain": "<IPython.core.display.Image object>"})])]
    nbformat.write(nb, lab["root"] / "scratch_animation.ipynb")
    try:
        opened = _call(page, "open", "scratch_animation.ipynb")
        assert [(i["animation"], i["shown"]) for i in opened["images"]] == [(True, True)], opened["images"]
        # the frame on screen changes: screenshots of the image until two differ (a canvas cannot
        # tell: drawImage of an animated image draws its first frame, by the HTML standard)
        from selenium.webdriver.common.by import By

        img = page.find_element(By.CSS_SELECTOR,
                                ".jp-NotebookPanel:not(.lm-mod-hidden) .jp-OutputArea-output img")
        first, changed, deadline = img.screenshot_as_png, False, time.monotonic() + 20
        while not changed and time.monotonic() < deadline:
            changed = img.screenshot_as_png != first
        assert changed, "the animated PNG shows one frame only (it does not play)"
    finally:
        _call(page, "close")


def test_exercise_tests_pass_in_jupyterlab_terminal(lab) -> None:
    """In JupyterLab's terminal (``make lab``) ``pytest`` is the venv's: an exercise's tests pass."""
    import re

    websocket = pytest.importorskip("websocket", reason="websocket-client (a jupyter dependency) is missing")
    exercises = lab["home"] / "exercises"
    shutil.copytree(ROOT / "exercises", exercises, ignore=shutil.ignore_patterns("__pycache__"))
    request = urllib.request.Request(f"{lab['url']}/api/terminals?token={lab['token']}", method="POST",
                                     data=b"{}", headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=30) as answer:
        name = json.load(answer)["name"]
    ws = websocket.create_connection(
        f"ws://{lab['url'].split('//')[1]}/terminals/websocket/{name}?token={lab['token']}",
        suppress_origin=True, timeout=180)
    try:
        ws.send(json.dumps(["stdin", f"cd {exercises} && echo PYTEST=$(command -v pytest) && "
                                     "pytest 02_euler_steps; echo EXIT=$?\r"]))
        out, deadline = "", time.monotonic() + 180
        while not re.search(r"EXIT=\d+", out) and time.monotonic() < deadline:
            message = json.loads(ws.recv())
            if message[0] == "stdout":
                out += message[1].replace("EXIT=$?", "")
    finally:
        ws.close()
    assert f"PYTEST={Path(sys.prefix) / 'bin' / 'pytest'}" in out, out[-2000:]
    assert "EXIT=0" in out and " passed" in out and "Error" not in out, out[-2000:]


def test_lab_serves_the_student_release(lab) -> None:
    """`make lab`'s root: the lessons with student/ (solutions stripped, no hidden test), no exercises/."""
    from mslab.grading.release import strip_solutions

    def get(path: str) -> dict:
        url = f"{lab['url']}/api/contents/{path}?token={lab['token']}"
        with urllib.request.urlopen(url, timeout=30) as answer:
            return json.load(answer)

    names = {item["name"] for item in get("student/06_implicit_euler")["content"]}
    assert names >= {"implicit_euler.py", "test_public.py", "README.md"} and "test_hidden.py" not in names
    shown = get("student/06_implicit_euler/implicit_euler.py")["content"]
    assert shown == strip_solutions((ROOT / "exercises/06_implicit_euler/implicit_euler.py").read_text())
    with pytest.raises(urllib.error.HTTPError):
        get("exercises")
