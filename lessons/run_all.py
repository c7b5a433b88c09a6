"""Re-execute lesson notebooks in place, so their stored outputs match the current library.

Usage (from the repository root)::

    make lessons                                        # the same, for every lesson
    .venv/bin/python lessons/run_all.py                 # every lessons/NN_*.ipynb
    .venv/bin/python lessons/run_all.py lessons/01_euler_taylor.ipynb

Each notebook runs top to bottom in a fresh ``python3`` kernel with ``lessons/`` as the
working directory; cells tagged ``raises-exception`` may raise. The notebook's kernelspec is
written as that kernel's own (name, display name, language) and its ``language_info`` as the
kernel reports it: JupyterLab rewrites either when it differs from the kernel it starts, and
a lesson would then open already modified (``tests/test_lab.py`` checks it in a browser).
Widget state is not stored (its ids are random; a live kernel rebuilds it), so re-runs give
clean diffs. Afterwards check them with nbval (twice, to be sure the outputs are reproducible)::

    .venv/bin/python -m pytest -q -p no:randomly --nbval --nbval-current-env \
        --nbval-sanitize-with lessons/sanitize.cfg lessons/
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import nbformat
from jupyter_client.kernelspec import KernelSpecManager
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parent
KERNEL = "python3"


def kernelspec_metadata(name: str = KERNEL) -> dict:
    """The ``kernelspec`` block JupyterLab writes for kernel ``name`` (stored as is: opens unmodified)."""
    spec = KernelSpecManager().get_kernel_spec(name)
    return {"name": name, "display_name": spec.display_name, "language": spec.language}


def coalesce_streams(outputs: list) -> list:
    """Merge consecutive stdout (or stderr) chunks: how the kernel splits them varies between runs."""
    merged: list = []
    for out in outputs:
        if (out.output_type == "stream" and merged and merged[-1].output_type == "stream"
                and merged[-1].name == out.name):
            merged[-1].text += out.text
        else:
            merged.append(out)
    return merged


def execute(path: Path, timeout: int = 300) -> float:
    """Run one notebook in place; returns the seconds it took."""
    nb = nbformat.read(path, as_version=4)
    nb.metadata["kernelspec"] = kernelspec_metadata()
    start = time.perf_counter()
    for cell in nb.cells:                       # no timestamps: re-runs give clean diffs
        cell.metadata.pop("execution", None)
    NotebookClient(nb, timeout=timeout, kernel_name=KERNEL, record_timing=False,
                   resources={"metadata": {"path": str(path.parent)}}).execute()
    elapsed = time.perf_counter() - start
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = coalesce_streams(cell.outputs)
    nb.metadata.pop("widgets", None)           # widget state has random ids; a live kernel rebuilds it
    missing = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.execution_count is None]
    if missing:
        raise RuntimeError(f"{path.name}: code cells {missing} have no execution count")
    nbformat.write(nb, path)
    return elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path,
                        help="notebooks to run (default: every lessons/NN_*.ipynb)")
    parser.add_argument("--timeout", type=int, default=300, help="seconds per cell")
    args = parser.parse_args(argv)
    paths = args.notebooks or sorted(HERE.glob("[0-9][0-9]_*.ipynb"))
    for path in paths:
        elapsed = execute(path, args.timeout)
        print(f"{path}: executed in {elapsed:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
