"""Registration checks what it is given; a broken method or effect file is one line, not a crash.

Each case is a one-file method (or effect) written into a temporary folder added to the
package's path, as a user would save it into ``mslab/integrators/`` (``docs/extending.md``).
Correct methods from outside the package (Ralston 3, the 3/8-rule RK4, Lobatto IIIC 2,
Ruth 3) pass the registry-wide tests; wrong ones are refused at registration, and the
registry-wide tests themselves still reject a method whose declared order is wrong.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from fractions import Fraction as Fr
from pathlib import Path

import pytest

import mslab
import mslab.effects as effects_package
import mslab.integrators as package
from mslab import errors
from mslab.effects import registry as effect_registry
from mslab.integrators import base

ROOT = Path(__file__).resolve().parents[1]

HEADER = ("from fractions import Fraction as Fr\n\n"
          "from mslab.integrators import ExplicitRK, ImplicitRK, Splitting, register\n\n")
LOBATTO = "[[Fr(1, 2), Fr(-1, 2)], [Fr(1, 2), Fr(1, 2)]], [Fr(1, 2), Fr(1, 2)]"
RALSTON = "[[0, 0, 0], [Fr(1, 2), 0, 0], [0, Fr(3, 4), 0]], [Fr(2, 9), Fr(1, 3), Fr(4, 9)]"
RUTH_KICKS = "kick=[Fr(7, 24), Fr(3, 4), Fr(-1, 24)]"

#: correct methods of the three families, with the orders of their references
GOOD = {
    "ralston3": (f'register(ExplicitRK({RALSTON}, name="ralston3", order=3))\n', 3),
    "rk38": ('register(ExplicitRK([[0, 0, 0, 0], [Fr(1, 3), 0, 0, 0], [Fr(-1, 3), 1, 0, 0], [1, -1, 1, 0]],\n'
             '                    [Fr(1, 8), Fr(3, 8), Fr(3, 8), Fr(1, 8)], name="rk38", order=4))\n', 4),
    "lobatto_iiic2": (f'register(ImplicitRK({LOBATTO}, name="lobatto_iiic2", order=2))\n', 2),
    # Ruth (1983), kick first: a leading zero drift
    "ruth3": (f'register(Splitting(drift=[0, Fr(2, 3), Fr(-2, 3), 1], {RUTH_KICKS}, name="ruth3",'
              ' order=3))\n', 3),
}

#: wrong method files -> what their one line must say
BAD = {
    "clash": ('x = 1\nregister(ExplicitRK([[0]], [1], name="rk4", order=1))\n',
              [":6: method name 'rk4' of ", "clash.py is already registered by ", "explicit_tableaux.py"]),
    "ralston_order4": (f'register(ExplicitRK({RALSTON}, name="ralston_order4", order=4))\n',
                       [":5: method 'ralston_order4' declares order 4, but its coefficients have order 3"]),
    "lobatto_order3": (f'register(ImplicitRK({LOBATTO}, name="lobatto_order3", order=3))\n',
                       ["declares order 3, but its coefficients have order 2"]),
    "ruth_swapped": (f'register(Splitting(drift=[Fr(2, 3), Fr(-2, 3), 1, 0], {RUTH_KICKS},'
                     ' name="ruth_swapped", order=3))\n',
                     ["declares order 3, but its coefficients have order 1", "begin drift with a 0"]),
    "understated": ('register(ExplicitRK([[0, 0], [Fr(1, 2), 0]], [0, 1], name="understated", order=1))\n',
                    ["declares order 1, but its coefficients have order more than 1"]),
    "weights": ('register(ExplicitRK([[0, 0], [1, 0]], [Fr(1, 2), Fr(3, 5)], name="weights", order=2))\n',
                ["the weights b sum to 1.1000000000000001, not 1"]),
    "kicks": ('register(Splitting(drift=[Fr(1, 2), Fr(1, 2)], kick=[Fr(9, 10)], name="kicks", order=1))\n',
              ["the weights kick sum to 0.90000000000000002, not 1"]),
    "row_sums": ('register(ExplicitRK([[0, 0], [Fr(1, 2), 0]], [0, 1], c=[0, 1], name="row_sums",'
                 ' order=2))\n',
                 ["c[1] = 1 is not the row sum of A, 0.5"]),
    "name_error": ('\nx = undefined_name + 1\nregister(ExplicitRK([[0]], [1], name="name_error", order=1))\n',
                   [":6: NameError: name 'undefined_name' is not defined"]),
    "syntax": ('register(ExplicitRK([[0]], [1], name="syntax", order=1)\n',
               [":5: SyntaxError: "]),
    "partial": ('register(ExplicitRK([[0]], [1], name="partial_ok", order=1))\n'
                'register(ExplicitRK([[0]], [1], name="partial_bad", order=2))\n',
                [":6: method 'partial_bad' declares order 2"]),
}


def _cleanup(folder: Path, names: list[str]) -> None:
    package.__path__[:] = [p for p in package.__path__ if p != str(folder)]
    for name in names:
        base._REGISTRY.pop(name, None)
        base._ORIGIN.pop(name, None)
        sys.modules.pop(f"mslab.integrators.{name}", None)
        package._FAILED.discard(f"mslab.integrators.{name}")
    for line in list(errors._BROKEN):
        if line.startswith(str(folder)):
            del errors._BROKEN[line]


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    """The GOOD and BAD files in one folder of the package path, discovered once."""
    folder = tmp_path_factory.mktemp("user_methods")
    for name, (body, *_) in {**GOOD, **BAD}.items():
        (folder / f"{name}.py").write_text(HEADER + body)
    package.__path__.append(str(folder))
    try:
        found = package.discover()
        with pytest.warns(errors.BrokenFileWarning):  # reported by the first lookup
            mslab.methods()
        lines = {name: [ln for ln in errors.broken_files() if ln.startswith(str(folder / f"{name}.py:"))]
                 for name in BAD}
        yield found, lines
    finally:
        _cleanup(folder, [*GOOD, *BAD, "partial_ok", "partial_bad"])


def test_correct_methods_register_with_their_orders(loaded):
    found, _ = loaded
    assert sorted(found) == sorted(GOOD)
    for name, (_, order) in GOOD.items():
        assert mslab.get_method(name).order == order == mslab.derive.order(name)


@pytest.mark.parametrize("name", sorted(BAD))
def test_each_wrong_file_is_one_line_naming_file_and_line(loaded, name):
    _, lines = loaded
    assert len(lines[name]) == 1, lines[name]
    line = lines[name][0]
    assert "\n" not in line
    for part in BAD[name][1]:
        assert part in line


def test_wrong_files_leave_the_registry_as_it_was(loaded):
    assert mslab.get_method("rk4").order == 4 and mslab.get_method("rk4").n_stages == 4
    registered = set(mslab.methods())
    # a failing file takes back all it registered
    assert not registered & (set(BAD) | {"partial_ok", "partial_bad"})
    assert {"euler", "rk4", "verlet", "implicit_euler", "forest_ruth"} <= registered
    with pytest.raises(ValueError, match=r"its file was skipped: .*name_error\.py:6: NameError"):
        mslab.get_method("name_error")


@pytest.mark.parametrize("name", ["rk38", "ralston3", "ruth3", "lobatto_iiic2"])
def test_registry_wide_tests_accept_correct_methods(loaded, name):
    from tests import test_integrators
    from tests.hard_cases import test_ledger_order

    test_integrators.test_ledger_total_conserved_to_method_order_with_damping(name)
    test_ledger_order.test_damped_oscillator_ledger_order(name)
    for gamma in (0.0, 0.4):
        test_integrators.test_convergence_order_on_oscillator(name, gamma)
    test_integrators.test_step_mutates_nothing_and_pinned_never_move(name)


def test_registry_wide_tests_reject_a_wrong_declared_order():
    """Built without ``register`` (which would refuse it): Ralston's order-3 tableau declared 4."""
    from tests import test_integrators

    wrong = mslab.ExplicitRK([[0, 0, 0], [Fr(1, 2), 0, 0], [0, Fr(3, 4), 0]], [Fr(2, 9), Fr(1, 3), Fr(4, 9)],
                             name="ralston_as_4", order=4)
    slope = test_integrators.ledger_slope(wrong)
    assert abs(slope - 3) < 0.2 and slope < wrong.order - 0.2
    with pytest.raises(AssertionError):
        test_integrators.check_ledger_order(wrong)
    from tests.hard_cases import test_ledger_order

    with pytest.raises(AssertionError):
        test_ledger_order.test_damped_oscillator_ledger_order(wrong)
    test_integrators.check_ledger_order(mslab.ExplicitRK(  # the same tableau declared 3: accepted
        [[0, 0, 0], [Fr(1, 2), 0, 0], [0, Fr(3, 4), 0]], [Fr(2, 9), Fr(1, 3), Fr(4, 9)], name="r3", order=3))


def test_undeclared_order_is_derived(tmp_path):
    (tmp_path / "kutta3_auto.py").write_text(HEADER + (
        'register(ExplicitRK([[0, 0, 0], [Fr(1, 2), 0, 0], [-1, 2, 0]], [Fr(1, 6), Fr(2, 3), Fr(1, 6)],\n'
        '                    name="kutta3_auto"))\n'))
    package.__path__.append(str(tmp_path))
    try:
        assert package.discover() == ["kutta3_auto"]
        assert mslab.get_method("kutta3_auto").order == 3
    finally:
        _cleanup(tmp_path, ["kutta3_auto"])


def test_same_file_registers_again_but_no_other_file_replaces(tmp_path):
    first = base.register(mslab.ExplicitRK([[0]], [1], name="again", order=1))
    try:
        second = base.register(mslab.ExplicitRK([[0]], [1], name="again", order=1))  # the same file: replaced
        assert mslab.get_method("again") is second is not first
        again = 'register(ExplicitRK([[0]], [1], name="again", order=1))\n'
        (tmp_path / "other_again.py").write_text(HEADER + again)
        package.__path__.append(str(tmp_path))
        package.discover()
        with pytest.warns(errors.BrokenFileWarning, match="other_again.py:5: method name 'again' of "):
            assert mslab.get_method("again") is second
        assert any(f"other_again.py:5: method name 'again' of {tmp_path / 'other_again.py'} is already "
                   f"registered by {__file__}" in line for line in errors.broken_files())
    finally:
        _cleanup(tmp_path, ["again", "other_again"])


def test_broken_effect_file_is_one_line_and_the_other_effects_work(tmp_path):
    (tmp_path / "broken_effect.py").write_text(textwrap.dedent("""\
        from mslab.effects.base import Effect
        from mslab.effects.registry import register


        @register
        class Broken(Effect):
            name = "broken"
            section = "broken"
            keys = (Key("k", "number"),)
        """))
    effects_package.__path__.append(str(tmp_path))
    try:
        effect_registry.discover()
        lines = [ln for ln in errors.broken_files() if ln.startswith(str(tmp_path))]
        assert lines == [f"{tmp_path / 'broken_effect.py'}:9: NameError: name 'Key' is not defined"]
        with pytest.warns(errors.BrokenFileWarning, match="broken_effect.py:9: NameError"):
            assert "broken" not in {cls.name for cls in effect_registry.effect_classes()}
        assert {"springs", "gravity", "damping"} <= {cls.name for cls in effect_registry.effect_classes()}
        scene = mslab.load_scene("pendulum", t_end=0.01)
        assert mslab.simulate(scene, method="rk4").stats.steps > 0
    finally:
        effects_package.__path__[:] = [p for p in effects_package.__path__ if p != str(tmp_path)]
        sys.modules.pop("mslab.effects.broken_effect", None)
        effect_registry._imported.discard("broken_effect")
        for line in list(errors._BROKEN):
            if line.startswith(str(tmp_path)):
                del errors._BROKEN[line]


def _cli(folder: Path, *argv: str) -> subprocess.CompletedProcess:
    code = ("import sys, mslab.integrators as p; p.__path__.append(sys.argv[1]); p.discover(); "
            "from mslab.cli import main; sys.exit(main(sys.argv[2:]))")
    return subprocess.run([sys.executable, "-c", code, str(folder), *argv], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)


def test_command_line_warns_in_one_line_per_broken_file_and_works(tmp_path):
    (tmp_path / "typo.py").write_text(HEADER + 'register(ExplicitRK([[0]], [1], nme="typo", order=1))\n')
    (tmp_path / "heun_as_3.py").write_text(HEADER + (
        'register(ExplicitRK([[0, 0], [1, 0]], [Fr(1, 2), Fr(1, 2)], name="heun_as_3", order=3))\n'))
    done = _cli(tmp_path, "methods")
    assert done.returncode == 0, done.stderr
    assert "rk4" in done.stdout and "Traceback" not in done.stderr
    assert done.stderr.splitlines() == [
        f"mslab: warning: {tmp_path / 'heun_as_3.py'}:5: method 'heun_as_3' declares order 3, but its "
        "coefficients have order 2 (mslab.derive.order) (file skipped)",
        f"mslab: warning: {tmp_path / 'typo.py'}:5: TypeError: ExplicitRK.__init__() got an unexpected "
        "keyword argument 'nme' (file skipped)"]
    run = _cli(tmp_path, "run", "pendulum", "--method", "heun_as_3", "--t-end", "0.1")
    assert run.returncode == 2
    assert run.stderr.splitlines()[-1].startswith("mslab: error: ")
    assert "unknown method 'heun_as_3'" in run.stderr.splitlines()[-1]
    assert "its file was skipped: " in run.stderr and len(run.stderr.splitlines()) == 3


def test_import_and_built_in_lookups_stay_cheap():
    code = ("import sys, mslab; mslab.methods(); mslab.get_method('rk4'); "
            "print(sorted(m for m in ('sympy', 'scipy', 'numba') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.stdout.strip() == "[]", out.stderr


def test_an_effect_file_may_not_replace_a_built_in_effect(tmp_path):
    (tmp_path / "my_springs.py").write_text(textwrap.dedent("""\
        from mslab.effects.base import Effect
        from mslab.effects.registry import register


        @register
        class MySprings(Effect):
            name = "springs"
        """))
    effects_package.__path__.append(str(tmp_path))
    try:
        effect_registry.discover()
        lines = [ln for ln in errors.broken_files() if ln.startswith(str(tmp_path))]
        head = (f"{tmp_path / 'my_springs.py'}:5: effect name 'springs' of {tmp_path / 'my_springs.py'} is "
                "already registered by ")
        assert len(lines) == 1 and lines[0].startswith(head)
        assert "mslab/effects/springs.py" in lines[0]
        with pytest.warns(errors.BrokenFileWarning):
            assert effect_registry.get_effect("springs").__module__ == "mslab.effects.springs"
    finally:
        effects_package.__path__[:] = [p for p in effects_package.__path__ if p != str(tmp_path)]
        sys.modules.pop("mslab.effects.my_springs", None)
        effect_registry._imported.discard("my_springs")
        for line in list(errors._BROKEN):
            if line.startswith(str(tmp_path)):
                del errors._BROKEN[line]


def test_files_imported_before_the_order_check_is_installed_are_checked_then(tmp_path):
    """``import mslab`` imports the method files first and installs mslab.derive's check after."""
    (tmp_path / "early.py").write_text(HEADER + (
        'register(ExplicitRK([[0]], [1], name="early_ok", order=1))\n'
        'register(ExplicitRK([[0, 0], [1, 0]], [Fr(1, 2), Fr(1, 2)], name="early_bad", order=3))\n'))
    check = base._order_check
    base._order_check = None
    package.__path__.append(str(tmp_path))
    try:
        assert package.discover() == ["early"]
        assert {"early_ok", "early_bad"} <= set(base._REGISTRY)  # not checked yet
        base.set_order_check(check)
        assert not {"early_ok", "early_bad"} & set(base._REGISTRY)  # the whole file is taken out
        assert f"{tmp_path / 'early.py'}:6: method 'early_bad' declares order 3, but its coefficients have " \
               "order 2 (mslab.derive.order)" in errors.broken_files()
    finally:
        base._order_check = check
        _cleanup(tmp_path, ["early", "early_ok", "early_bad"])
