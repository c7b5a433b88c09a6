"""A sweep decides its backend once, from the cost of all its runs (issue 21)."""

import numpy as np

import mslab
from mslab.fast import AUTO_SECONDS, numpy_seconds
from mslab.fast.job import job_backends


def test_many_short_runs_together_take_the_compiled_loop():
    scene = mslab.load_scene("chain")
    rk4 = mslab.get_method("rk4")
    steps = 50
    one = numpy_seconds(scene.system, rk4, steps)
    n_runs = int(AUTO_SECONDS / one) + 2          # no run alone repays loading, all together do
    assert one < AUTO_SECONDS < n_runs * one
    assert job_backends(scene.system, [(rk4, steps)]) == ["numpy"]
    assert job_backends(scene.system, [(rk4, steps)] * n_runs) == ["numba"] * n_runs
    # the same job on the numpy or numba backend, asked by name, is kept as asked
    assert job_backends(scene.system, [(rk4, steps)] * n_runs, "numpy") == ["numpy"] * n_runs
    assert job_backends(scene.system, [(rk4, steps)], "numba") == ["numba"]


def test_methods_without_a_compiled_loop_stay_numpy_in_a_compiled_job():
    scene = mslab.load_scene("chain")
    rk4, fms = mslab.get_method("rk4"), mslab.get_method("fast_mass_spring")
    runs = [(rk4, 10**6), (fms, 10)]
    assert job_backends(scene.system, runs) == ["numba", "numpy"]


def test_work_precision_sweep_on_the_default_backend_runs_compiled(monkeypatch):
    monkeypatch.delenv("MSLAB_BACKEND", raising=False)
    scene = mslab.load_scene("chain")
    dts = [scene.settings.t_end / n for n in (400, 800, 1600, 3200, 6400, 12800)]
    records = mslab.precision.work_precision(scene, ["rk4"], dts, timing=False)
    assert {r["backend"] for r in records} == {"numba"}
    numpy = mslab.precision.work_precision(scene, ["rk4"], dts[:2], timing=False, backend="numpy")
    assert {r["backend"] for r in numpy} == {"numpy"}
    # the same runs: equal counts, and errors equal up to the round-off the two codes may
    # accumulate differently (a few ulps of the scene's extent per stage of every step)
    extent = float(abs(scene.state0.x).max())
    for a, b in zip(records, numpy, strict=False):
        assert (a["n_force"], a["steps"]) == (b["n_force"], b["steps"])
        roundoff = 4 * a["n_force"] * np.finfo(float).eps * extent
        assert abs(a["error"] - b["error"]) <= roundoff


def test_scipy_curves_get_the_sweeps_backend(monkeypatch):
    """scipy's curves of a compiled sweep get mslab's compiled forces; a numpy sweep keeps numpy's."""
    from mslab.fast.job import rhs_backend
    from mslab.precision.reference import _flat_rhs, _y0

    monkeypatch.delenv("MSLAB_BACKEND", raising=False)
    scene = mslab.load_scene("chain")
    system = scene.system
    assert rhs_backend(system, ["numba", "numpy"]) == "numba"
    assert rhs_backend(system, ["numpy"]) == "numpy" and rhs_backend(system, []) == "numpy"
    assert rhs_backend(system, [], "numba") == "numba" and rhs_backend(system, ["numba"], "numpy") == "numpy"
    # the compiled right-hand side is the same function: equal to the numpy one to round-off
    shape = scene.state0.x.shape
    y = _y0(scene) + 1e-2 * np.random.default_rng(0).normal(size=_y0(scene).shape)
    fast_f, slow_f = _flat_rhs(system, shape, "numba")(0.0, y), _flat_rhs(system, shape)(0.0, y)
    assert np.max(np.abs(fast_f - slow_f)) <= 1e-12 * np.max(np.abs(slow_f))
    dts = [scene.settings.t_end / n for n in (400, 800, 1600, 3200, 6400, 12800)]
    records = mslab.precision.work_precision(scene, ["rk4"], dts, timing=False, scipy_methods=["DOP853"],
                                             rtols=[1e-6])
    scipy = [r for r in records if r["solver"] == "scipy"]
    assert [r["backend"] for r in scipy] == ["numba"] and scipy[0]["ok"]
    plain = mslab.precision.scipy_records(scene, methods=["DOP853"], rtols=[1e-6], timing=False)
    assert [r["backend"] for r in plain] == ["numpy"]
    # the same solver at the same tolerance: its error is set by the tolerance, not by round-off
    assert 0.5 <= scipy[0]["error"] / plain[0]["error"] <= 2.0
