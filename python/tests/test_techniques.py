"""The registry as data."""

import pytest

import penumbra


def test_techniques_lists_the_registry_with_capabilities():
    techniques = penumbra.techniques()
    names = [t["name"] for t in techniques]
    assert "dcs" in names and "reference" in names and "shadow-map" in names
    assert len(names) == len(set(names))
    by_name = {t["name"]: t for t in techniques}
    assert by_name["dcs"]["exact"] is True
    assert by_name["shadow-map"]["exact"] is False
    assert by_name["reference"]["cost"] == "rays"
    for t in techniques:
        assert {"summary", "module", "exact_image", "output", "support", "cost"} <= set(t)
        assert t["output"] in ("Vcoef", "radiance")
        assert "rect_lights" in t["support"] and "sphere_lights" in t["support"]


def test_every_listed_technique_renders_or_refuses_as_it_says(two_lights):
    # The scene has a sphere light: a technique that declares it refuses
    # them raises ValueError naming itself; every other one renders.
    for t in penumbra.techniques():
        name = t["name"]
        if t["support"]["sphere_lights"].startswith("refused"):
            with pytest.raises(ValueError, match=name):
                two_lights.render(technique=name, samples=4, width=16, height=12)
        else:
            out = two_lights.render(technique=name, samples=4, width=16, height=12)
            assert out.radiance.shape == (12, 16, 3), name
