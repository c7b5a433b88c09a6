"""mslab's benchmark harnesses and their reference kernels (not part of the installed package).

``suite`` holds the measurements of ``mslab bench`` and ``benchmarks/run_bench.py``;
``references`` the hand-written kernels they compare with; ``warp_cloth`` the side-by-side
comparison with NVIDIA Warp's CPU backend (issue 14). Run from a checkout: the ``mslab
bench`` command finds this folder next to the ``mslab`` package.
"""
