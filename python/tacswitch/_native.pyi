"""Type stubs of the native extension ``tacswitch._native`` (checked by ``mypy.stubtest``)."""

from typing import Any, final

import numpy as np
from numpy.typing import NDArray

__version__: str
__all__ = [
    "SLIP_N_BASE_FEATURES",
    "SLIP_N_FEATURES",
    "SLIP_N_FRAME",
    "SLIP_N_SNAP",
    "SlipDetector",
    "SlipFeatures",
    "Tracker",
    "__version__",
    "dilate_mask",
    "estimate_pitch",
    "extract_markers",
    "inpaint_biharmonic",
    "inpaint_telea",
    "match_markers",
    "merge_patches",
    "tile",
]

def extract_markers(
    img: NDArray[np.uint8],
    *,
    polarity: str = "dark",
    block_size: int | None = None,
    threshold: float | None = None,
    min_area: int | None = None,
    max_area: int | None = None,
    min_fill: float = 0.35,
    max_aspect: float = 3.0,
    dilate: int = 0,
    adaptive: bool = False,
    exclude_border: bool = True,
) -> dict[str, Any]: ...
def dilate_mask(mask: NDArray[np.bool_], iterations: int = 1) -> NDArray[np.bool_]: ...
def match_markers(
    ref_pts: NDArray[np.float32],
    cur_pts: NDArray[np.float32],
    max_dist: float | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.bool_], NDArray[np.int64], float]: ...
def estimate_pitch(points: NDArray[np.float32]) -> float | None: ...
def inpaint_telea(img: NDArray[Any], mask: NDArray[np.uint8], radius: int) -> NDArray[Any]: ...
def inpaint_biharmonic(img: NDArray[Any], mask: NDArray[np.uint8]) -> NDArray[Any]: ...
def tile(
    img: NDArray[Any], patch: int, overlap: int
) -> tuple[NDArray[Any], NDArray[np.int64]]: ...
def merge_patches(
    patches: NDArray[Any],
    origins: NDArray[np.int64],
    height: int,
    width: int,
    mode: str = "average",
) -> NDArray[Any]: ...

@final
class Tracker:
    def __new__(
        cls,
        ref_pts: NDArray[np.float32],
        max_dist: float | None = None,
        *,
        polarity: str = "dark",
        block_size: int | None = None,
        threshold: float | None = None,
        min_area: int | None = None,
        max_area: int | None = None,
        min_fill: float = 0.35,
        max_aspect: float = 3.0,
        exclude_border: bool = True,
    ) -> Tracker: ...
    def update_points(
        self, points: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.bool_], int]: ...
    def update_image(
        self, img: NDArray[np.uint8]
    ) -> tuple[NDArray[np.float32], NDArray[np.bool_], int]: ...
    def reset(self) -> None: ...
    @property
    def reference(self) -> NDArray[np.float32]: ...
    @property
    def positions(self) -> NDArray[np.float32]: ...
    @property
    def max_dist(self) -> float: ...
    @property
    def frame(self) -> int: ...

@final
class SlipDetector:
    def __new__(
        cls,
        threshold_px: float | None,
        rigid_threshold_px: float | None = None,
        active_fraction: float = 0.5,
        points: NDArray[np.float32] | None = None,
    ) -> SlipDetector: ...
    def update(self, motion: NDArray[np.float32], valid: NDArray[np.bool_]) -> dict[str, Any]: ...
    def reset(self) -> None: ...
    @property
    def first_slip(self) -> int | None: ...

SLIP_N_BASE_FEATURES: int
SLIP_N_FEATURES: int
SLIP_N_FRAME: int
SLIP_N_SNAP: int

@final
class SlipFeatures:
    def __new__(cls, points: NDArray[np.float32], pitch: float,
                still_filter: bool = False) -> SlipFeatures: ...
    @property
    def still_filter(self) -> bool: ...
    def update(self, motion: NDArray[np.float32], valid: NDArray[np.bool_]
               ) -> NDArray[np.float32]: ...
    def reset(self) -> None: ...
    def __len__(self) -> int: ...
