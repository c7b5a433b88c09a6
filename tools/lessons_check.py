"""Check the lessons' markdown sentences against the claims that back them.

Usage: ``python tools/lessons_check.py [lessons/NN_x.ipynb ...]`` (default: every lesson).

Exit 0 when every sentence is backed and agrees with its claims, 1 with a list otherwise, 2 on a
file that cannot be read.

A sentence *needs backing* when, outside code, links' targets, headings and citations ("eq. 3",
"lesson 04", "§2.3", names such as ``rk4`` or "2D", list markers "1."), it contains a number
(inside ``$...$`` too, where a side of a relation is purely numeric: ``$k = 100$``,
``$|R| = 1/2$``, ``$10^{-4}$``, not ``$O(h^2)$``), a magnitude word or a verdict word
(``mslab.claims.MAGNITUDES``, ``mslab.claims.FRACTIONS``, ``mslab.claims.VERDICTS``).

A sentence is *backed* by an HTML comment inside it or right after its end; a comment at the
very start of a paragraph, block quote or list item covers that whole block:

* ``<!-- claim: ID -->`` (several: ``<!-- claim: ID1, ID2 -->``) names claims of the same
  notebook, whose stored outputs show ``claim holds: [ID] statement  (name = value, ...)``
  (``mslab.claims.claim``). Then the sentence must agree with the printed values:

  - every number equals a printed value to the digits the sentence gives ("14.5" against
    "14.53"), or is bounded by one: "more than / at least 70" needs a printed value above 70,
    "below / within / up to 1e-6" one below, "about / ~ 30" one within 10 %, "30-50", "3 to 5",
    "between 3 and 5" one inside, "10 or more" one at least 10 (inside ``$...$``: ``<``,
    ``\\le``, ``\\approx``); a number word counts where it is a factor ("seven times", "tenfold");
  - a number with a unit ("within 10 s", "6 steps", "three times") is held to the printed values
    of that unit (``mslab.claims.UNITS``), when there are any;
  - every magnitude word ("several", "tens", "twice", "halves", ...) has a printed value in
    its range, written once in ``mslab.claims.MAGNITUDES``;
  - every share word ("a fifth", "two thirds", "one in four", "nine in ten", "most of", "the
    majority", ...) has a printed share (a value in 0-1, or a percent printed with ``%``) in its
    range, written once in ``mslab.claims.FRACTIONS``; a bound ("more than half", "over a
    third", "half of it or more") bounds the share by its nominal value;
  - every verdict word ("faster", "only", "never", "same", "bounded", ...) appears in the
    statement of one of its claims, with its subjects on the same sides (``mslab.claims_order``).

* ``<!-- no-claim: REASON -->`` (or ``REASON: a few words``) marks a sentence that is not a
  measurement; REASON is one of ``mslab.claims.NO_CLAIM_REASONS`` and the words never name a claim.

Folded solutions (``<details>``) are not checked; a claim ID not defined or not holding is listed.
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import nbformat

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from mslab.claims import (  # noqa: E402
    FRACTIONS,
    MAGNITUDES,
    NO_CLAIM_REASONS,
    VERDICTS,
    Number,
    Printed,
    comparable,
    fits,
    in_base,
    normalise,
    numbers_in,
    parse_printed,
    share_range,
)
from mslab.claims_order import reversed_comparisons  # noqa: E402

LESSONS = ROOT / "lessons"

VERDICT = re.compile(rf"(?<!\bat\s)\b(?:{VERDICTS})\b", re.IGNORECASE)     # "at most 3" is a bound
MAGNITUDE = [(re.compile(rf"\b(?:{words})\b(?!-)", re.IGNORECASE), ranges)
             for words, ranges in MAGNITUDES.items()]
# share words, not in a mixed number ("one and a quarter"); after a bound, "half" not before "a(n)"
FRACTION = [(re.compile(rf"(?<!and )\b(?:{words})\b(?!-)", re.IGNORECASE), share)
            for words, share in FRACTIONS.items()]
HALF = re.compile(r"\bhalf\b(?!-|\s+an?\b)", re.IGNORECASE)     # "less than half", not "half a minute"
COMMENT = re.compile(r"<!--\s*(claim|no-claim)\s*:\s*(.*?)\s*-->", re.DOTALL)
CLAIM_ID = re.compile(r"""\bid\s*=\s*(?:f?["'])([\w.\-]+)["']""")
MATH = re.compile(r"\$\$.*?\$\$|(?<!\\)\$[^$]+?(?<!\\)\$", re.DOTALL)
RELATION = re.compile(r"\\approx|\\sim|\\simeq|\\leq?|\\geq?|\\lt|\\gt|\\ll|\\gg|[<>=≈≤≥]")
REL_SIGN = {"\\approx": "≈", "\\sim": "≈", "\\simeq": "≈", "\\le": "≤", "\\leq": "≤", "\\lt": "<",
            "\\ge": "≥", "\\geq": "≥", "\\gt": ">", "\\ll": "<", "\\gg": ">"}

# spans whose digits are not numbers of a statement (each replaced by filler of equal length)
MASKS = [
    re.compile(r"<!--.*?-->", re.DOTALL),                       # comments (read separately)
    re.compile(r"```.*?```", re.DOTALL),                        # code blocks
    re.compile(r"`[^`]*`"),                                     # inline code
    MATH,                                                       # equations (read separately)
    re.compile(r"\]\([^)]*\)"),                                 # link targets
    re.compile(r"<[^>\n]+>"),                                   # html tags
    re.compile(r"^\s{0,3}#.*$", re.MULTILINE),                  # headings
    re.compile(r"^\s*(?:\d+[.)]|[-*+])\s", re.MULTILINE),       # list markers
    re.compile(r"^\s*>", re.MULTILINE),                        # block quotes
    re.compile(r"\b(?:seed\s+)?(?:eqs?|equations?|lessons?|sections?|exercises?|cells?|chapters?|"
               r"figs?|figures?|items?|issues?|ch)\.?\s*\d[\d.]*(?:\s*(?:[–-]|and|to|,)\s*\d[\d.]*)*",
               re.IGNORECASE),                                  # citations: eq. 3, lessons 04-05
    re.compile(r"§\s*\d[\d.]*(?:\s*[–-]\s*\d[\d.]*)*"),         # §2.3
    re.compile(r"(?!\d+(?:\.\d+)?[eE][-+−]?\d)"                 # names: rk4, dop853, 2D, 3rd
               r"(?:\b\w*[A-Za-z_]\w*\d\w*\b|\b\d+[A-Za-z_]*[A-Za-z_]\w*\b)"),
]
ABBREVIATIONS = re.compile(r"\b(?:e\.g|i\.e|vs|cf|approx|etc|eqs?|resp|no)\.", re.IGNORECASE)
SENTENCE_END = re.compile(r"[.!?:;](?=\s+[^a-z\s])|\n\s*\n|\n(?=\s*(?:\d+[.)]|[-*+])\s)")
LEAD_COMMENT = re.compile(r"\s*(?:>\s*)?(?:(?:\d+[.)]|[-*+])\s+)?(?:\*\*)?\s*<!--\s*(?:no-)?claim\s*:")


def _bound(words: str, signs: str) -> re.Pattern:
    """Words (or signs) of a bound at the end of the text before a number; a space matches any white space."""
    spaced = words.replace(" ", r"\s+")
    return re.compile(rf"(?:\b(?<!\bno\s)(?:{spaced})|[{signs}])\s*$", re.IGNORECASE)


ABOVE = _bound("more than|over|above|greater than|exceeds?|exceeding|at least|beyond", ">≥")
BELOW = _bound("less than|fewer than|below|under|at most|within|up to|no more than|smaller than", "<≤")
ABOUT = _bound("about|around|roughly|approximately|nearly|almost|close to|some", "~≈")
DETAILS = re.compile(r"<details>.*?</details>", re.DOTALL)     # a folded solution of a task
OR_MORE = re.compile(r"\s*(?:or\s+more|or\s+above|or\s+larger|and\s+more|\+)\b", re.IGNORECASE)
OR_LESS = re.compile(r"\s*(?:or\s+less|or\s+fewer|or\s+below|or\s+smaller)\b", re.IGNORECASE)
RANGE_JOIN = re.compile(r"\s*(?:[-–]|to)\s*$")
OF_WHAT = r"(?:\s+of\s+(?:\w+\s+)?[\w']+)?"                  # "half of it or more"


@dataclass
class Finding:
    """One unbacked sentence, a sentence its claims contradict, or a dangling claim reference."""

    path: Path
    cell: int
    text: str

    def __str__(self) -> str:
        return f"{self.path}:cell {self.cell}: {self.text}"


FILL = "\u2591"                                                # what masks write


def _fill(m: re.Match) -> str:
    return re.sub(r"[^\n]", FILL, m.group(0))


def _math_view(src: str) -> str:
    """A math span with only its purely numeric sides kept (and relations as one sign), same length."""
    body_start = 2 if src.startswith("$$") else 1
    out = list(re.sub(r"[^\n]", FILL, src))
    pieces, last = [], body_start
    for m in RELATION.finditer(src, body_start, len(src) - body_start):
        pieces.append((last, m.start()))
        sign = REL_SIGN.get(m.group(0), m.group(0))
        out[m.start()] = sign
        last = m.end()
    pieces.append((last, len(src) - body_start))
    for a, b in pieces:
        piece = src[a:b]
        bare = re.sub(r"\\(?:text|mathrm|mbox|,|;|:|!| )\{?[^}\\]*\}?|\\%|%|\\quad|\\left|\\right", "", piece)
        rest = normalise(bare)
        numbers = numbers_in(rest)
        for n in reversed(numbers):
            rest = rest[:n.start] + rest[n.end:]
        if numbers and not re.sub(r"[\s\-−+(){}]|\\times|\\cdot|\\,", "", rest):
            out[a:b] = list(piece)
    return "".join(out)


def views(text: str) -> tuple[str, str]:
    """``text`` with code, comments, citations and names blanked out (same length): once with
    equations blanked too (for splitting sentences), once with their numeric sides kept."""
    blank = text
    for pattern in MASKS:
        blank = pattern.sub(_fill, blank)
    blank = ABBREVIATIONS.sub(lambda m: m.group(0)[:-1] + FILL, blank)
    numeric = list(blank)
    code = text
    for pattern in MASKS[:3]:
        code = pattern.sub(_fill, code)
    headings = [h.span() for h in MASKS[6].finditer(code)]
    for m in MATH.finditer(code):
        if not any(a <= m.start() < b for a, b in headings):
            numeric[m.start():m.end()] = list(_math_view(m.group(0)))
    return blank, "".join(numeric).replace(FILL, " ")


def _split(text: str, pattern: str, start: int, end: int) -> list[tuple[int, int]]:
    bounds = [start] + [m.end() for m in re.compile(pattern).finditer(text, start, end)] + [end]
    return list(zip(bounds, bounds[1:], strict=False))


def _blocks(text: str) -> list[tuple[int, int, str | None]]:
    """Paragraphs, and the items of lists, as (start, end, lead comment or None)."""
    blocks = []
    for p0, p1 in _split(text, r"\n\s*\n", 0, len(text)):
        lead = COMMENT.search(text, p0, p1).group(0) if LEAD_COMMENT.match(text, p0, p1) else None
        for a, b in _split(text, r"\n(?=\s*(?:\d+[.)]|[-*+])\s)", p0, p1):
            own = COMMENT.search(text, a, b).group(0) if LEAD_COMMENT.match(text, a, b) else None
            blocks.append((a, b, own or lead))
    return blocks


def _sentences(text: str, blank: str, start: int, end: int) -> list[tuple[int, int]]:
    """Sentences of ``text[start:end]``; a comment right after a sentence's end belongs to it."""
    cuts = [start]
    for m in SENTENCE_END.finditer(blank, start, end):
        cut = m.end()
        trailing = re.match(r"\s*(<!--.*?-->\s*)+", text[cut:end], re.DOTALL)
        cuts.append(cut + (trailing.end() if trailing else 0))
    cuts.append(end)
    return [(a, b) for a, b in zip(cuts, cuts[1:], strict=False) if text[a:b].strip()]


def share_words(numeric: str) -> list[tuple[re.Match, tuple[float, float, float]]]:
    """The share words of a sentence (``mslab.claims.FRACTIONS``), with (nominal, lo, hi); a
    "half" after a bound ("less than half", "more than half the limit") is a share too."""
    found = [(m, share) for pattern, share in FRACTION for m in pattern.finditer(numeric)]
    half = (0.5, *share_range(0.5))
    found += [(m, half) for m in HALF.finditer(numeric)
              if (ABOVE.search(numeric[:m.start()]) or BELOW.search(numeric[:m.start()]))
              and not any(f.start() <= m.start() < f.end() for f, _ in found)]
    return sorted(found, key=lambda f: f[0].start())


def _outside(m: re.Match, spans: list[tuple[re.Match, object]]) -> bool:
    return not any(f.start() < m.end() and m.start() < f.end() for f, _ in spans)


def _needs_backing(numeric: str) -> bool:
    return bool(numbers_in(numeric) or VERDICT.search(numeric) or share_words(numeric)
                or any(p.search(numeric) for p, _ in MAGNITUDE))


def share_problems(numeric: str, claims: list[Printed]) -> list[str]:
    """The share words of one sentence that no printed share (0-1, or a percent) makes true."""
    shares = tuple(v for p in claims for v in p.shares)
    problems = []
    for m, (nominal, lo, hi) in share_words(numeric):
        bound = Number(nominal, 0.0, 0, 0, "")
        before, after = numeric[:m.start()], numeric[m.end():]
        if ABOVE.search(before) or re.match(OF_WHAT + OR_MORE.pattern, after, re.IGNORECASE):
            ok, meaning = fits("above", bound, None, shares), f"above {nominal:.3g}"
        elif BELOW.search(before) or re.match(OF_WHAT + OR_LESS.pattern, after, re.IGNORECASE):
            ok, meaning = fits("below", bound, None, shares), f"below {nominal:.3g}"
        else:
            ok, meaning = fits("magnitude", None, (lo, hi), shares), f"in {lo:.3g}-{hi:.3g}"
        if not ok:
            problems.append(f"'{m.group(0)}' (a share {meaning}, printed as a ratio or a %): "
                            f"no printed value fits")
    return problems


def claims_of(nb: nbformat.NotebookNode) -> tuple[set[str], dict[str, Printed]]:
    """IDs that code cells define, and the stored claims that hold, by ID."""
    defined, holding = set(), {}
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        defined |= set(CLAIM_ID.findall(cell.source))
        for out in cell.get("outputs", []):
            if out.get("output_type") == "stream":
                holding.update((p.id, p) for p in parse_printed(out.get("text", "")))
    return defined | set(holding), holding


def _root(word: str) -> str:
    word = word.lower()
    return re.sub(r"(?:s|ed|ing)$", "", word) if len(word) > 5 else word


def disagreements(numeric: str, claims: list[Printed]) -> list[str]:
    """What of one sentence (its numeric view) the printed claims do not carry."""
    numeric = normalise(numeric)
    values = tuple(v for p in claims for v in p.values)
    statements = " ".join(p.statement.lower() for p in claims)
    problems, numbers, used = [], numbers_in(numeric), set()
    for i, n in enumerate(numbers):
        if i in used:
            continue
        before = numeric[:n.start]
        nxt = numbers[i + 1] if i + 1 < len(numbers) else None
        gap = numeric[n.end:nxt.start] if nxt else ""
        between = re.search(r"between\s*$", before, re.I) and gap.strip() == "and"
        if nxt and (RANGE_JOIN.fullmatch(gap) or between):
            used.add(i + 1)
            lo, hi = in_base(n, numeric, nxt.end), in_base(nxt, numeric, nxt.end)
            ok = fits("range", None, (lo.value - lo.half_ulp, hi.value + hi.half_ulp),
                      comparable(numeric, nxt.end, claims, values))
            label = f"{n.text}-{nxt.text}"
        else:
            after = numeric[n.end:n.end + 20]
            kind = ("above" if ABOVE.search(before) or OR_MORE.match(after) else
                    "below" if BELOW.search(before) or OR_LESS.match(after) else
                    "about" if ABOUT.search(before) else "equal")
            ok = fits(kind, in_base(n, numeric, n.end), None, comparable(numeric, n.end, claims, values))
            label = n.text if kind == "equal" else f"{kind} {n.text}"
        if not ok:
            problems.append(f"{label.strip()}: no printed value fits")
    shares = share_words(numeric)
    for pattern, ranges in MAGNITUDE:
        for m in filter(lambda m: _outside(m, shares), pattern.finditer(numeric)):
            before = numeric[:m.start()]
            if ABOVE.search(before):                  # "more than twice": above the range's lower end
                ranges = tuple((lo, float("inf")) for lo, _ in ranges[:1])
            elif BELOW.search(before):                # "less than half": below its upper end
                ranges = tuple((0.0, hi) for _, hi in ranges[-1:])
            if not any(fits("magnitude", None, r, values) for r in ranges):
                problems.append(f"'{m.group(0)}': no printed value in {ranges}")
    for m in filter(lambda m: _outside(m, shares), VERDICT.finditer(numeric)):
        if not re.search(rf"\b{re.escape(_root(m.group(0)))}", statements):
            problems.append(f"'{m.group(0)}' is in no claim's statement")
    return problems + share_problems(numeric, claims)


def _backing(comments: list[re.Match], defined: set[str]) -> tuple[list[str] | None, str | None]:
    """(claim ids, or None for a no-claim) and a problem with the comments, if any."""
    ids = [cid for c in comments if c.group(1) == "claim"
           for cid in filter(None, (s.strip() for s in c.group(2).split(",")))]
    if ids:
        return ids, None
    text = comments[0].group(2)
    reason = re.match(r"[\w-]*", text).group(0)
    words = text[len(reason):]
    if reason not in NO_CLAIM_REASONS:
        return None, f"no-claim reason {reason!r} is not one of {', '.join(NO_CLAIM_REASONS)}"
    named = [cid for cid in defined if re.search(rf"\b{re.escape(cid)}\b", words)]
    return None, (f"no-claim names claims {named}: back the sentence with them" if named else None)


def check_markdown(path: Path, index: int, text: str, defined: set[str],
                   holding: dict[str, Printed]) -> list[Finding]:
    """Findings of one markdown cell."""
    found = []
    for comment in COMMENT.finditer(text):
        problem = _backing([comment], defined)[1]
        if problem:
            found.append(Finding(path, index, f"{comment.group(0)} [{problem}]"))
        if comment.group(1) == "claim":
            for cid in filter(None, (s.strip() for s in comment.group(2).split(","))):
                if cid not in defined:
                    found.append(Finding(path, index, f"claim {cid!r} is named but no code cell defines it"))
                elif cid not in holding:
                    found.append(Finding(path, index, f"claim {cid!r} has no stored 'claim holds' output"))
    blank, numeric = views(text)
    solutions = [m.span() for m in DETAILS.finditer(text)]
    for b0, b1, lead in _blocks(text):
        for s0, s1 in _sentences(text, blank, b0, b1):
            if any(a <= s0 < b for a, b in solutions):
                continue
            comments = list(COMMENT.finditer(text, s0, s1)) or list(COMMENT.finditer(lead or ""))
            sentence = " ".join(text[s0:s1].split())
            if not comments:
                if _needs_backing(numeric[s0:s1]):
                    found.append(Finding(path, index, sentence))
                continue
            ids = _backing(comments, defined)[0]
            if ids:
                claims = [holding[cid] for cid in ids if cid in holding]
                problems = disagreements(numeric[s0:s1], claims) + reversed_comparisons(
                    COMMENT.sub(" ", sentence).replace("`", ""), [c.statement for c in claims])
                found += [Finding(path, index, f"{sentence} [{p}]") for p in problems] if claims else []
    return found


def check_notebook(path: Path) -> list[Finding]:
    """Every unbacked or contradicted sentence and every dangling claim reference of one notebook."""
    nb = nbformat.read(path, as_version=4)
    defined, holding = claims_of(nb)
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
        print(f"{len(findings)} sentence(s) that no claim backs or that their claims do not carry "
              f"(see tools/lessons_check.py's docstring)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
