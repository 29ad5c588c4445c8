"""penumbra: physically based soft shadows, rendered into NumPy arrays.

    import penumbra
    scene = penumbra.load_scene("scenes/spheres.toml")
    out = scene.render(technique="dcs", samples=64, width=256, height=256)
    out.radiance            # float32, H x W x 3, linear, row 0 at the top
"""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._penumbra import SceneError as SceneError

__version__: str

#: Every AOV layer a render can return besides radiance, in output order:
#: ``("depth", "position", "normal", "albedo", "mask", "vcoef")``.
AOVS: Tuple[str, ...]

_Path = Union[str, os.PathLike[str]]
_F32 = npt.NDArray[np.float32]

class Render:
    """A finished render: float32 NumPy arrays (row 0 at the top) and its
    report as data."""

    width: int
    """Width in pixels."""
    height: int
    """Height in pixels."""
    radiance: _F32
    """Linear radiance, ``H x W x 3``."""
    aovs: Dict[str, _F32]
    """AOV layers by name: ``H x W`` for ``depth`` and ``mask``, ``H x W x C``
    otherwise (``position``, ``normal``, ``albedo``: 3; ``vcoef``: one per
    light). Background pixels are 0."""
    channels: Dict[str, List[str]]
    """Each layer's channel names, as in the EXR (``"normal": ["X", "Y", "Z"]``)."""
    vcoef: List[_F32]
    """Visibility coefficient per light, ``H x W`` each, as the technique
    returned it (requested as an AOV or not)."""
    timings: Dict[str, float]
    """Seconds per pass, in pass order."""
    explain: Dict[str, Any]
    """The ``--explain`` report: ``technique``, ``samples``, ``simd`` (the
    SIMD level), ``threads``, ``buffers`` (dicts of ``name``, ``detail``,
    ``bytes``) and ``notes``."""
    warnings: List[str]
    """What the result leaves out of the scene, in words."""

    def srgb(self) -> _F32:
        """Radiance clamped to [0, 1] and sRGB-encoded, as the PNG stores
        it before rounding: ready for ``matplotlib.pyplot.imshow``."""

class Scene:
    """A loaded scene (immutable; render it as often as you like)."""

    @classmethod
    def from_toml(cls, text: str, base_dir: _Path = ".") -> Scene:
        """A scene from TOML text; relative paths resolve from ``base_dir``.
        Raises :class:`SceneError` (with the line) when it is invalid."""
    @property
    def name(self) -> str:
        """``[scene] name``, or the file's stem (``"scene"`` for text)."""
    @property
    def width(self) -> int:
        """The camera's width in pixels."""
    @property
    def height(self) -> int:
        """The camera's height in pixels."""
    @property
    def lights(self) -> int:
        """Number of lights."""
    @property
    def triangles(self) -> int:
        """Number of triangles."""
    def render(
        self,
        technique: str = "dcs",
        samples: int = 64,
        width: Optional[int] = None,
        height: Optional[int] = None,
        seed: int = 0,
        aovs: Union[str, Sequence[str], None] = (),
        threads: Optional[int] = None,
        pattern: Optional[str] = None,
        target_error: Optional[float] = None,
        max_samples: Optional[int] = None,
        max_time: Optional[float] = None,
        **options: Any,
    ) -> Render:
        """Renders the scene. The GIL is released meanwhile; Ctrl-C raises
        KeyboardInterrupt. The same arguments give the same bits on any
        thread count, equal to ``penumbra render --exr``'s.

        Args:
            technique: a name from :func:`techniques`.
            samples: light samples per pixel and light (1..=2**20).
            width: overrides the camera's width.
            height: overrides the camera's height.
            seed: the seed of every random choice.
            aovs: layers besides radiance (names from :data:`AOVS`, or ``"all"``).
            threads: worker threads (default: all cores).
            pattern: light sample placement, as ``--pattern``.
            **options: technique options as the CLI's flags without dashes
                (``map_size=2048`` for ``--map-size 2048``).

        Raises:
            ValueError: a parameter out of range; the message names it.
        """

def load_scene(path: _Path) -> Scene:
    """Loads a scene file. Raises :class:`SceneError` naming the file and
    line when it is invalid, :class:`OSError` when it cannot be read."""

def techniques() -> List[Dict[str, Any]]:
    """Every registered technique and its capabilities: dicts with ``name``,
    ``summary``, ``module``, ``page``, ``exact``, ``exact_image``, ``output``,
    ``support`` and ``cost`` (what ``penumbra techniques --json`` prints)."""

def compare(
    scenes: Union[_Path, Sequence[_Path]],
    techniques: Sequence[str] = ("dcs", "penumbra-casting", "reference"),
    samples: Sequence[int] = (4, 16, 64, 256),
    reference_samples: int = 4096,
    patterns: Sequence[str] = ("stratified",),
    repeat: int = 3,
    width: Optional[int] = None,
    height: Optional[int] = None,
    threads: Optional[int] = None,
    seed: int = 0,
    out: Optional[_Path] = None,
    cache_dir: Optional[_Path] = None,
    images: bool = True,
    sweep_settings: bool = False,
) -> List[Dict[str, Any]]:
    """Runs ``penumbra compare`` and returns one dict per row of
    results.csv (its columns as keys; empty cells are ``None``); with
    ``out`` the files are written there too. Each technique runs in its
    default configuration at every sample count and pattern; with
    ``sweep_settings=True`` also every other quality setting it sweeps
    (``--sweep-settings``)."""
