"""Common student mistakes, planted in copies of the reference solutions (issue 36, item 6).

Each :class:`Mistake` is the reference file of one exercise with a few definitions appended
that redefine a function the way a student commonly gets it wrong. ``fails`` lists the
tests that must fail (and only those: every other test of the exercise keeps its points),
``maybe`` the tests on inputs drawn at grading time that fail for some draws only, and
``named`` the public tests whose one-line reason must name the mistake, with the words
that must appear (``P:name`` is ``test_public.py::name``, ``H:name`` ``test_hidden.py::name``).
Used by ``tests/test_exercise_feedback.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Mistake:
    """One planted mistake: the exercise, how its solution is changed, what must fail.

    ``code`` is appended to the solution (definitions that replace the right ones), or is a
    tuple of ``(right, wrong)`` lines swapped in it.
    """

    name: str
    exercise: str
    module: str
    code: str | tuple[tuple[str, str], ...]
    fails: frozenset[str]
    named: dict[str, str] = field(default_factory=dict)
    maybe: frozenset[str] = frozenset()

    def text(self, source: Path) -> str:
        """The reference file of the exercise in ``source`` with this mistake planted."""
        text = (source / self.exercise / self.module).read_text()
        if isinstance(self.code, str):
            return text + "\n" + self.code
        for right, wrong in self.code:
            assert right in text, (self.name, right)
            text = text.replace(right, wrong)
        return text


def _m(name: str, exercise: str, module: str, code: str | tuple, fails: set[str], named: dict | None = None,
       maybe: set[str] | None = None) -> Mistake:
    def full(test: str) -> str:
        return test.replace("P:", "test_public.py::", 1).replace("H:", "test_hidden.py::", 1)

    drawn = {t for t in fails if t.endswith("drawn_at_grading")} | (maybe or set())
    return Mistake(name, exercise, module, code, frozenset(map(full, fails)),
                   {full(t): words for t, words in (named or {}).items()}, frozenset(map(full, drawn)))


E01, M01 = "01_spring_force", "spring_force.py"
E02, M02 = "02_euler_steps", "euler_steps.py"
E03, M03 = "03_heun_midpoint", "heun_midpoint.py"
E04, M04 = "04_rk4_tableau", "rk_tableau.py"
E05, M05 = "05_verlet_leapfrog", "verlet_leapfrog.py"
E06, M06 = "06_implicit_euler", "implicit_euler.py"
E07, M07 = "07_stability_function", "stability_function.py"
E08, M08 = "08_penalty_collision", "penalty_collision.py"
E09, M09 = "09_energy_ledger", "energy_ledger.py"
E10, M10 = "10_cheapest_method", "cheapest_method.py"
E11, M11 = "11_shear_bend_springs", "cloth_springs.py"
E12, M12 = "12_own_method", "own_method.py"

_PAIR_01 = "pair = (stiffness * (rest_length - length) / length)[:, None] * d"
_BLOCK_01 = "block = -k * (uu + (1.0 - rest / length) * (eye - uu))"
_NEWTON_06 = "np.linalg.solve(eye - dt * (dt * K + D), -g.ravel())"
_N06 = {"P:test_newton_solves_a_stiff_step", "H:test_newton_matches_the_library_with_drag",
        "H:test_newton_needs_few_iterations", "H:test_newton_damps_a_stiff_oscillation",
        "H:test_newton_on_a_chain_drawn_at_grading"}
_I07 = {"P:test_euler_and_heun_intervals_end_at_minus_two", "H:test_rk3_and_rk4_intervals",
        "H:test_interval_of_a_damped_euler_variant", "H:test_interval_of_a_tableau_drawn_at_grading"}
_F01 = {"P:test_single_stretched_spring", "P:test_forces_of_a_small_net",
        "P:test_internal_forces_sum_to_zero", "H:test_forces_in_3d_with_shared_particles",
        "H:test_force_is_minus_energy_gradient", "H:test_random_net_drawn_at_grading"}
_J01 = {"P:test_jacobian_by_finite_differences", "H:test_jacobian_matches_the_library",
        "H:test_jacobian_is_symmetric", "H:test_random_net_drawn_at_grading"}

MISTAKES: list[Mistake] = [
    _m("01 force sign", E01, M01,
       ((_PAIR_01, _PAIR_01.replace("(rest_length - length)", "(length - rest_length)")),), _F01,
       {"P:test_single_stretched_spring": "the sign"}),
    _m("01 direction not normalised", E01, M01,
       ((_PAIR_01, _PAIR_01.replace(" / length", "")),), _F01,
       {"P:test_single_stretched_spring": "unit vector"}),
    _m("01 no reaction on j", E01, M01,
       (("np.add.at(f, j, -pair)", "np.add.at(f, j, 0 * pair)"),),
       _F01, {"P:test_single_stretched_spring": "opposite force on j"}),
    _m("01 Jacobian without the geometric term", E01, M01,
       ((_BLOCK_01, "block = -k * uu"),), _J01,
       {"P:test_jacobian_by_finite_differences": "(1 - L/l)(I - u u^T) of a stretched spring is missing"}),
    _m("01 Jacobian sign", E01, M01,
       ((_BLOCK_01, _BLOCK_01.replace("-k", "k")),), _J01,
       {"P:test_jacobian_by_finite_differences": "the sign of K"}),

    _m("02 symplectic Eulers swapped", E02, M02,
       "\n_a, _b = symplectic_euler_step, symplectic_euler_x_step\n"
       "symplectic_euler_step, symplectic_euler_x_step = _b, _a\n",
       {"P:test_symplectic_euler_matches_the_library",
        "P:test_symplectic_euler_x_matches_the_library",
        "H:test_symplectic_eulers_keep_the_energy_bounded",
        "H:test_all_three_on_a_chain_drawn_at_grading"},
       {"P:test_symplectic_euler_matches_the_library": "symplectic Eulers are swapped",
        "P:test_symplectic_euler_x_matches_the_library": "symplectic Eulers are swapped"}),
    _m("02 forward Euler moves x with the new v", E02, M02,
       "\ndef forward_euler_step(x, v, accel, dt):\n    v_new = v + dt * accel(x, v)\n"
       "    return x + dt * v_new, v_new\n",
       {"P:test_forward_euler_on_an_oscillator",
        "H:test_forward_euler_with_drag_matches_the_library",
        "H:test_forward_euler_gains_energy_every_step",
        "H:test_all_three_on_a_chain_drawn_at_grading"},
       {"P:test_forward_euler_on_an_oscillator": "new velocity"}),
    _m("02 step returns the old state", E02, M02,
       "\ndef symplectic_euler_step(x, v, accel, dt):\n    return x.copy(), v.copy()\n",
       {"P:test_symplectic_euler_matches_the_library",
        "H:test_symplectic_eulers_keep_the_energy_bounded",
        "H:test_all_three_on_a_chain_drawn_at_grading"},
       {"P:test_symplectic_euler_matches_the_library": "old state"}),

    _m("03 Heun and midpoint swapped", E03, M03,
       "\n_a, _b = heun_step, midpoint_step\nheun_step, midpoint_step = _b, _a\n",
       {"P:test_heun_on_a_swinging_spring", "P:test_heun_matches_the_library",
        "P:test_midpoint_matches_the_library", "H:test_both_in_3d_with_velocities",
        "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_heun_on_a_swinging_spring": "midpoint method's step",
        "P:test_heun_matches_the_library": "midpoint method's step",
        "P:test_midpoint_matches_the_library": "Heun's step"}),
    _m("03 midpoint slope with the old velocity", E03, M03,
       "\ndef midpoint_step(x, v, accel, dt):\n    a = accel(x, v)\n"
       "    x_mid, v_mid = x + 0.5 * dt * v, v + 0.5 * dt * a\n"
       "    return x + dt * v_mid, v + dt * accel(x_mid, v)\n",
       {"P:test_midpoint_matches_the_library", "H:test_both_in_3d_with_velocities",
        "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_midpoint_matches_the_library": "half-step velocity"}),
    _m("03 midpoint slope at the end of the step", E03, M03,
       "\ndef midpoint_step(x, v, accel, dt):\n    a = accel(x, v)\n"
       "    x_end, v_end = x + dt * v, v + dt * a\n"
       "    return x + dt * v_end, v + dt * accel(x_end, v_end)\n",
       {"P:test_midpoint_matches_the_library", "H:test_midpoint_is_second_order",
        "H:test_both_in_3d_with_velocities", "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_midpoint_matches_the_library": "end of the step"}),
    _m("03 Heun with the predicted slope only", E03, M03,
       "\ndef heun_step(x, v, accel, dt):\n    a = accel(x, v)\n"
       "    x_p, v_p = x + dt * v, v + dt * a\n"
       "    return x + dt * v_p, v + dt * accel(x_p, v_p)\n",
       {"P:test_heun_on_a_swinging_spring", "P:test_heun_matches_the_library",
        "H:test_heun_is_second_order", "H:test_both_in_3d_with_velocities",
        "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_heun_on_a_swinging_spring": "only the slope at the predicted end",
        "P:test_heun_matches_the_library": "only the slope at the predicted end"}),

    _m("04 RK4 weights misordered", E04, M04,
       "\n_t = rk4_tableau\ndef rk4_tableau():\n    A, b, c = _t()\n"
       "    return A, np.array([1.0, 1.0, 2.0, 2.0]) / 6.0, c\n",
       {"P:test_rk4_tableau_reproduces_the_stages_of_the_course",
        "H:test_student_rk4_tableau_drives_the_library"},
       {"P:test_rk4_tableau_reproduces_the_stages_of_the_course": "weights misordered"}),
    _m("04 RK4 weights 1/4 each", E04, M04,
       "\n_t = rk4_tableau\ndef rk4_tableau():\n    A, b, c = _t()\n    return A, np.full(4, 0.25), c\n",
       {"P:test_rk4_tableau_reproduces_the_stages_of_the_course",
        "H:test_student_rk4_tableau_drives_the_library"},
       {"P:test_rk4_tableau_reproduces_the_stages_of_the_course": "equal weights"}),
    _m("04 position slope is the old velocity", E04, M04,
       (("kx.append(vi)", "kx.append(v)"),),
       {"P:test_rk_step_with_rk4_matches_the_library",
        "P:test_rk_step_with_euler_and_heun_tableaux",
        "H:test_rk4_through_the_stepper_is_fourth_order", "H:test_any_five_stage_tableau",
        "H:test_a_tableau_drawn_at_grading"},
       {"P:test_rk_step_with_rk4_matches_the_library": "stage's own velocity",
        "P:test_rk_step_with_euler_and_heun_tableaux": "stage's own velocity"}),
    _m("04 stages without h", E04, M04,
       (("xi = x + dt * sum", "xi = x + sum"), ("vi = v + dt * sum", "vi = v + sum")),
       {"P:test_rk_step_with_rk4_matches_the_library",
        "P:test_rk_step_with_euler_and_heun_tableaux",
        "H:test_rk4_through_the_stepper_is_fourth_order", "H:test_any_five_stage_tableau",
        "H:test_a_tableau_drawn_at_grading"},
       {"P:test_rk_step_with_rk4_matches_the_library": "times h"}),

    _m("05 Verlet start without h^2/2 a", E05, M05,
       "\ndef verlet_start(x0, v0, accel, dt):\n    return x0 - dt * v0\n",
       {"P:test_verlet_start_is_the_backward_taylor_step", "H:test_starts_drawn_at_grading"},
       {"P:test_verlet_start_is_the_backward_taylor_step": "h^2/2 a term is missing"}),
    _m("05 leapfrog start a whole step", E05, M05,
       "\ndef leapfrog_start(x0, v0, accel, dt):\n    return v0 + dt * accel(x0)\n",
       {"P:test_leapfrog_start_is_half_an_euler_step", "H:test_starts_drawn_at_grading"},
       {"P:test_leapfrog_start_is_half_an_euler_step": "whole Euler step"}),
    _m("05 Verlet step with h, not h^2", E05, M05,
       "\ndef verlet_step(x, x_prev, accel, dt):\n    return 2.0 * x - x_prev + dt * accel(x)\n",
       {"P:test_verlet_steps_match_the_library",
        "H:test_verlet_and_leapfrog_give_the_same_positions", "H:test_verlet_is_second_order",
        "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_verlet_steps_match_the_library": "h^2 a(x_n)"}),
    _m("05 leapfrog kick at the old position", E05, M05,
       "\ndef leapfrog_step(x, v_half, accel, dt):\n    return x + dt * v_half, v_half + dt * accel(x)\n",
       {"P:test_leapfrog_steps_match_the_library",
        "H:test_verlet_and_leapfrog_give_the_same_positions",
        "H:test_leapfrog_stays_bounded_near_its_limit", "H:test_both_on_a_chain_drawn_at_grading"},
       {"P:test_leapfrog_steps_match_the_library": "new position"}),

    _m("06 Newton matrix without the damping term", E06, M06,
       ((_NEWTON_06, _NEWTON_06.replace("(dt * K + D)", "dt * K")),),
       {"P:test_newton_solves_a_stiff_step"},
       {"P:test_newton_solves_a_stiff_step": "I - h (h K + D)"}),
    _m("06 Newton matrix without h on K", E06, M06,
       ((_NEWTON_06, _NEWTON_06.replace("dt * K + D", "K + D")),),
       _N06, {"P:test_newton_solves_a_stiff_step": "RuntimeError"},
       {"H:test_newton_damps_a_stiff_oscillation"}),  # converges for some drawn k, h
    _m("06 fixed point never gives up", E06, M06,
       "\n_fp = implicit_euler_fixed_point\n"
       "def implicit_euler_fixed_point(x, v, accel, dt, tol=1e-10, max_iter=100):\n"
       "    try:\n        return _fp(x, v, accel, dt, tol, max_iter)\n"
       "    except RuntimeError:\n        return x.copy(), v.copy(), max_iter\n",
       {"P:test_fixed_point_refuses_a_large_step"},
       {"P:test_fixed_point_refuses_a_large_step": "expected RuntimeError, nothing was raised"}),
    _m("06 Newton returns an explicit Euler step", E06, M06,
       "\ndef implicit_euler_newton(x, v, problem, dt, tol=1e-10, max_iter=20):\n"
       "    v_new = v + dt * problem(x, v)\n    return x + dt * v_new, v_new, 1\n", _N06,
       {"P:test_newton_solves_a_stiff_step": "an explicit step"}),

    _m("07 A transposed", E07, M07,
       "\n_sf = stability_function\ndef stability_function(A, b, z):\n"
       "    return _sf(np.asarray(A).T, b, z)\n",
       {"P:test_rk4_is_the_taylor_polynomial", "H:test_any_explicit_tableau_matches_the_stage_recursion",
        "H:test_interval_of_a_tableau_drawn_at_grading",
        # real_stability_interval calls the student's own R: its tests fail too where A is full enough
        "P:test_euler_and_heun_intervals_end_at_minus_two", "H:test_rk3_and_rk4_intervals"},
       {"P:test_rk4_is_the_taylor_polynomial": "A transposed"}),
    _m("07 R without the leading 1", E07, M07,
       "\n_sf = stability_function\ndef stability_function(A, b, z):\n    return _sf(A, b, z) - 1.0\n",
       {"P:test_forward_euler_is_one_plus_z", "P:test_rk4_is_the_taylor_polynomial",
        "H:test_any_explicit_tableau_matches_the_stage_recursion", *_I07},
       {"P:test_forward_euler_is_one_plus_z": "leading 1",
        "P:test_rk4_is_the_taylor_polynomial": "leading 1"}),
    _m("07 interval as a positive length", E07, M07,
       "\n_ri = real_stability_interval\ndef real_stability_interval(A, b, tol=1e-12):\n"
       "    return -_ri(A, b, tol)\n",
       {"P:test_euler_and_heun_intervals_end_at_minus_two", "H:test_rk3_and_rk4_intervals",
        "H:test_interval_of_a_damped_euler_variant", "H:test_interval_of_a_tableau_drawn_at_grading"},
       {"P:test_euler_and_heun_intervals_end_at_minus_two": "negative number"}),
    _m("07 the bracket's end, not bisected", E07, M07,
       "\ndef real_stability_interval(A, b, tol=1e-12):\n    lo = -1.0\n"
       "    while abs(stability_function(A, b, lo)) <= 1.0:\n        lo *= 2.0\n    return float(lo)\n",
       _I07, {"P:test_euler_and_heun_intervals_end_at_minus_two": "not bisected"}),

    _m("08 depth with the wrong sign", E08, M08,
       "\ndef penetration_depth(x, normal, offset):\n    return x @ normal - offset\n",
       {"P:test_depth_is_signed_distance_below_the_plane", "P:test_frictionless_push_is_a_spring",
        "P:test_with_friction_matches_the_library", "H:test_tilted_plane_in_3d_matches_the_library",
        "H:test_normal_force_is_minus_energy_gradient", "H:test_friction_opposes_sliding_and_obeys_coulomb",
        "H:test_a_plane_drawn_at_grading"},
       {"P:test_depth_is_signed_distance_below_the_plane": "the sign"}),
    _m("08 friction along the whole velocity", E08, M08,
       (("vt = v - (v @ normal)[:, None] * normal[None, :]", "vt = v"),),
       {"P:test_with_friction_matches_the_library", "H:test_tilted_plane_in_3d_matches_the_library",
        "H:test_friction_opposes_sliding_and_obeys_coulomb", "H:test_a_plane_drawn_at_grading"},
       {"P:test_with_friction_matches_the_library": "tangential"}),
    _m("08 force outside the wall too", E08, M08,
       (("fn = np.where(active, stiffness * depth, 0.0)", "fn = stiffness * depth"),),
       {"P:test_frictionless_push_is_a_spring", "P:test_with_friction_matches_the_library",
        "H:test_tilted_plane_in_3d_matches_the_library", "H:test_a_plane_drawn_at_grading"},
       {"P:test_frictionless_push_is_a_spring": "only particles with depth p > 0",
        "P:test_with_friction_matches_the_library": "only particles with depth p > 0"}),
    _m("08 friction not regularised", E08, M08,
       (("np.sum(vt * vt, axis=1) + slip_velocity**2", "np.sum(vt * vt, axis=1)"),),
       # at rest (v_t = 0) the unregularised friction is 0/0: the frictionless tests fail too
       {"P:test_with_friction_matches_the_library", "H:test_tilted_plane_in_3d_matches_the_library",
        "H:test_a_plane_drawn_at_grading", "P:test_frictionless_push_is_a_spring",
        "H:test_normal_force_is_minus_energy_gradient"},
       {"P:test_with_friction_matches_the_library": "not regularised"}),

    _m("09 kinetic energy without the mass", E09, M09,
       "\ndef kinetic_energy(v, problem):\n    free = ~np.asarray(problem.pinned)\n"
       "    return float(0.5 * np.sum(np.asarray(v)[free] ** 2))\n",
       {"P:test_kinetic_and_potential_energy_of_a_moving_chain",
        "P:test_the_ledger_of_a_damped_chain_balances_along_rk4",
        "H:test_chain_and_error_drawn_at_grading"},
       {"P:test_kinetic_and_potential_energy_of_a_moving_chain": "the mass is missing"}),
    _m("09 gravity's sign", E09, M09,
       "\n_pe = potential_energy\ndef potential_energy(x, problem):\n"
       "    g = np.sum(problem.mass[:, None] * problem.gravity[None, :] * np.asarray(x))\n"
       "    return float(_pe(x, problem) + 2.0 * g)\n",
       {"P:test_kinetic_and_potential_energy_of_a_moving_chain",
        "P:test_the_ledger_of_a_damped_chain_balances_along_rk4",
        "H:test_chain_and_error_drawn_at_grading"},
       {"P:test_kinetic_and_potential_energy_of_a_moving_chain": "sign of gravity"}),
    _m("09 drag work by the rectangle rule", E09, M09,
       "\n_lg = ledger\ndef ledger(xs, vs, problem, dt):\n    K, U, _ = _lg(xs, vs, problem, dt)\n"
       "    P = problem.gamma * np.sum(np.asarray(vs)[:, ~problem.pinned] ** 2, axis=(1, 2))\n"
       "    return K, U, np.concatenate([[0.0], np.cumsum(dt * P[:-1])])\n",
       {"P:test_the_ledger_of_a_damped_chain_balances_along_rk4"},
       {"P:test_the_ledger_of_a_damped_chain_balances_along_rk4": "trapezoid"}),
    _m("09 band without the absolute value", E09, M09,
       (("return float(np.max(np.abs(e))), float(slope)", "return float(np.max(e)), float(slope)"),),
       {"P:test_band_and_drift_of_a_synthetic_error", "H:test_chain_and_error_drawn_at_grading",
        "H:test_leapfrog_band_shrinks_four_times_when_h_halves"},
       {"P:test_band_and_drift_of_a_synthetic_error": "|error|"}),
    _m("09 drift fitted on the whole run", E09, M09,
       (("slope = np.polyfit(t[half], e[half], 1)[0]", "slope = np.polyfit(t, e, 1)[0]"),),
       {"P:test_band_and_drift_of_a_synthetic_error", "H:test_chain_and_error_drawn_at_grading"},
       {"P:test_band_and_drift_of_a_synthetic_error": "second half"}),

    _m("10 fit returns log C", E10, M10,
       (("return float(math.exp(log_c)), float(p)", "return float(log_c), float(p)"),),
       {"P:test_fit_recovers_an_exact_and_a_noisy_power_law",
        "P:test_loose_target_goes_to_low_order_and_tight_to_high_order",
        "H:test_choice_from_runs_measured_by_the_library_reaches_the_target",
        "H:test_the_start_up_evaluation_decides_a_tie", "H:test_a_table_drawn_at_grading"},
       {"P:test_fit_recovers_an_exact_and_a_noisy_power_law": "log C, not C"}),
    _m("10 steps rounded, not ceiled", E10, M10,
       (("n_steps = math.ceil(t_end / h)", "n_steps = round(t_end / h)"),),
       {"P:test_step_and_cost_of_one_method", "H:test_a_table_drawn_at_grading"},
       {"P:test_step_and_cost_of_one_method": "ceiling"}),
    _m("10 start-up evaluations forgotten", E10, M10,
       (("int(n_steps * evals_per_step + start_evals)", "int(n_steps * evals_per_step)"),),
       {"P:test_step_and_cost_of_one_method",
        "H:test_choice_from_runs_measured_by_the_library_reaches_the_target",
        "H:test_the_start_up_evaluation_decides_a_tie", "H:test_a_table_drawn_at_grading"},
       {"P:test_step_and_cost_of_one_method": "start-up evaluation is missing"}),
    _m("10 step from target / C to the power p", E10, M10,
       "\ndef step_for_target(C, p, target):\n    return float((target / C) ** p)\n",
       {"P:test_step_and_cost_of_one_method",
        "P:test_loose_target_goes_to_low_order_and_tight_to_high_order",
        "H:test_choice_from_runs_measured_by_the_library_reaches_the_target",
        "H:test_the_start_up_evaluation_decides_a_tie", "H:test_a_table_drawn_at_grading"},
       {"P:test_step_and_cost_of_one_method": "the power p, not the root"}),

    _m("11 one diagonal per cell", E11, M11,
       "\n_gs = grid_springs\ndef grid_springs(n_rows, n_cols, kind):\n"
       "    pairs = _gs(n_rows, n_cols, kind)\n    if kind != 'shear':\n        return pairs\n"
       "    return np.array([p for p in pairs.tolist() if p[1] - p[0] == n_cols + 1]).reshape(-1, 2)\n",
       {"P:test_shear_springs_are_both_diagonals_of_every_cell", "H:test_grids_drawn_at_grading"},
       {"P:test_shear_springs_are_both_diagonals_of_every_cell": "two per cell"}),
    _m("11 bend springs on the diagonal", E11, M11,
       "\n_gs = grid_springs\ndef grid_springs(n_rows, n_cols, kind):\n"
       "    if kind != 'bend':\n        return _gs(n_rows, n_cols, kind)\n"
       "    return np.array([(i * n_cols + j, (i + 2) * n_cols + j + 2) for i in range(n_rows - 2)\n"
       "                     for j in range(n_cols - 2)]).reshape(-1, 2)\n",
       {"P:test_bend_springs_of_a_4_by_5_grid", "H:test_bend_springs_skip_one_particle",
        "H:test_grids_drawn_at_grading"},
       {"P:test_bend_springs_of_a_4_by_5_grid": "not along diagonals"}),
    _m("11 shear with cos and sin swapped", E11, M11,
       "\ndef sheared(n_rows, n_cols, spacing, theta):\n"
       "    i, j = np.divmod(np.arange(n_rows * n_cols), n_cols)\n"
       "    return np.stack([j * spacing + i * spacing * np.cos(theta),\n"
       "                     i * spacing * np.sin(theta)], axis=1)\n",
       {"P:test_the_shear_mode_is_free_for_structural_springs_only", "H:test_grids_drawn_at_grading"},
       {"P:test_the_shear_mode_is_free_for_structural_springs_only": "cos and sin swapped"}),

    _m("12 nodes as column sums", E12, M12,
       "\ndef order3_conditions(A, b):\n    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float)\n"
       "    c = A.sum(axis=0)\n"
       "    return np.array([b.sum() - 1.0, b @ c - 0.5, b @ c**2 - 1.0 / 3.0, b @ (A @ c) - 1.0 / 6.0])\n",
       {"P:test_residuals_of_kutta_and_of_a_second_order_method"},
       {"P:test_residuals_of_kutta_and_of_a_second_order_method": "row sums"}),
    _m("12 b2 and b3 swapped", E12, M12,
       "\n_kf = kutta_family\ndef kutta_family(c2, c3):\n"
       "    A, b = _kf(c2, c3)\n    return A, b[[0, 2, 1]]\n",
       {"P:test_kutta_family_gives_kutta_and_heun3", "P:test_my_method_has_derived_order_three",
        "H:test_kutta_family_at_nodes_drawn_at_grading",
        "H:test_my_method_has_order_three_in_the_library",
        "H:test_my_method_has_the_third_order_stability_function"},
       {"P:test_kutta_family_gives_kutta_and_heun3": "b2 and b3 swapped"}),
    _m("12 rk3 step with the old velocity as position slope", E12, M12,
       (("kx.append(vi)", "kx.append(v)"),),
       {"P:test_rk3_step_with_kutta_matches_the_library", "H:test_rk3_step_converges_with_order_three"},
       {"P:test_rk3_step_with_kutta_matches_the_library": "stage's own velocity"}),
]
