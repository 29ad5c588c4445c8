"""The native module (Rust, pyo3). Use the ``penumbra`` package instead."""

from typing import Any, Dict, List, Optional, Tuple

CANCEL_WIRED: bool
COMPARE_WIRED: bool

class SceneError(ValueError):
    """A scene file (or TOML text) is invalid; the message names the file
    and line."""

class NativeScene:
    def summary(self) -> Tuple[str, int, int, int, int]: ...
    def render(
        self,
        technique: str,
        samples: int,
        width: Optional[int],
        height: Optional[int],
        seed: int,
        aovs: List[str],
        threads: Optional[int],
        pattern: Optional[str],
        option_args: List[str],
        target_error: Optional[float],
        max_samples: Optional[int],
        max_time: Optional[float],
    ) -> Dict[str, Any]: ...

def load_scene(path: str) -> NativeScene: ...
def scene_from_toml(text: str, base_dir: str) -> NativeScene: ...
def techniques_json() -> str: ...
def defaults_json() -> str: ...

def compare_json(
    scenes: List[str],
    techniques: List[str],
    samples: List[int],
    reference_samples: int,
    patterns: List[str],
    repeat: int,
    width: Optional[int],
    height: Optional[int],
    threads: Optional[int],
    seed: int,
    out: Optional[str],
    cache_dir: Optional[str],
    no_images: bool,
    sweep_settings: bool,
) -> str: ...
