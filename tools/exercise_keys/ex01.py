"""Key of exercise 01 (spring forces and their Jacobian): the known mistakes' answers."""

import numpy as np


def _forces(x, springs, stiffness, rest_length):
    i, j = springs[:, 0], springs[:, 1]
    d = x[i] - x[j]
    length = np.linalg.norm(d, axis=1)

    def assemble(pair, reaction=-1.0):
        f = np.zeros_like(x, dtype=float)
        np.add.at(f, i, pair)
        np.add.at(f, j, reaction * pair)
        return [f]

    pull = (stiffness * (rest_length - length) / length)[:, None] * d
    return {"mistakes": {
        "the sign: a stretched spring (l > L) pulls its two ends together": assemble(-pull),
        "the direction is not a unit vector: divide x_i - x_j by l": assemble(pull * length[:, None]),
        "the opposite force on j is missing: each spring pulls both its ends": assemble(pull, 0.0)}}


def _jacobian(x, springs, stiffness, rest_length):
    n, dim = x.shape
    right, along = np.zeros((n * dim, n * dim)), np.zeros((n * dim, n * dim))
    for (i, j), k, rest in zip(springs, stiffness, rest_length, strict=True):
        length = np.linalg.norm(x[i] - x[j])
        u = (x[i] - x[j]) / length
        uu = np.outer(u, u)
        si, sj = slice(i * dim, (i + 1) * dim), slice(j * dim, (j + 1) * dim)
        for K, block in ((right, -k * (uu + (1.0 - rest / length) * (np.eye(dim) - uu))), (along, -k * uu)):
            K[si, si] += block
            K[sj, sj] += block
            K[si, sj] -= block
            K[sj, si] -= block
    return {"mistakes": {
        "the sign of K: a stretched spring's K pulls back, -k (u u^T + (1 - L/l)(I - u u^T))": [-right],
        "only the -k u u^T part: the term -k (1 - L/l)(I - u u^T) of a stretched spring is missing": [along]}}


CASES = {"single_spring": lambda t: _forces(*t.single_spring()),
         "small_net": lambda t: _forces(*t.small_net()),
         "three_particles": lambda t: _jacobian(*t.three_particles())}
