"""Renders through the Python API: shapes, dtypes, AOVs, determinism."""

import numpy as np
import pytest

import penumbra


def test_radiance_is_float32_rows_by_columns_by_rgb(spheres):
    out = spheres.render(samples=4, width=48, height=32, threads=1)
    assert out.radiance.shape == (32, 48, 3)
    assert out.radiance.dtype == np.float32
    assert (out.width, out.height) == (48, 32)
    assert np.isfinite(out.radiance).all()
    # Lit ground and spheres, black background: not a constant image.
    assert out.radiance.max() > 0.1 and out.radiance.min() >= 0.0


def test_camera_size_when_not_overridden(two_lights):
    out = two_lights.render(samples=1)
    assert out.radiance.shape == (two_lights.height, two_lights.width, 3) == (30, 40, 3)


def test_scene_summary(spheres, two_lights):
    assert spheres.name == "spheres-9x9"
    assert (spheres.width, spheres.height, spheres.lights) == (1024, 1024, 1)
    assert spheres.triangles > 81 * 20 * 20  # 81 spheres and the ground
    assert two_lights.lights == 2 and two_lights.name == "scene"
    assert "spheres-9x9" in repr(spheres)


def test_every_aov_has_its_shape_and_sane_values(two_lights):
    out = two_lights.render(samples=16, aovs="all", threads=1)
    h, w = 30, 40
    assert set(out.aovs) >= set(penumbra.AOVS)
    assert out.aovs["depth"].shape == (h, w)
    assert out.aovs["mask"].shape == (h, w)
    for name in ("position", "normal", "albedo"):
        assert out.aovs[name].shape == (h, w, 3), name
    assert out.aovs["vcoef"].shape == (h, w, 2)  # one channel per light
    assert out.channels["normal"] == ["X", "Y", "Z"]
    assert out.channels["vcoef"] == ["0", "1"]
    for values in out.aovs.values():
        assert values.dtype == np.float32

    mask = out.aovs["mask"]
    surface = mask == 1.0
    assert set(np.unique(mask)) <= {0.0, 1.0}
    assert surface.any() and not surface.all()  # the ground ends in the frame
    assert (out.aovs["depth"][surface] > 0).all()
    assert (out.aovs["depth"][~surface] == 0).all()
    normal_length = np.linalg.norm(out.aovs["normal"][surface], axis=-1)
    np.testing.assert_allclose(normal_length, 1.0, atol=1e-3)
    vcoef = out.aovs["vcoef"]
    assert ((vcoef >= 0) & (vcoef <= 1)).all()
    # Each light casts a shadow somewhere and lights the ground elsewhere.
    for k in range(2):
        lit = vcoef[..., k][surface]
        assert (lit < 0.5).any() and (lit == 1.0).any(), k


def test_vcoef_per_light_matches_the_layer_on_surfaces(two_lights):
    out = two_lights.render(samples=16, aovs=["vcoef", "mask"])
    assert len(out.vcoef) == 2
    surface = out.aovs["mask"] == 1.0
    for k, v in enumerate(out.vcoef):
        assert v.shape == (30, 40) and v.dtype == np.float32
        np.testing.assert_array_equal(v[surface], out.aovs["vcoef"][..., k][surface])


def test_rows_run_top_to_bottom(two_lights):
    # The camera looks down at the ground from above and in front: the
    # bottom rows see the ground near the camera, the top rows see farther.
    depth = two_lights.render(samples=1, aovs=["depth", "mask"]).aovs["depth"]
    column = depth[:, 20]
    seen = column[column > 0]
    assert seen[0] > seen[-1]


def test_timings_explain_and_warnings_are_data(two_lights):
    out = two_lights.render(samples=4, threads=1)
    assert out.explain["technique"] == "dcs" and out.explain["samples"] == 4
    assert out.explain["threads"] == 1
    assert out.timings and all(isinstance(s, float) and s >= 0 for s in out.timings.values())
    assert "gbuffer" in " ".join(out.timings)
    assert isinstance(out.explain["simd"], str)
    assert all({"name", "detail", "bytes"} <= set(b) for b in out.explain["buffers"])
    assert isinstance(out.warnings, list)
    assert "penumbra.Render 40x30" in repr(out)


def test_same_call_same_bits_on_any_thread_count(spheres):
    args = dict(technique="reference", samples=8, width=40, height=40, aovs=["vcoef"])
    a = spheres.render(threads=1, **args)
    b = spheres.render(threads=1, **args)
    c = spheres.render(threads=2, **args)
    for other in (b, c):
        assert a.radiance.tobytes() == other.radiance.tobytes()
        assert a.aovs["vcoef"].tobytes() == other.aovs["vcoef"].tobytes()


def test_seed_changes_a_sampled_image(spheres):
    args = dict(technique="reference", samples=4, width=40, height=40, threads=1)
    assert spheres.render(seed=1, **args).radiance.tobytes() != spheres.render(
        seed=2, **args
    ).radiance.tobytes()


def test_technique_options_reach_the_technique(spheres):
    # A coarser shadow map gives a different image; an unknown option or a
    # bad value is refused by the command line's own parser.
    args = dict(technique="shadow-map", width=48, height=48, threads=1)
    small = spheres.render(map_size=64, **args)
    large = spheres.render(map_size=1024, **args)
    assert small.radiance.tobytes() != large.radiance.tobytes()
    with pytest.raises(ValueError, match="no-such-option"):
        spheres.render(no_such_option=3, **args)


def test_srgb_is_the_clamped_encoding(two_lights):
    out = two_lights.render(samples=4)
    srgb = out.srgb()
    assert srgb.shape == out.radiance.shape and srgb.dtype == np.float32
    assert srgb.min() >= 0 and srgb.max() <= 1
    assert (srgb >= np.clip(out.radiance, 0, 1) - 1e-6).all()  # brightens
