"""Bad scene files shared by test_scenes and test_cli: one valid base, one mistake per case."""

from __future__ import annotations

BASE = """\
[scene]
dim = 2

[particles]
positions = [[0.0, 0.0], [1.0, 0.0]]
mass = 1.0
pinned = [0]

[springs.structural]
pairs = [[0, 1]]
stiffness = 100.0

[run]
method = "rk4"
dt = 0.01
t_end = 1.0
"""

#: (replace this, with that) -> the key the error must name, a word of the reason
BAD = {
    "syntax": (("dim = 2", "dim = = 2"), "line 2", "TOML syntax"),
    "unknown_section": (("[run]", "[gravty]\ng = 9.81\n[run]"), "gravty", "did you mean 'gravity'"),
    "unknown_key": (("stiffness = 100.0", "stifness = 100.0"), "springs.structural.stifness",
                    "did you mean 'stiffness'"),
    "unknown_kind": (("[springs.structural]", "[springs.structual]"), "springs.structual", "structural"),
    "wrong_type": (("stiffness = 100.0", 'stiffness = "100"'), "springs.structural.stiffness", "number"),
    "non_finite": (("stiffness = 100.0", "stiffness = inf"), "springs.structural.stiffness", "finite"),
    "nan_position": (("[1.0, 0.0]]", "[nan, 0.0]]"), "particles.positions[1][0]", "finite"),
    "mass_zero": (("mass = 1.0", "mass = 0.0"), "particles.mass", "> 0"),
    "mass_negative_in_list": (("mass = 1.0", "mass = [1.0, -2.0]"), "particles.mass[1]", "> 0"),
    "stiffness_negative": (("stiffness = 100.0", "stiffness = -5.0"), "springs.structural.stiffness", ">= 0"),
    "spring_index": (("pairs = [[0, 1]]", "pairs = [[0, 2]]"), "springs.structural.pairs[0]", "out of range"),
    "pinned_index": (("pinned = [0]", "pinned = [5]"), "particles.pinned[0]", "out of range"),
    "zero_length": (("[1.0, 0.0]]", "[0.0, 0.0]]"), "springs.structural.rest_length", "zero length"),
    "dt_zero": (("dt = 0.01", "dt = 0.0"), "run.dt", "> 0"),
    "t_end_negative": (("t_end = 1.0", "t_end = -1.0"), "run.t_end", "> 0"),
    "unknown_method": (('method = "rk4"', 'method = "rk5"'), "run.method", "valid methods"),
    "vector_length": (("[1.0, 0.0]]", "[1.0, 0.0, 0.0]]"), "particles.positions[1]", "2 numbers"),
    "generator": (("positions = [[0.0, 0.0], [1.0, 0.0]]", 'generator = "chian"'), "particles.generator",
                  "did you mean 'chain'"),
}


def bad_file(tmp_path, case: str):
    (old, new), key, reason = BAD[case]
    assert old in BASE
    path = tmp_path / f"{case}.toml"
    path.write_text(BASE.replace(old, new, 1))
    return path, key, reason


# ---- effects registry / issue 11 defects 9-10 (effects branch): keep this block together -------------
BAD.update({
    "duplicate_spring": (("pairs = [[0, 1]]", "pairs = [[0, 1], [0, 1]]"), "springs.structural.pairs[1]",
                         "springs.structural.pairs[0] = [0, 1]"),
    "duplicate_spring_reversed": (("pairs = [[0, 1]]", "pairs = [[0, 1], [1, 0]]"),
                                  "springs.structural.pairs[1]",
                                  "joins the same two particles as springs.structural.pairs[0]"),
    "duplicate_spring_across_kinds": (("[run]", "[springs.shear]\npairs = [[1, 0]]\nstiffness = 5.0\n[run]"),
                                      "springs.shear.pairs[0]", "springs.structural.pairs[0] = [0, 1]"),
    "anchor_index": (("[run]", "[anchors]\nparticles = [0, 7]\nstiffness = 10.0\n[run]"),
                     "anchors.particles[1]", "out of range"),
    "anchor_points_count": (("[run]", "[anchors]\nparticles = [1]\nstiffness = 10.0\n"
                             "points = [[0.0, 0.0], [1.0, 1.0]]\n[run]"), "anchors.points",
                            "one entry per particle (1)"),
    "anchor_missing_stiffness": (("[run]", "[anchors]\nparticles = [1]\n[run]"), "anchors.stiffness",
                                 "missing"),
    "collider_type": (("[run]", '[[colliders]]\ntype = "plain"\nnormal = [0.0, 1.0]\noffset = 0.0\n'
                       "stiffness = 1.0\n[run]"), "colliders[0].type", "did you mean 'plane'"),
    "plane_zero_normal": (("[run]", '[[colliders]]\ntype = "plane"\nnormal = [0.0, 0.0]\noffset = 0.0\n'
                           "stiffness = 1.0\n[run]"), "colliders[0].normal", "zero vector"),
    "gravity_vector_length": (("[run]", "[gravity]\ng = [0.0, 0.0, -9.81]\n[run]"), "gravity.g", "2 numbers"),
})
#: valid scene files whose run ``mslab run`` and ``mslab validate`` must refuse (issue 11):
#: (replace this, with that) -> the key the error names, a word of the reason
BAD_RUN = {
    # 10^10 saved samples of two 2D particles: about a terabyte, over any memory budget
    "memory": (("dt = 0.01\nt_end = 1.0", "dt = 1e-6\nt_end = 1e4\nsave_every = 1"), "run",
               "save_every >="),
}

#: command-line mistakes of ``mslab run`` on a valid scene: extra arguments -> (key, word of the reason)
BAD_OPTIONS = {
    "max_memory_word": (["--max-memory", "lots"], "--max-memory", "not a memory size"),
    "max_memory_small": (["--max-memory", "1k"], "run", "over the memory budget of 1 kB"),
    "method": (["--method", "rk5"], "run.method", "valid methods"),
}


def bad_run_file(tmp_path, case: str):
    """A valid scene file whose run is refused: (path, key, reason)."""
    (old, new), key, reason = BAD_RUN[case]
    assert old in BASE
    path = tmp_path / f"{case}.toml"
    path.write_text(BASE.replace(old, new, 1))
    return path, key, reason
