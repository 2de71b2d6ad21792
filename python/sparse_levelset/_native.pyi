"""Type stubs of the compiled extension (used through the `sparse_levelset` package, whose
functions and classes carry the documentation)."""

from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str
SIMD_LEVEL: str

_Progress = Optional[Callable[[dict], object]]
_F32 = npt.NDArray[np.float32]
_Mesh = Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32], _F32]

_Bool = npt.NDArray[np.bool_]
_Axes3 = Tuple[float, float, float]
_Periodic3 = Tuple[bool, bool, bool]

def distance(
    phi: _F32,
    dx: _Axes3,
    order: int,
    narrow: Optional[float],
    periodic: _Periodic3,
    mask: Optional[_Bool] = ...,
    progress: _Progress = ...,
) -> Tuple[_F32, _Bool]: ...
def travel_time(
    phi: _F32,
    speed: _F32,
    dx: _Axes3,
    order: int,
    narrow: Optional[float],
    periodic: _Periodic3,
    mask: Optional[_Bool] = ...,
    progress: _Progress = ...,
) -> Tuple[_F32, _Bool]: ...
def extension_velocities(
    phi: _F32,
    speed: _F32,
    dx: _Axes3,
    order: int,
    narrow: Optional[float],
    periodic: _Periodic3,
    mask: Optional[_Bool] = ...,
    ext_mask: Optional[_Bool] = ...,
    progress: _Progress = ...,
) -> Tuple[_F32, _Bool, _F32]: ...
def isosurface(
    volume: _F32,
    level: Optional[float],
    spacing: Tuple[float, float, float],
    inside: str,
    reverse: bool,
    step: int = ...,
    mask: Optional[npt.NDArray[np.bool_]] = ...,
    closed: bool = ...,
    allow_degenerate: bool = ...,
    progress: _Progress = ...,
) -> Tuple[_F32, npt.NDArray[np.int32], _F32, npt.NDArray[np.float32]]: ...
def save_mesh(
    path: str,
    verts: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    normals: Optional[npt.NDArray[np.float64]] = ...,
) -> None: ...
def load_mesh(path: str) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]: ...

class LevelSet:
    @staticmethod
    def from_dense(
        phi: _F32, voxel_size: float, origin: Tuple[float, float, float], half_width: float
    ) -> LevelSet: ...
    @staticmethod
    def from_mesh(
        verts: npt.NDArray[np.float64],
        faces: npt.NDArray[np.int64],
        voxel_size: Optional[float],
        half_width: float,
        progress: _Progress = ...,
    ) -> LevelSet: ...
    @staticmethod
    def shape(
        kind: str,
        center: Tuple[float, float, float],
        voxel_size: float,
        half_width: float,
        radius: Optional[float] = ...,
        minor_radius: Optional[float] = ...,
        sizes: Optional[Tuple[float, float, float]] = ...,
    ) -> LevelSet: ...
    @staticmethod
    def load(
        path: str, voxel_size: float, origin: Tuple[float, float, float], half_width: float
    ) -> LevelSet: ...
    def save(self, path: str, margin: int, compression: str) -> None: ...
    def to_dense(self, lo: Tuple[int, int, int], hi: Tuple[int, int, int]) -> _F32: ...
    def value(self, points: npt.NDArray[np.float64]) -> _F32: ...
    def measure(self, delta_width: float = ...) -> dict: ...
    def union(self, other: LevelSet) -> LevelSet: ...
    def intersection(self, other: LevelSet) -> LevelSet: ...
    def difference(self, other: LevelSet) -> LevelSet: ...
    def __or__(self, other: LevelSet) -> LevelSet: ...
    def __and__(self, other: LevelSet) -> LevelSet: ...
    def __sub__(self, other: LevelSet) -> LevelSet: ...
    def mesh(self, level: float = ..., coarsen: int = ..., progress: _Progress = ...) -> _Mesh: ...
    def render(
        self,
        width: int,
        height: int,
        azimuth: float,
        elevation: float,
        fov: float,
        samples: int,
        ground: bool,
        shadows: bool,
        progress: _Progress = ...,
    ) -> npt.NDArray[np.uint8]: ...
    def filter(self, ops: List[str]) -> LevelSet: ...
    def reinitialize(
        self, order: int = ..., half_width: Optional[float] = ..., progress: _Progress = ...
    ) -> LevelSet: ...
    def band(self) -> Tuple[npt.NDArray[np.int32], _F32]: ...
    voxel_size: float
    origin: Tuple[float, float, float]
    half_width: float
    background: float
    band_voxels: int
    bbox: Tuple[Tuple[int, int, int], Tuple[int, int, int]]
    memory: int
    checksum: int

class Simulation:
    def __init__(
        self,
        levelset: LevelSet,
        *,
        speed: float = ...,
        speed_field: Optional[_F32] = ...,
        curvature: float = ...,
        velocity: Optional[Tuple[float, float, float]] = ...,
        velocity_field: Optional[_F32] = ...,
        field_origin: Tuple[int, int, int] = ...,
        volume_conserving: bool = ...,
        scheme: str = ...,
        integrator: str = ...,
        cfl: float = ...,
        dt: Optional[float] = ...,
        renormalization: str = ...,
        renormalization_sweeps: int = ...,
        grid: str = ...,
        threads: Optional[int] = ...,
    ) -> None: ...
    def step(self) -> dict: ...
    def run_until(
        self, t: float, callback: Optional[Callable[[Simulation, dict], object]] = ..., max_steps: int = ...
    ) -> int: ...
    def measure(self) -> dict: ...
    time: float
    steps: int
    collapsed: bool
    levelset: LevelSet

class Image:
    def __init__(self, array: _F32, spacing: Tuple[float, float, float]) -> None: ...
    array: _F32
    shape: Sequence[int]
    spacing: Sequence[float]
    affine: Sequence[Sequence[float]]

class Segmentation:
    mask: npt.NDArray[np.uint8]
    levelset: LevelSet
    report_json: str
    leaked: bool
    def mesh(self) -> _Mesh: ...
    def save_mask(self, path: str) -> None: ...

def load_image(path: str, spacing: Optional[Tuple[float, float, float]] = ...) -> Image: ...
def segment(
    image: Image,
    method: str,
    seeds: Sequence[Sequence[float]],
    world: bool,
    init_mask: Optional[npt.NDArray[np.uint8]],
    init_levelset: Optional[_F32],
    lower_threshold: Optional[float],
    upper_threshold: Optional[float],
    sigma: Optional[float],
    propagation_scaling: Optional[float],
    curvature_scaling: Optional[float],
    advection_scaling: Optional[float],
    edge_scale: Optional[float],
    sigmoid: Optional[Tuple[float, float]],
    lambda1: float,
    lambda2: float,
    nu: float,
    maximum_rms_error: float,
    volume_change: float,
    window: int,
    number_of_iterations: int,
    terms: Sequence[Tuple[str, float]],
    threads: Optional[int],
    progress: _Progress = ...,
    feature: Optional[_F32] = ...,
    leak_guard: bool = ...,
    first_edge: bool = ...,
    fast_start: bool = ...,
) -> Segmentation: ...
