"""docs/extending.md, followed literally: each integrator example in one file, picked up everywhere.

The Python blocks of the section "Adding an integrator" are written into a temporary folder
added to ``mslab.integrators.__path__``; ``discover()`` imports them as a new file in the
package would be imported. Then the registry-wide checks run on the new methods, and the
command line (``mslab stability``, ``mslab run``) and ``mslab.derive.order`` see them.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import mslab
import mslab.integrators as package
from mslab.cli import main
from mslab.integrators import base

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = {"ssprk3": 3, "trapezoidal": 2, "pefrl": 4}


def _integrator_blocks() -> list[str]:
    text = (ROOT / "docs" / "extending.md").read_text()
    section = text[text.index("## Adding an integrator"):text.index("## Adding an effect")]
    return re.findall(r"```python\n(.*?)```", section, re.S)


@pytest.fixture(scope="module")
def examples(tmp_path_factory):
    folder = tmp_path_factory.mktemp("more_methods")
    blocks = _integrator_blocks()
    assert len(blocks) == 3
    for block in blocks:
        name = re.search(r'name="(\w+)"', block).group(1)
        (folder / f"{name}.py").write_text(block)
    old_path = list(package.__path__)
    package.__path__.append(str(folder))
    try:
        found = package.discover()
        assert sorted(found) == sorted(EXAMPLES)
        yield {name: mslab.get_method(name) for name in EXAMPLES}
    finally:
        package.__path__[:] = old_path
        for name in EXAMPLES:
            base._REGISTRY.pop(name, None)
            sys.modules.pop(f"mslab.integrators.{name}", None)


def test_examples_are_registered_with_their_families(examples):
    assert {n: m.family for n, m in examples.items()} == {
        "ssprk3": "explicit_rk", "trapezoidal": "implicit_rk", "pefrl": "splitting"}
    assert set(EXAMPLES) <= set(mslab.methods())


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_derived_order_is_the_declared_one(examples, name):
    assert mslab.derive.order(name) == EXAMPLES[name] == examples[name].order


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_registry_wide_checks(examples, name):
    from tests import test_fast, test_integrators, test_stability

    for gamma in (0.0, 0.4):
        test_integrators.test_convergence_order_on_oscillator(name, gamma)
    test_integrators.test_force_evaluations_are_counted_per_stage(name)
    test_integrators.test_step_mutates_nothing_and_pinned_never_move(name)
    test_stability.test_measured_map_equals_theory(name)
    if examples[name].compiled is not None:
        for scene_name in test_fast.SCENES:
            test_fast.test_trajectory_equals_numpy_path(scene_name, name)


def test_stability_limits_from_the_coefficients(examples):
    from mslab import stability as st

    # every 3-stage, order-3 tableau has R = 1 + z + z^2/2 + z^3/6: imaginary limit sqrt(3)
    assert st.imag_limit("ssprk3") == pytest.approx(np.sqrt(3.0), abs=1e-9)
    assert examples["trapezoidal"].a_stable and st.real_interval("trapezoidal") == -np.inf
    z = np.array([-1.0 + 2.0j, 0.5j, -3.0])
    np.testing.assert_allclose(st.amplification("trapezoidal", z), (1 + z / 2) / (1 - z / 2), rtol=1e-13)
    assert 0 < st.oscillator_limit("pefrl") < 4


def test_command_line_sees_the_new_methods(examples, capsys):
    assert main(["stability", "ssprk3", "trapezoidal", "pefrl", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    text = json.dumps(rows)
    for name in EXAMPLES:
        assert name in text
    assert main(["run", "pendulum", "--method", "pefrl", "--t-end", "0.5", "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    assert "pefrl" in json.dumps(run) and run["stats"]["steps"] > 0


# -- the page itself: its files are clean code, and it names what the code accepts ------------------
def _saved_files() -> list[tuple[str, str]]:
    """``(path, code)`` of every "Save as `mslab/...py`" block of the page."""
    text = (ROOT / "docs" / "extending.md").read_text()
    found = re.findall(r"Save\s+(?:this\s+)?as\s+`(mslab/[\w/]+\.py)`.*?```python\n(.*?)```", text, re.S)
    assert [p for p, _ in found] == ["mslab/integrators/ssprk3.py", "mslab/integrators/trapezoidal.py",
                                     "mslab/integrators/pefrl.py", "mslab/effects/loads.py"]
    return found


@pytest.mark.parametrize("path", [p for p, _ in _saved_files()])
def test_each_example_file_is_ruff_clean_where_it_is_saved(path):
    import subprocess

    pytest.importorskip("ruff")
    code = dict(_saved_files())[path]
    command = [sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise",
               "--stdin-filename", path, "-"]
    done = subprocess.run(command, input=code, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_page_names_what_the_code_accepts():
    import dataclasses

    from mslab.effects.base import BuildContext
    from mslab.effects.schema import Key

    text = (ROOT / "docs" / "extending.md").read_text()
    with pytest.raises(ValueError) as info:
        mslab.ImplicitRK([[1]], [1], solver="nope")
    options = re.findall(r"'(\w+)'", str(info.value).split(", got")[0])
    assert options == ["newton", "fixed_point", "linearised"]
    for option in options:
        assert f'`"{option}"`' in text
    table = text[text.index("| field | meaning |"):]
    table = table[:table.index("\n\n")]
    for field in dataclasses.fields(Key):
        assert f"`{field.name}`" in table, field.name
    context = [f.name for f in dataclasses.fields(BuildContext)] + ["n_particles"]
    for attribute in context:
        assert f"`ctx.{attribute}`" in text, attribute
    for method in ("force_and_power", "kernel_items", "kernel_params", "compiled_jacobians"):
        assert f"`{method}(" in text, method
    assert "leading zero drift" in text and "make docs" in text
