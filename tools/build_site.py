"""Render the course to a static website that works offline: ``make site`` (issue 13, item 6).

The lessons (with their stored figures and animations), the exercises' READMEs and docs/*.md
become HTML pages under ``site/`` with a table of contents on ``site/index.html``. Formulas are
typeset by a local copy of MathJax, never a CDN: Debian's ``libjs-mathjax`` (installed by
``.ci/run``) or the npm package ``mathjax`` version 2 (``npm install mathjax@2`` in the
repository root). Without either the build stops with one line saying how to get one.

Usage (from the repository root)::

    .venv/bin/python tools/build_site.py [--out site]

Open ``site/index.html`` over HTTP (``python -m http.server -d site``): browsers refuse web
fonts from ``file://`` pages, so MathJax's fonts need a server.
"""

from __future__ import annotations

import argparse
import html
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: where a MathJax 2 tree (with MathJax.js at its top) may be found, in this order
NPM_PREFIX = ROOT / ".cache" / "site-npm"
MATHJAX_CANDIDATES = (Path("/usr/share/javascript/mathjax"), ROOT / "node_modules" / "mathjax",
                      NPM_PREFIX / "node_modules" / "mathjax")
MATHJAX_CONFIG = "TeX-AMS_CHTML-full"
#: nbconvert's lab template without its CDN scripts (require.js, widget manager, mermaid)
TEMPLATES = Path(__file__).resolve().parent / "site_template"
#: the parts of MathJax 2 that the CommonHTML output of TeX needs (about 8 MB instead of 54)
MATHJAX_PARTS = ("MathJax.js", f"config/{MATHJAX_CONFIG}.js", "config/Safe.js", "config/local",
                 "extensions", "jax/input/TeX", "jax/output/CommonHTML", "jax/element",
                 "fonts/HTML-CSS/TeX/woff", "localization/en")
EXTERNAL = re.compile(r"<(script|link|img)\b[^>]*\b(src|href)=\"(https?:)?//[^\"]*\"", re.I)
#: matplotlib's ``to_jshtml`` animations style their buttons with Font Awesome from a CDN: the site
#: drops that stylesheet and shows the same buttons as plain characters
FONT_AWESOME = re.compile(r"<link\b[^>]*font-awesome[^>]*>\s*")
ICONS = {"fa-minus": "&minus;", "fa-plus": "+", "fa-fast-backward": "|&#x25C0;",
         "fa-step-backward": "&#x25C1;", "fa-play fa-flip-horizontal": "&#x25C0;",
         "fa-pause": "&#x2759;&#x2759;", "fa-play": "&#x25B6;", "fa-step-forward": "&#x25B7;",
         "fa-fast-forward": "&#x25B6;|"}
WIDGET = "application/vnd.jupyter.widget-view+json"
WIDGET_NOTE = ("<p><em>Here an interactive control (ipywidgets) appears when the notebook runs in "
               "Jupyter; the static version of the same figure follows.</em></p>")
MATH = re.compile(r"\$\$.+?\$\$|\$[^$\n]+?\$", re.S)

#: no favicon request (it would be a 404 in the browser's console)
FAVICON = '<link rel="icon" href="data:,">'
STYLE = """
body { font-family: sans-serif; max-width: 60rem; margin: 0 auto; padding: 0 1rem 3rem; line-height: 1.5; }
nav.site { font-family: sans-serif; padding: 0.6rem 1rem; background: #eef2f6; border-bottom: 1px solid #ccd;
           position: sticky; top: 0; z-index: 10; }
nav.site a { margin-right: 1.2rem; }
pre, code { background: #f5f5f5; }
pre { padding: 0.6rem; overflow-x: auto; }
table { border-collapse: collapse; } td, th { border: 1px solid #ccc; padding: 0.2rem 0.5rem; }
"""


class SiteError(Exception):
    """A build problem to report in one line."""


def _installed_mathjax() -> Path | None:
    for root in MATHJAX_CANDIDATES:
        if (root / "MathJax.js").is_file() and (root / "config" / f"{MATHJAX_CONFIG}.js").is_file():
            return root
    return None


def find_mathjax() -> Path:
    """A MathJax 2 tree: Debian's, a local npm one, or npm's fetched into .cache/ when npm exists.

    SiteError with the remedy when none can be had.
    """
    root = _installed_mathjax()
    if root is None and shutil.which("npm"):
        print("site: no MathJax installed; fetching the npm package mathjax@2 into .cache/site-npm")
        subprocess.run(["npm", "install", "--no-save", "--no-audit", "--no-fund", "--loglevel=error",
                        "--prefix", str(NPM_PREFIX), "mathjax@2"], check=False)
        root = _installed_mathjax()
    if root is not None:
        return root
    raise SiteError("no local MathJax 2 and no npm: install Debian's libjs-mathjax "
                    "(apt-get install libjs-mathjax) or run 'npm install mathjax@2' in the repository root")


def copy_mathjax(source: Path, target: Path) -> None:
    """Copy the parts of MathJax that the pages use (symlinks resolved)."""
    for part in MATHJAX_PARTS:
        src = source / part
        if not src.exists():
            continue
        dst = target / part
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True)
        else:
            shutil.copy2(src, dst)


def mathjax_head(prefix: str) -> str:
    """Script tags loading the local MathJax with the notebook's delimiters ($...$, $$...$$)."""
    return f"""<script type="text/x-mathjax-config">
MathJax.Hub.Config({{tex2jax: {{inlineMath: [['$','$'], ['\\\\(','\\\\)']],
  displayMath: [['$$','$$'], ['\\\\[','\\\\]']], processEscapes: true}}, messageStyle: 'none'}});
</script>
<script src="{prefix}mathjax/MathJax.js?config={MATHJAX_CONFIG},Safe"></script>"""


def nav(prefix: str, title: str) -> str:
    return (f'<nav class="site"><a href="{prefix}index.html">mslab course: contents</a>'
            f"<span>{html.escape(title)}</span></nav>")


def markdown_page(text: str, title: str, prefix: str) -> str:
    """A markdown file as a page; formulas are kept away from the markdown parser."""
    import mistune

    spans: list[str] = []

    def keep(match: re.Match) -> str:
        spans.append(match.group(0))
        return f"MATHSPAN{len(spans) - 1}X"

    body = mistune.create_markdown(plugins=["table", "strikethrough", "url"])(MATH.sub(keep, text))
    body = re.sub(r"MATHSPAN(\d+)X", lambda m: html.escape(spans[int(m.group(1))], quote=False), body)
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">{FAVICON}"
            f"<title>{html.escape(title)}</title><link rel=\"stylesheet\" href=\"{prefix}style.css\">"
            f"{mathjax_head(prefix)}</head>\n"
            f"<body>{nav(prefix, title)}\n<main>{body}</main></body></html>\n")


def notebook_page(path: Path, title: str) -> str:
    """A lesson rendered by nbconvert's lab template with its stored outputs, local MathJax only."""
    import nbformat
    from nbconvert import HTMLExporter

    exporter = HTMLExporter(template_name="offline", extra_template_basedirs=[str(TEMPLATES)])
    exporter.mathjax_url = f"../mathjax/MathJax.js?config={MATHJAX_CONFIG},Safe"
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:                       # widgets need a live kernel: say so in their place
        for out in cell.get("outputs", []):
            if WIDGET in out.get("data", {}):
                out["data"] = {"text/html": WIDGET_NOTE}
    page, _ = exporter.from_notebook_node(nb)
    page = FONT_AWESOME.sub("", page)
    for name, glyph in ICONS.items():
        page = page.replace(f'<i class="fa {name}"></i>', f"<span>{glyph}</span>")
    if match := EXTERNAL.search(page):
        raise SiteError(f"{path.name}: the page would load from the network: {match.group(0)[:120]}")
    page = page.replace("</head>", f'{FAVICON}<link rel="stylesheet" href="../style.css"></head>', 1)
    return re.sub(r"(<body[^>]*>)", lambda m: m.group(1) + nav("../", title), page, count=1)


def first_heading(text: str, default: str) -> str:
    match = re.search(r"^#\s+(.+)$", text, re.M)
    return match.group(1).strip() if match else default


def build(out: Path) -> list[Path]:
    """Write the whole site into ``out`` (replaced); returns the HTML pages written."""
    import nbformat

    mathjax = find_mathjax()
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    copy_mathjax(mathjax, out / "mathjax")
    (out / "style.css").write_text(STYLE)
    sections: dict[str, list[tuple[str, str]]] = {"Lessons": [], "Exercises": [], "Documentation": []}
    pages = []
    for nb_path in sorted((ROOT / "lessons").glob("[0-9][0-9]_*.ipynb")):
        nb = nbformat.read(nb_path, as_version=4)
        text = next((c.source for c in nb.cells if c.cell_type == "markdown"), "")
        title = first_heading(text, nb_path.stem)
        target = out / "lessons" / f"{nb_path.stem}.html"
        target.parent.mkdir(exist_ok=True)
        target.write_text(notebook_page(nb_path, title), encoding="utf-8")
        sections["Lessons"].append((f"lessons/{target.name}", title))
        pages.append(target)
    markdown = [("Exercises", p, "exercises", p.parent.name)
                for p in sorted((ROOT / "exercises").glob("*/README.md"))]
    markdown += [("Documentation", p, "docs", p.stem) for p in sorted((ROOT / "docs").glob("*.md"))]
    for section, md_path, folder, stem in markdown:
        text = md_path.read_text(encoding="utf-8")
        title = first_heading(text, stem)
        target = out / folder / f"{stem}.html"
        target.parent.mkdir(exist_ok=True)
        target.write_text(markdown_page(text, title, "../"), encoding="utf-8")
        sections[section].append((f"{folder}/{target.name}", title))
        pages.append(target)
    toc = "\n".join(f"<h2>{name}</h2>\n<ol>\n" + "\n".join(
        f'<li><a href="{href}">{html.escape(title)}</a></li>' for href, title in entries) + "\n</ol>"
        for name, entries in sections.items())
    index = out / "index.html"
    heading = "<h1>mslab: mass-spring simulation course</h1>"
    page = markdown_page("", "mslab course", "").replace("<main></main>", f"<main>{heading}\n{toc}</main>")
    index.write_text(page, encoding="utf-8")
    return [index, *pages]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "site", help="output folder (replaced)")
    args = parser.parse_args(argv)
    try:
        pages = build(args.out)
    except SiteError as err:
        print(f"site: {err}", file=sys.stderr)
        return 1
    print(f"site: {len(pages)} pages in {args.out}/ (open {args.out}/index.html over HTTP)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
