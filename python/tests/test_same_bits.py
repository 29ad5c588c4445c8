"""A Python render equals the command line's EXR bit for bit, on any
thread count.

The CLI is the binary at $PENUMBRA_BIN (default: target/release/penumbra
of the repository, or of $CARGO_TARGET_DIR); build it from the same tree
(`cargo build --release`) or the comparison means nothing. The EXR is read
with OpenEXR's own Python reader (PyPI `OpenEXR`), not penumbra's, so the
check does not rest on penumbra reading back what it wrote.
"""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import ROOT, SCENES

OpenEXR = pytest.importorskip("OpenEXR", reason="pip install OpenEXR to compare with the CLI's EXR")


def penumbra_bin() -> Path:
    if "PENUMBRA_BIN" in os.environ:
        return Path(os.environ["PENUMBRA_BIN"])
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if not target.is_absolute():
        target = ROOT / target
    return target / "release" / "penumbra"


BIN = penumbra_bin()
if not BIN.is_file():
    pytest.skip(
        f"SKIPPED LOUDLY: no penumbra binary at {BIN} (set PENUMBRA_BIN or "
        "run `cargo build --release`): the CLI-equality tests did not run",
        allow_module_level=True,
    )

AOVS = ["depth", "position", "normal", "albedo", "mask", "vcoef"]
CASES = [
    # scene, technique, samples, width, height
    ("spheres.toml", "dcs", 16, 48, 40),
    ("tinted.toml", "reference", 8, 40, 32),
    ("tinted.toml", "shadow-map", 1, 40, 32),
]


def cli_exr(tmp_path, scene, technique, samples, width, height, threads):
    exr = tmp_path / f"cli-{threads}.exr"
    png = tmp_path / f"cli-{threads}.png"
    subprocess.run(
        [
            str(BIN), "render", str(SCENES / scene),
            "-o", str(png), "--exr", str(exr),
            "--technique", technique, "--samples", str(samples),
            "--width", str(width), "--height", str(height),
            "--aov", ",".join(AOVS), "--threads", str(threads),
        ],
        check=True,
        capture_output=True,
    )
    with OpenEXR.File(str(exr), separate_channels=True) as f:
        channels = f.channels()
        return {name: np.asarray(c.pixels) for name, c in channels.items()}


def python_channels(out: penumbra.Render):
    """The Render as the EXR's channels: `R, G, B` and `<layer>.<channel>`."""
    channels = {name: out.radiance[..., k] for k, name in enumerate("RGB")}
    for layer, values in out.aovs.items():
        for k, name in enumerate(out.channels[layer]):
            channels[f"{layer}.{name}"] = values if values.ndim == 2 else values[..., k]
    return channels


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("scene, technique, samples, width, height", CASES)
def test_python_render_equals_the_cli_exr_bit_for_bit(
    tmp_path, scene, technique, samples, width, height, threads
):
    cli = cli_exr(tmp_path, scene, technique, samples, width, height, threads)
    out = penumbra.load_scene(SCENES / scene).render(
        technique=technique, samples=samples, width=width, height=height,
        aovs=AOVS, threads=threads,
    )
    ours = python_channels(out)
    assert set(ours) == set(cli)
    for name, values in cli.items():
        assert values.dtype == np.float32, name
        assert values.shape == (height, width), name
        assert ours[name].dtype == np.float32
        # Bits, not values: -0.0 against 0.0 or two NaNs would differ.
        assert values.view(np.uint32).tobytes() == np.ascontiguousarray(
            ours[name]
        ).view(np.uint32).tobytes(), f"{scene} {technique} threads={threads}: channel {name}"
    # Not all black: the comparison compared something.
    assert out.radiance.max() > 0.05
