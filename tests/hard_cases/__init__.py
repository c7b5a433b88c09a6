"""Hard cases: scenes where integrators must stay stable where theory says they are.

Each module builds its scenes programmatically (SceneBuilder and the generators) and
states what must hold. Run them on their own from the command line::

    python -m tests.hard_cases          # same as: pytest -q tests/hard_cases
"""
