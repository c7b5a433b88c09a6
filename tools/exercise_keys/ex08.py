"""Key of exercise 08 (penalty contact with a plane): forces outside the wall, or with friction gone wrong."""

import numpy as np


def _wrong_forces(x, v, normal, offset, stiffness, friction, slip):
    depth = offset - x @ normal
    fn = np.where(depth > 0.0, stiffness * depth, 0.0)
    vt = v - (v @ normal)[:, None] * normal[None, :]

    def force(fn, along, slip):
        speed = np.sqrt(np.sum(along * along, axis=1) + slip**2)
        with np.errstate(divide="ignore", invalid="ignore"):
            return [fn[:, None] * normal[None, :] - (friction * fn / speed)[:, None] * along]

    wrong = {"a force outside the wall: only particles with depth p > 0 are pushed":
             force(stiffness * depth, vt, slip),
             "friction along the whole velocity: it opposes the tangential part v - (n.v) n only":
             force(fn, v, slip),
             "friction not regularised: divide by sqrt(|v_t|^2 + eps^2), not by |v_t|": force(fn, vt, 0.0)}
    # at rest (v_t = 0) the unregularised friction is 0/0: a NaN answer names no mistake (and is no JSON)
    return {"mistakes": {hint: w for hint, w in wrong.items() if np.all(np.isfinite(w[0]))}}


CASES = {"resting_contact": lambda t: _wrong_forces(*t.resting_contact()),
         "sliding_contact": lambda t: _wrong_forces(*t.sliding_contact())}
