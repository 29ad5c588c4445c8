"""The defaults Python's signatures write out are the crate's own
(RenderOptions::default, CompareOptions::default): one source of truth,
shown where editors show it."""

import inspect
import json

import penumbra
from penumbra import _penumbra

DEFAULTS = json.loads(_penumbra.defaults_json())


def _signature_defaults(function) -> dict:
    return {
        name: p.default
        for name, p in inspect.signature(function).parameters.items()
        if p.default is not inspect.Parameter.empty
    }


def test_render_defaults_are_the_crates():
    got = _signature_defaults(penumbra.Scene.render)
    want = DEFAULTS["render"]
    assert got["technique"] == want["technique"]
    assert got["samples"] == want["samples"]
    assert got["seed"] == want["seed"]
    # None means the crate's pattern; say which it is.
    assert got["pattern"] is None and want["pattern"] == "stratified"


def test_compare_defaults_are_the_crates():
    got = _signature_defaults(penumbra.compare)
    want = DEFAULTS["compare"]
    assert list(got["techniques"]) == want["techniques"]
    assert list(got["samples"]) == want["samples"]
    assert got["reference_samples"] == want["reference_samples"]
    assert list(got["patterns"]) == want["patterns"]
    assert got["repeat"] == want["repeat"]
    assert got["seed"] == want["seed"]
    assert got["images"] == want["images"]
    assert got["sweep_settings"] == want["sweep_settings"]
