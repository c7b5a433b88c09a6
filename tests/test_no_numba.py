"""mslab without numba and cvxopt (issue 39): ``auto`` falls back to numpy, ``numba`` says what is missing.

Each case runs in a subprocess whose import system refuses numba and cvxopt (a ``sys.meta_path``
finder), as on a machine where they are not installed; ``make test-minimal`` runs the suite's
chosen tests in a venv that really lacks them.
"""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mslab
from mslab import jit
from mslab.scenes import generators

BLOCK = """
import importlib.abc, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in ("numba", "cvxopt"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, Block())
"""


def _without_numba(code: str) -> dict:
    """Run ``code`` (which sets ``out``, a JSON-able dict) where numba and cvxopt cannot be imported."""
    script = BLOCK + textwrap.dedent(code) + "\nimport json; print(json.dumps(out))\n"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_auto_falls_back_to_numpy_with_one_notice():
    out = _without_numba("""
        import warnings
        import mslab
        from mslab.scenes import generators
        cloth = generators.cloth(64, 64)  # long enough that auto compiles where numba is there
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            sims = [mslab.Simulation(cloth, "symplectic_euler", dt=1e-4, t_end=1.0, check_stability=False)
                    for _ in range(2)]
            for sim in sims:
                sim.advance(3)
        out = {"compiled": [s.compiled for s in sims], "numba": "numba" in __import__("sys").modules,
               "notes": [str(w.message) for w in seen if w.category is mslab.errors.PerformanceWarning],
               "x": sims[0].state.x.tolist()}
    """)
    assert out["compiled"] == [False, False] and not out["numba"]
    assert len(out["notes"]) == 1 and "numba is not installed" in out["notes"][0]
    assert "slower" in out["notes"][0]  # what it costs
    cloth = generators.cloth(64, 64)
    if jit.available():  # here (not in make test-minimal's venv) the same session compiles
        assert mslab.Simulation(cloth, "symplectic_euler", dt=1e-4, t_end=1.0, check_stability=False).compiled
    here = mslab.Simulation(cloth, "symplectic_euler", dt=1e-4, t_end=1.0, backend="numpy",
                            check_stability=False)
    here.advance(3)
    np.testing.assert_array_equal(np.array(out["x"]), here.state.x)  # the numpy loop, bitwise


def test_backend_numba_without_numba_is_one_clear_error():
    out = _without_numba("""
        import mslab
        try:
            mslab.simulate(mslab.load_scene("chain"), "rk4", t_end=0.01, backend="numba")
            out = {"error": None}
        except ModuleNotFoundError as err:
            out = {"error": str(err)}
    """)
    assert out["error"] is not None and "pip install numba" in out["error"]
    assert "backend='numpy'" in out["error"]


@pytest.mark.parametrize("method", ["fast_mass_spring"])
def test_numpy_path_needs_neither_numba_nor_cvxopt(method):
    """fast_mass_spring's local step (a compiled kernel) runs as plain Python without numba: the same run."""
    out = _without_numba(f"""
        import mslab
        tr = mslab.simulate(mslab.load_scene("chain"), {method!r}, dt=0.01, t_end=0.5, backend="auto")
        out = {{"x": tr.x[-1].tolist()}}
    """)
    here = mslab.simulate(mslab.load_scene("chain"), method, dt=0.01, t_end=0.5, backend="numpy")
    np.testing.assert_allclose(np.array(out["x"]), here.x[-1], rtol=0, atol=1e-10)


def test_sweeps_fall_back_to_numpy():
    """A job long enough to compile (a convergence study, an energy-drift comparison, a work-precision
    diagram) steps numpy without numba, with one notice (it asked for the compiled loop before)."""
    out = _without_numba("""
        import warnings
        import mslab
        from mslab.fast.job import job_backends, rhs_backend
        from mslab.precision import energy_drift
        from mslab.scenes import chain
        scene = chain()
        runs = [(mslab.get_method("rk4"), 10**6)]
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            backends = job_backends(scene.system, runs)
            drift = energy_drift(scene, ["symplectic_euler"], dt=1e-3, t_end=0.05, n_save=10, warm_up=False)
        out = {"backends": backends, "rhs": rhs_backend(scene.system, backends),
               "notes": [str(w.message) for w in seen if w.category is mslab.errors.PerformanceWarning],
               "error": drift["symplectic_euler"].error.tolist()}
    """)
    assert out["backends"] == ["numpy"] and out["rhs"] == "numpy"
    assert len(out["notes"]) == 1 and "numba is not installed" in out["notes"][0]
    from mslab.precision import energy_drift
    from mslab.scenes import chain
    numpy = energy_drift(chain(), ["symplectic_euler"], dt=1e-3, t_end=0.05, n_save=10, warm_up=False,
                         backend="numpy")
    assert out["error"] == numpy["symplectic_euler"].error.tolist()  # the numpy loop's run, bit for bit


NEEDS_NUMBA = {"03_verlet_leapfrog", "04_implicit_euler", "06_energy_drift", "07_work_precision"}


def test_a_lesson_that_needs_numba_says_so_in_its_first_cell():
    """Measured in a venv without numba (README, "mslab without numba"): every other lesson passes there
    within its 60 s; these four time the compiled loop (``backend="numba"``), or run long or chaotic
    runs whose stored outputs are the compiled loop's. Each says so in its first cell, and a lesson
    that asks for ``backend="numba"`` in code must be one of them."""
    from pathlib import Path

    for path in sorted((Path(__file__).resolve().parents[1] / "lessons").glob("[0-9][0-9]_*.ipynb")):
        cells = [("".join(c["source"]), c["cell_type"]) for c in json.loads(path.read_text())["cells"]]
        says = "**Needs numba**" in cells[0][0]
        asks = any('backend="numba"' in source for source, kind in cells if kind == "code")
        assert says == (path.stem in NEEDS_NUMBA), path.stem
        assert says or not asks, f"{path.stem} asks for backend='numba' without saying it needs numba"
