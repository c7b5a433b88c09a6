"""Scenes: the programmatic builder, generators, and (later) TOML scene files."""

from mslab.scenes.builder import Scene, SceneBuilder, Settings
from mslab.scenes.generators import chain, cloth, grid_springs, lattice, oscillator, oscillator_solution

__all__ = ["Scene", "SceneBuilder", "Settings", "chain", "cloth", "grid_springs", "lattice", "oscillator", "oscillator_solution"]
