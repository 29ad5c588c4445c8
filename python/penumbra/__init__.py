"""penumbra: physically based soft shadows, rendered into NumPy arrays.

The smallest complete use::

    import penumbra
    scene = penumbra.load_scene("scenes/spheres.toml")
    out = scene.render(technique="dcs", samples=64, width=256, height=256)
    out.radiance            # float32, H x W x 3, linear, row 0 at the top

A render is a pure function of the scene, the options and the seed: the
same call gives the same bits on any thread count, and the same bits as
``penumbra render ... --exr`` on the command line (docs/python.md).
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _penumbra
from ._penumbra import SceneError

__all__ = [
    "AOVS",
    "Render",
    "Scene",
    "SceneError",
    "compare",
    "load_scene",
    "techniques",
]

__version__ = "0.1.0"

#: Every AOV layer a render can return besides radiance, in output order.
AOVS: Tuple[str, ...] = ("depth", "position", "normal", "albedo", "mask", "vcoef")
"""The layers every render can return; a progressive render can also
return ``"error"`` (``error.Y``, ``error.V``: docs/progressive.md)."""

PathLike = Union[str, "os.PathLike[str]"]


def _unsigned(name: str, value: Any, optional: bool = False) -> Optional[int]:
    """`value` as a non-negative int, or an error naming the parameter.

    Only the type and sign are checked here (so that the native call's
    conversion never fails without a name); every range is checked once,
    by the Rust library, with the command line's limits.
    """
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"parameter `{name}`: expected an int, got {type(value).__name__}")
    if value < 0:
        raise ValueError(f"parameter `{name}`: {value} is negative")
    return int(value)


def _option_words(options: Dict[str, Any]) -> List[str]:
    """Technique options as the command line's words.

    ``map_size=1024`` becomes ``--map-size 1024``, ``True``
    a bare flag (``False`` and ``None`` leave the default), a list or
    tuple comma-joined. The words go through the command line's own
    parser, so the names, values and errors are the CLI's.
    """
    words: List[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            words.append(flag)
        elif isinstance(value, (list, tuple)):
            words += [flag, ",".join(str(v) for v in value)]
        else:
            words += [flag, str(value)]
    return words


def _aov_names(aovs: Union[str, Iterable[str], None]) -> List[str]:
    if aovs is None:
        return []
    if isinstance(aovs, str):
        return list(AOVS) if aovs == "all" else [a.strip() for a in aovs.split(",") if a.strip()]
    return [str(a) for a in aovs]


class Render:
    """A finished render: float32 NumPy arrays and its report as data.

    Every image is row-major with row 0 at the top, like the PNG and EXR
    the command line writes.

    Attributes:
        radiance: linear radiance, ``H x W x 3``.
        aovs: the requested AOV layers (and any the technique adds) by
            name: ``H x W`` for a one-channel layer (``depth``, ``mask``),
            ``H x W x C`` otherwise (``position``, ``normal``, ``albedo``:
            C = 3; ``vcoef``: C = number of lights). Background pixels are 0
            (``mask`` tells them apart).
        channels: each layer's channel names (``"normal": ["X", "Y", "Z"]``),
            the EXR's ``<layer>.<channel>``.
        vcoef: the visibility coefficient per light, ``H x W`` each, as the
            technique returned it (whatever is requested as AOVs).
        timings: seconds per pass, in pass order.
        explain: the ``--explain`` report: technique, samples, SIMD level,
            threads, buffers, notes.
        warnings: what the result leaves out of the scene, in words.
    """

    __slots__ = (
        "width",
        "height",
        "radiance",
        "aovs",
        "channels",
        "vcoef",
        "timings",
        "explain",
        "warnings",
    )

    def __init__(self, data: Dict[str, Any]) -> None:
        self.width: int = data["width"]
        self.height: int = data["height"]
        self.radiance: np.ndarray = data["radiance"]
        self.aovs: Dict[str, np.ndarray] = {}
        self.channels: Dict[str, List[str]] = {}
        for name, (values, channel_names) in data["aovs"].items():
            if len(channel_names) == 1 and name != "vcoef":
                values = values.reshape(values.shape[:2])
            self.aovs[name] = values
            self.channels[name] = list(channel_names)
        self.vcoef: List[np.ndarray] = list(data["vcoef"])
        self.timings: Dict[str, float] = dict(data["timings"])
        self.explain: Dict[str, Any] = json.loads(data["explain_json"])
        self.warnings: List[str] = list(data["warnings"])

    def srgb(self) -> np.ndarray:
        """Radiance clamped to [0, 1] and sRGB-encoded (``H x W x 3``,
        float32), as the PNG stores it before rounding to 8 bits: ready for
        ``matplotlib.pyplot.imshow``."""
        x = np.clip(self.radiance, 0.0, 1.0)
        return np.where(
            x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055
        ).astype(np.float32)

    def __repr__(self) -> str:
        layers = ", ".join(self.aovs) or "no AOVs"
        total = sum(self.timings.values())
        return (
            f"<penumbra.Render {self.width}x{self.height}, {len(self.vcoef)} light(s), "
            f"{layers}, {total * 1e3:.1f} ms>"
        )


class Scene:
    """A loaded scene: from a file with :func:`load_scene`, or from TOML
    text with :meth:`Scene.from_toml`. It is immutable; render it as often
    as you like, from any thread."""

    __slots__ = ("_native",)

    def __init__(self, native: "_penumbra.NativeScene") -> None:
        if not isinstance(native, _penumbra.NativeScene):
            raise TypeError("use penumbra.load_scene(path) or penumbra.Scene.from_toml(text)")
        self._native = native

    @classmethod
    def from_toml(cls, text: str, base_dir: PathLike = ".") -> "Scene":
        """A scene from TOML text (docs/scene-format.md); relative paths in
        it (models, textures) resolve from ``base_dir``. An invalid scene
        raises :class:`SceneError` with the line."""
        return cls(_penumbra.scene_from_toml(text, os.fspath(base_dir)))

    @property
    def name(self) -> str:
        """``[scene] name``, or the file's stem (``"scene"`` for text)."""
        return self._native.summary()[0]

    @property
    def width(self) -> int:
        """The camera's width in pixels (a render may override it)."""
        return self._native.summary()[1]

    @property
    def height(self) -> int:
        """The camera's height in pixels (a render may override it)."""
        return self._native.summary()[2]

    @property
    def lights(self) -> int:
        """Number of lights (the length of :attr:`Render.vcoef`)."""
        return self._native.summary()[3]

    @property
    def triangles(self) -> int:
        """Number of triangles."""
        return self._native.summary()[4]

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
        """Renders the scene; see :class:`Render` for what comes back.

        Args:
            technique: a name from :func:`techniques` (default ``"dcs"``,
                exact depth complexity sampling).
            samples: light samples per pixel and light (1..=2**20).
            width, height: override the camera's size.
            seed: the seed of every random choice.
            aovs: layers to return besides radiance (:data:`AOVS`, or
                ``"all"``).
            threads: worker threads (default: all cores); the image is the
                same for every count.
            pattern: light sample placement (``"stratified"`` by default;
                ``"sobol"``, ``"interleaved:4"``, ... as ``--pattern``).
            target_error, max_samples, max_time: progressive rendering
                (docs/progressive.md): independent sets of ``samples``
                until the estimated radiance RMSE is at most
                ``target_error``, within ``max_samples`` samples in all and
                ``max_time`` seconds; ``explain["convergence"]`` says how
                it stopped, and ``aovs=["error"]`` returns the per-pixel
                estimate.
            **options: the techniques' own options, named as the command
                line's without the dashes: ``map_size=1024`` for
                ``--map-size 1024``, ``True`` for a bare flag.

        Raises:
            ValueError: a parameter out of range (the message names it).
            KeyboardInterrupt: Ctrl-C while rendering.
        """
        data = self._native.render(
            str(technique),
            _unsigned("samples", samples),
            _unsigned("width", width, optional=True),
            _unsigned("height", height, optional=True),
            _unsigned("seed", seed),
            _aov_names(aovs),
            _unsigned("threads", threads, optional=True),
            None if pattern is None else str(pattern),
            _option_words(options),
            None if target_error is None else float(target_error),
            _unsigned("max_samples", max_samples, optional=True),
            None if max_time is None else float(max_time),
        )
        return Render(data)

    def __repr__(self) -> str:
        name, width, height, lights, triangles = self._native.summary()
        return (
            f"<penumbra.Scene {name!r}: {width}x{height}, {lights} light(s), "
            f"{triangles} triangles>"
        )


def load_scene(path: PathLike) -> Scene:
    """Loads a scene file (TOML, docs/scene-format.md). An invalid scene
    raises :class:`SceneError` whose message names the file and line; a
    missing file raises :class:`OSError`."""
    return Scene(_penumbra.load_scene(os.fspath(path)))


def techniques() -> List[Dict[str, Any]]:
    """Every registered technique and what it supports, in registry order:
    dicts with ``name``, ``summary``, ``module``, ``page``, ``exact``,
    ``exact_image``, ``output``, ``support`` (per kind of scene content)
    and ``cost`` -- what ``penumbra techniques --json`` prints."""
    return json.loads(_penumbra.techniques_json())


def compare(
    scenes: Union[PathLike, Sequence[PathLike]],
    techniques: Sequence[str] = ("dcs", "penumbra-casting", "reference"),
    samples: Sequence[int] = (4, 16, 64, 256),
    reference_samples: int = 4096,
    patterns: Sequence[str] = ("stratified",),
    repeat: int = 3,
    width: Optional[int] = None,
    height: Optional[int] = None,
    threads: Optional[int] = None,
    seed: int = 0,
    out: Optional[PathLike] = None,
    cache_dir: Optional[PathLike] = None,
    images: bool = True,
    sweep_settings: bool = False,
) -> List[Dict[str, Any]]:
    """Runs ``penumbra compare``: each technique in its default
    configuration (what ``Scene.render`` renders) at every sample count
    and pattern, against each scene's reference, timed; with
    ``sweep_settings=True`` (``--sweep-settings``) also every other
    quality setting the technique sweeps (map sizes, DCS's centre
    silhouettes, ...). Returns one dict per row of results.csv (its
    columns as keys; empty cells are ``None``). With ``out`` the files
    are written too (results.csv/json/md, charts and, unless
    ``images=False``, images); without it nothing is written but the
    reference cache. Other arguments are the command line's, with the
    same defaults."""
    if isinstance(scenes, (str, os.PathLike)):
        scenes = [scenes]
    text = _penumbra.compare_json(
        [os.fspath(s) for s in scenes],
        [str(t) for t in techniques],
        [_unsigned("samples", s) for s in samples],
        _unsigned("reference_samples", reference_samples),
        [str(p) for p in patterns],
        _unsigned("repeat", repeat),
        _unsigned("width", width, optional=True),
        _unsigned("height", height, optional=True),
        _unsigned("threads", threads, optional=True),
        _unsigned("seed", seed),
        None if out is None else os.fspath(out),
        None if cache_dir is None else os.fspath(cache_dir),
        not images,
        bool(sweep_settings),
    )
    return json.loads(text)
