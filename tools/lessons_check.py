"""List the lessons' markdown sentences that state a number or a verdict no claim backs.

Usage (from the repository root)::

    python tools/lessons_check.py                       # every lessons/NN_*.ipynb
    python tools/lessons_check.py lessons/03_verlet_leapfrog.ipynb

Exit 0 when every such sentence is backed, 1 with a list (``FILE:cell N: sentence``) otherwise,
2 on a file that cannot be read.

A sentence *needs backing* when, outside equations (``$...$``, ``$$...$$``), code (`` `...` ``),
links' targets and headings, it contains a digit or a verdict word (bounded, drifting, stable,
faster, times, order, ...). Citations do not count as numbers: "eq. 3", "eqs. 1–2", "lesson 04",
"section 2", "§2.3", "exercise 02", names such as ``rk4`` or "2D", list markers "1.".

A sentence is *backed* by an HTML comment inside it or right after its end:

* ``<!-- claim: ID -->`` (several: ``<!-- claim: ID1, ID2 -->``) names a claim of the same
  notebook: a code cell calls ``claim(..., id="ID")`` (``mslab.claims``) and its stored output
  shows ``claim holds: [ID]``. An ID that no cell defines, or whose stored output does not show
  it holding, is listed too.
* ``<!-- no-claim: reason -->`` marks a sentence that is not a measurement (a definition, a
  scene's parameters, a fact of the mathematics derived in an equation).

A comment at the very start of a paragraph, block quote or list item (before any text) covers
that whole block instead of one sentence. Claim IDs are found as literal ``id="ID"`` arguments
and in the stored outputs.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import nbformat

LESSONS = Path(__file__).resolve().parents[1] / "lessons"

VERDICT = re.compile(
    r"\b(bounded|unbounded|drift(?:s|ing|ed)?|stable|unstable|faster|slower|cheaper|dearer|"
    r"times|orders?|more accurate|less accurate|better|worse|twice|halves|halving|doubles|"
    r"\w+fold|grows?|shrinks?|blows? up)\b", re.IGNORECASE)
COMMENT = re.compile(r"<!--\s*(claim|no-claim)\s*:\s*(.*?)\s*-->", re.DOTALL)
CLAIM_ID = re.compile(r"""\bid\s*=\s*(?:f?["'])([\w.\-]+)["']""")

# spans whose digits are not numbers of a statement (each replaced by filler of equal length)
MASKS = [
    re.compile(r"<!--.*?-->", re.DOTALL),                       # comments (read separately)
    re.compile(r"\$\$.*?\$\$", re.DOTALL),                      # display equations
    re.compile(r"(?<!\\)\$[^$]+?(?<!\\)\$", re.DOTALL),         # inline equations
    re.compile(r"```.*?```", re.DOTALL),                        # code blocks
    re.compile(r"`[^`]*`"),                                     # inline code
    re.compile(r"\]\([^)]*\)"),                                 # link targets
    re.compile(r"<[^>\n]+>"),                                   # html tags
    re.compile(r"^\s{0,3}#.*$", re.MULTILINE),                  # headings
    re.compile(r"^\s*(?:\d+[.)]|[-*+])\s", re.MULTILINE),       # list markers
    re.compile(r"^\s*>", re.MULTILINE),                        # block quotes
    re.compile(r"\b(?:seed\s+)?(?:eqs?|equations?|lessons?|sections?|exercises?|cells?|chapters?|"
               r"figs?|figures?|items?|issues?|ch)\.?\s*\d[\d.]*(?:\s*(?:[–-]|and|to|,)\s*\d[\d.]*)*",
               re.IGNORECASE),                                  # citations: eq. 3, lessons 04-05
    re.compile(r"§\s*\d[\d.]*(?:\s*[–-]\s*\d[\d.]*)*"),         # §2.3
    re.compile(r"\b\w*[A-Za-z_]\w*\d\w*\b|\b\d+[A-Za-z_]*[A-Za-z_]\w*\b"),  # rk4, dop853, 2D, 3rd
]
ABBREVIATIONS = re.compile(r"\b(?:e\.g|i\.e|vs|cf|approx|etc|eqs?|resp|no)\.", re.IGNORECASE)
SENTENCE_END = re.compile(r"[.!?:;](?=\s+[^a-z\s])|\n\s*\n|\n(?=\s*(?:\d+[.)]|[-*+])\s)")
DIGIT = re.compile(r"\d")
LEAD_COMMENT = re.compile(r"\s*(?:>\s*)?(?:(?:\d+[.)]|[-*+])\s+)?(?:\*\*)?\s*<!--\s*(?:no-)?claim\s*:")


@dataclass
class Finding:
    """One unbacked sentence (or a claim reference that no cell backs)."""

    path: Path
    cell: int
    text: str

    def __str__(self) -> str:
        return f"{self.path}:cell {self.cell}: {self.text}"


def _masked(text: str) -> str:
    """``text`` with equations, code, comments, citations and names blanked out (same length)."""
    for pattern in MASKS:
        text = pattern.sub(lambda m: re.sub(r"[^\n]", "~", m.group(0)), text)
    return ABBREVIATIONS.sub(lambda m: m.group(0)[:-1] + "~", text)


def _split(text: str, pattern: str, start: int, end: int) -> list[tuple[int, int]]:
    bounds = [start] + [m.end() for m in re.compile(pattern).finditer(text, start, end)] + [end]
    return list(zip(bounds, bounds[1:], strict=False))


def _blocks(text: str) -> list[tuple[int, int]]:
    """Paragraphs, and the items of lists, as (start, end) offsets; a paragraph or item that
    starts with a claim or no-claim comment is left out (the comment covers it)."""
    blocks = []
    for p0, p1 in _split(text, r"\n\s*\n", 0, len(text)):
        if not LEAD_COMMENT.match(text, p0, p1):
            blocks += [(a, b) for a, b in _split(text, r"\n(?=\s*(?:\d+[.)]|[-*+])\s)", p0, p1)
                       if not LEAD_COMMENT.match(text, a, b)]
    return blocks


def _sentences(text: str, start: int, end: int) -> list[tuple[int, int]]:
    """Sentences of ``text[start:end]``; a comment right after a sentence's end belongs to it."""
    masked = _masked(text)
    cuts = [start]
    for m in SENTENCE_END.finditer(masked, start, end):
        cut = m.end()
        trailing = re.match(r"\s*(<!--.*?-->\s*)+", text[cut:end], re.DOTALL)
        cuts.append(cut + (trailing.end() if trailing else 0))
    cuts.append(end)
    return [(a, b) for a, b in zip(cuts, cuts[1:], strict=False) if text[a:b].strip()]


def _needs_backing(masked: str) -> bool:
    return bool(DIGIT.search(masked) or VERDICT.search(masked))


def claim_ids(nb: nbformat.NotebookNode) -> tuple[set[str], set[str]]:
    """IDs that code cells define, and IDs whose stored output shows the claim holding."""
    defined, holding = set(), set()
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        defined |= set(CLAIM_ID.findall(cell.source))
        for out in cell.get("outputs", []):
            text = out.get("text", "") if out.get("output_type") == "stream" else ""
            holding |= set(re.findall(r"claim holds: \[([\w.\-]+)\]", text))
    return defined | holding, holding


def check_markdown(path: Path, index: int, text: str, defined: set[str], holding: set[str]) -> list[Finding]:
    """Findings of one markdown cell."""
    found = []
    for comment in COMMENT.finditer(text):
        if comment.group(1) == "claim":
            for cid in filter(None, (s.strip() for s in comment.group(2).split(","))):
                if cid not in defined:
                    found.append(Finding(path, index, f"claim {cid!r} is named but no code cell defines it"))
                elif cid not in holding:
                    found.append(Finding(path, index, f"claim {cid!r} has no stored 'claim holds' output"))
    masked_all = _masked(text)
    for b0, b1 in _blocks(text):
        for s0, s1 in _sentences(text, b0, b1):
            if COMMENT.search(text[s0:s1]) or not _needs_backing(masked_all[s0:s1]):
                continue
            found.append(Finding(path, index, " ".join(text[s0:s1].split())))
    return found


def check_notebook(path: Path) -> list[Finding]:
    """Every unbacked sentence and every dangling claim reference of one notebook."""
    nb = nbformat.read(path, as_version=4)
    defined, holding = claim_ids(nb)
    found = []
    for index, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown":
            found += check_markdown(path, index, cell.source, defined, holding)
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path,
                        help="notebooks to check (default: every lessons/NN_*.ipynb)")
    args = parser.parse_args(argv)
    paths = args.notebooks or sorted(LESSONS.glob("[0-9][0-9]*_*.ipynb"))
    findings: list[Finding] = []
    for path in paths:
        try:
            findings += check_notebook(path)
        except (OSError, ValueError) as exc:
            print(f"lessons_check: error: {path}: {exc}", file=sys.stderr)
            return 2
    for finding in findings:
        print(finding)
    if findings:
        print(f"{len(findings)} sentence(s) with a number or verdict that no claim backs "
              f"(add <!-- claim: ID --> or <!-- no-claim: reason -->)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
