"""pytest in lessons/: the notebooks (nbval); never the student release made by `make lab`.

nbval compares each re-executed cell's outputs with the stored ones, but not where a cell says
``# NBVAL_IGNORE_OUTPUT`` (timings), and never the images (``image/png`` is in its skip list: a
figure that stops rendering still passes on its ``<Figure ...>`` text). Every executed cell, those
included, is also checked here on what the live kernel printed: no stderr, no raw repr (the same
pattern as tests/lab_page.js), and as many images as stored, each a PNG that decodes to a picture
of positive size. With nbval's own checks this is what tests/test_lab.py's Run All saw in a live
kernel; the browser then runs only the lessons where a live kernel shows more (widgets).
"""

from __future__ import annotations

import base64
import io
import re

import pytest

collect_ignore = ["student"]

#: a value printed as its repr, not its meaning (the same pattern as tests/lab_page.js: RAW)
RAW = re.compile(r"^<(function|bound method)|object at 0x|np\.(float|int)\d+\(", re.MULTILINE)


def _png_size(data: str) -> tuple[int, int]:
    from PIL import Image

    with Image.open(io.BytesIO(base64.b64decode(data))) as image:
        image.load()     # the first frame decodes (an animated PNG's too)
        return image.size


def live_problems(outs: list, stored: list) -> list[str]:
    """What a live run's outputs ``outs`` of one cell show wrong, against its ``stored`` outputs."""
    found = [f"stderr printed: {o.get('text', '')[-300:]!r}" for o in outs
             if o.get("output_type") == "stream" and o.get("name") == "stderr"]
    for o in outs:
        text = "" if o.get("output_type") == "stream" else o.get("data", {}).get("text/plain", "")
        text = "".join(text) if isinstance(text, list) else text
        if RAW.search(text):
            found.append(f"raw value printed: {text[:80]!r}")
    images = [o["data"]["image/png"] for o in outs if "image/png" in o.get("data", {})]
    n_stored = sum("image/png" in o.get("data", {}) for o in stored)
    if len(images) != n_stored:
        found.append(f"{len(images)} images shown, {n_stored} stored")
    for k, data in enumerate(images):
        try:
            width, height = _png_size(data)
        except Exception as e:     # any decoder error: not a picture
            found.append(f"image {k} is not a PNG: {e}")
            continue
        if width <= 0 or height <= 0:
            found.append(f"image {k} is {width}x{height}")
    return found


def _check_live_outputs(item: pytest.Item) -> None:
    compare, checked = item.compare_outputs, item.options["check"]

    def compare_outputs(test, ref, skip_compare=None) -> bool:
        found = live_problems(test, ref)
        if found:
            item.comparison_traceback = found
            return False
        return compare(test, ref, skip_compare) if checked else True

    item.compare_outputs = compare_outputs
    item.options["check"] = True     # nbval calls compare_outputs only where it checks


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every nbval cell also checks its live outputs (``live_problems``), ignored ones included."""
    for item in items:
        if type(item).__name__ == "IPyNbCell" and hasattr(item, "compare_outputs"):
            _check_live_outputs(item)
