"""Shared fixtures: the repository's scenes and a small two-light scene."""

from pathlib import Path

import pytest

import penumbra

#: The repository root (python/tests/ is two levels below it).
ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"

#: A ground, an occluder and two lights (a rect and a sphere), 40 x 30:
#: renders in milliseconds, and has a shadow and lit ground from each light.
TWO_LIGHTS = """
[camera]
eye = [0.0, 5.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y = 45
width = 40
height = 30

[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
radiance = 10

[[light]]
type = "sphere"
center = [1.5, 3.0, 0.5]
radius = 0.3
radiance = 5

[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]

[[object]]
name = "occluder"
shape = "box"
size = [1.0, 1.0, 1.0]
translate = [0.0, 1.0, 0.0]
"""


@pytest.fixture(scope="session")
def two_lights() -> penumbra.Scene:
    return penumbra.Scene.from_toml(TWO_LIGHTS)


@pytest.fixture(scope="session")
def spheres() -> penumbra.Scene:
    return penumbra.load_scene(SCENES / "spheres.toml")
