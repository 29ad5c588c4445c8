"""Progressive rendering to a target error from Python."""

import numpy as np
import pytest

import penumbra


def test_target_error_stops_and_reports_how(spheres):
    out = spheres.render(
        samples=8, width=48, height=32, threads=1, target_error=1e-2, aovs=["error", "mask"]
    )
    c = out.explain["convergence"]
    assert c["stop"] == "target-error"
    assert c["error"] <= 1e-2
    assert c["sets"] == len(c["curve"]) >= 2
    err = out.aovs["error"]
    assert err.shape == (32, 48, 2)
    # error.Y's mean square over the shading points is the image estimate.
    mask = out.aovs["mask"] > 0.5
    assert np.sqrt(np.mean(err[..., 0][mask].astype(np.float64) ** 2)) == pytest.approx(
        c["error"], rel=1e-3
    )


def test_max_samples_gives_the_same_bits_on_any_thread_count(spheres):
    a = spheres.render(samples=4, width=32, height=24, threads=1, max_samples=12)
    b = spheres.render(samples=4, width=32, height=24, threads=2, max_samples=12)
    assert a.explain["convergence"]["sets"] == 3
    assert a.explain["convergence"]["stop"] == "max-samples"
    assert np.array_equal(a.radiance.view(np.uint32), b.radiance.view(np.uint32))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(target_error=-1.0), "target_error"),
        (dict(max_time=0.0), "max_time"),
        (dict(max_samples=2), "max_samples"),
        (dict(technique="shadow-map", target_error=0.01), "does not sample the light"),
        (dict(aovs=["error"]), "aovs"),
    ],
)
def test_bad_progressive_parameters_name_themselves(spheres, kwargs, name):
    with pytest.raises(ValueError, match=name):
        spheres.render(samples=4, width=16, height=16, **kwargs)
