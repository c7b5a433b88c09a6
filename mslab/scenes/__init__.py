"""Scenes: the programmatic builder, generators, and TOML scene files (``load_scene``)."""

from mslab.scene import Scene, Settings
from mslab.scenes.builder import SceneBuilder
from mslab.scenes.generators import chain, cloth, grid_springs, lattice, oscillator, oscillator_solution
from mslab.scenes.loader import load_scene, scene_names, scene_path

__all__ = [
    "Scene", "SceneBuilder", "Settings", "chain", "cloth", "grid_springs", "lattice", "load_scene",
    "oscillator", "oscillator_solution", "scene_names", "scene_path",
]
