"""Bad input raises a Python exception that names the file and line or the
parameter; never a crash."""

import pytest

import penumbra

from conftest import TWO_LIGHTS


def test_bad_toml_names_the_line():
    text = TWO_LIGHTS.replace("fov_y = 45", "fov_y == 45")
    line = TWO_LIGHTS.splitlines().index("fov_y = 45") + 1
    with pytest.raises(penumbra.SceneError) as err:
        penumbra.Scene.from_toml(text)
    assert f":{line}:" in str(err.value)
    assert isinstance(err.value, ValueError)


def test_invalid_value_names_the_line():
    text = TWO_LIGHTS.replace("radius = 0.3", "radius = -1.0")
    line = TWO_LIGHTS.splitlines().index("radius = 0.3") + 1
    with pytest.raises(penumbra.SceneError, match=f":{line}:.*radius"):
        penumbra.Scene.from_toml(text)


def test_scene_file_error_names_the_file_and_line(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text(TWO_LIGHTS.replace('shape = "box"', 'shape = "torus"'))
    line = TWO_LIGHTS.splitlines().index('shape = "box"') + 1
    with pytest.raises(penumbra.SceneError) as err:
        penumbra.load_scene(path)
    assert f"broken.toml:{line}:" in str(err.value)
    assert "torus" in str(err.value)


def test_missing_file_is_an_os_error(tmp_path):
    with pytest.raises(OSError, match="nowhere.toml"):
        penumbra.load_scene(tmp_path / "nowhere.toml")


def test_unknown_technique_lists_the_known_ones(two_lights):
    with pytest.raises(ValueError, match=r"parameter `technique`.*known:.*dcs"):
        two_lights.render(technique="raytraced-magic")


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(samples=0), "samples"),
        (dict(samples=-4), "samples"),
        (dict(width=0), "width"),
        (dict(height=10**6), "height"),
        (dict(threads=0), "threads"),
        (dict(aovs=["depth", "shininess"]), "aovs"),
        (dict(pattern="zigzag"), "pattern"),
    ],
)
def test_out_of_range_parameter_is_a_value_error_naming_it(two_lights, kwargs, name):
    with pytest.raises(ValueError, match=f"parameter `{name}`"):
        two_lights.render(**kwargs)


def test_wrong_type_is_a_type_error_naming_it(two_lights):
    with pytest.raises(TypeError, match="parameter `samples`"):
        two_lights.render(samples=2.5)


def test_scene_cannot_be_made_from_nothing():
    with pytest.raises(TypeError):
        penumbra.Scene(None)
