"""Level sets on sparse grids: signed distances, isosurfaces, evolving interfaces and
image segmentation, on the Sorted Tile List engine of the ``sparse-levelset`` Rust library.

Arrays
------
Every function takes NumPy arrays of float32 or float64 (any real dtype for images), in
C or Fortran order. The work is done in float32: a float64 array is converted (a copy),
as is an array that is neither C- nor Fortran-contiguous; a contiguous float32 array is
read without copying. Results of ``distance`` come back in the input's float dtype.

Coordinates follow the libraries these functions stand in for:

* ``distance`` and ``isosurface`` work on array axes, like scikit-fmm and scikit-image:
  ``isosurface`` returns vertices in array-axis order (``verts[:, 0]`` along axis 0) times
  ``spacing``, exactly as ``skimage.measure.marching_cubes``.
* ``LevelSet`` objects live in world space: points, vertices and mesh coordinates are
  ``(x, y, z)``; a dense field is indexed ``phi[z, y, x]`` (the ``.npy`` convention of the
  ``levelset`` command line), voxel ``(i, j, k)`` sits at ``origin + voxel_size * (i, j, k)``.
* ``segment`` takes seeds as array indices in the image array's axis order and ``spacing``
  per array axis; an ``Image`` read by ``load_image`` is indexed ``[i, j, k]`` along the
  file's x, y, z axes, as nibabel does.

Long calls release the GIL, honour Ctrl-C (``KeyboardInterrupt``, nothing changed) and
take an optional ``progress`` callback, called from the calling thread with a dict
(``done``/``total``, or a segmentation's ``iteration``, ``rms``, ...). Errors are Python
exceptions carrying the library's message, the class chosen by the error's kind:
``ValueError`` for bad arrays, parameters and file extensions, ``OSError`` for files that
cannot be read or written, ``MemoryError`` when the result cannot fit, ``RuntimeError`` when
the computation failed.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Callable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

__all__ = [
    "distance",
    "travel_time",
    "extension_velocities",
    "isosurface",
    "LevelSet",
    "Simulation",
    "evolve2d",
    "Image",
    "load_image",
    "segment",
    "Segmentation",
    "LeakWarning",
    "ContrastWarning",
    "VanishedWarning",
    "save_mesh",
    "load_mesh",
    "__version__",
    "SIMD_LEVEL",
]

__version__ = _native.__version__

#: The instruction-set level the kernels run at, detected when the module is imported:
#: ``"avx512"`` (x86-64-v4), ``"avx2"`` (AVX2 and FMA) or ``"baseline"``. The environment
#: variable ``LEVELSET_SIMD`` forces one; a level the CPU cannot run is refused at import.
SIMD_LEVEL: str = _native.SIMD_LEVEL

Progress = Optional[Callable[[dict], object]]


def _float32(a, name: str, ndims: Sequence[int] = (3,), allow_int: bool = False) -> np.ndarray:
    """`a` as a float32 array of one of `ndims` dimensions, C- or Fortran-contiguous,
    copied only when the dtype or the layout requires it."""
    if isinstance(a, np.ma.MaskedArray):
        if np.ma.getmaskarray(a).any():
            raise ValueError(
                f"{name}: masked arrays with masked elements are not supported (scikit-fmm's "
                "obstacles); fill the masked values or pass the plain array"
            )
        a = a.data
    a = np.asarray(a)
    if a.dtype.kind not in ("fiub" if allow_int else "fiu"):
        raise ValueError(f"{name}: expected a real-valued array, got dtype {a.dtype}")
    if a.ndim not in ndims:
        want = " or ".join(f"{d}-D" for d in ndims)
        raise ValueError(f"{name}: expected a {want} array, got shape {a.shape}")
    if a.size == 0:
        raise ValueError(f"{name}: the array is empty (shape {a.shape})")
    if a.dtype == np.float32 and (a.flags.c_contiguous or a.flags.f_contiguous):
        return a
    if a.flags.f_contiguous and not a.flags.c_contiguous:
        return np.asfortranarray(a, dtype=np.float32)
    return np.ascontiguousarray(a, dtype=np.float32)


def _spacing(spacing, ndim: int, name: str = "spacing") -> Tuple[float, ...]:
    s = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (ndim,))
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {tuple(s)}")
    return tuple(float(v) for v in s)


class _Fmm:
    """The arguments of a scikit-fmm call, checked and laid out for the native functions:
    ``phi`` as a 3-D float32 array (1-D and 2-D arrays get leading axes of length 1), the
    obstacle mask, ``dx`` and ``periodic`` per axis of that array, ``narrow``."""

    def __init__(self, phi, dx, order, narrow, periodic, self_test):
        if self_test not in (0, 1):
            raise ValueError("self_test must be 0 or 1")
        if not (isinstance(order, (int, np.integer)) and order in (1, 2)):
            raise ValueError(f"order must be 1 or 2, got {order!r}")
        self.out_dtype = np.float64 if np.asarray(phi).dtype == np.float64 else np.float32
        mask = np.ma.getmaskarray(phi) if isinstance(phi, np.ma.MaskedArray) else None
        a = _float32(np.ma.getdata(phi), "phi", ndims=(1, 2, 3))
        nd = a.ndim
        self.shape = a.shape
        pad = (1,) * (3 - nd)
        self.phi = a.reshape(pad + a.shape)
        self.fortran = self.phi.flags.f_contiguous and not self.phi.flags.c_contiguous
        d = np.asarray(dx, dtype=np.float64)
        if d.ndim == 0:
            d = np.full(nd, float(d))
        if d.shape != (nd,):
            raise ValueError(f"dx must be a number or one per axis of phi ({nd}), got {dx!r}")
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise ValueError(f"dx must be finite and greater than zero, got {tuple(d)}")
        self.dx = (1.0,) * (3 - nd) + tuple(float(v) for v in d)
        if isinstance(periodic, (bool, np.bool_)):
            per = (bool(periodic),) * nd
        elif hasattr(periodic, "__len__") and len(periodic) == nd:
            per = tuple(bool(v) for v in periodic)
        else:
            raise ValueError(
                'parameter "periodic" must be of type bool or sequence of type bool of '
                f"length phi.ndim ({nd}), got {periodic!r}"
            )
        self.periodic = (False,) * (3 - nd) + per
        if narrow is None:
            narrow = 0.0
        narrow = float(narrow)
        if not narrow >= 0 or not np.isfinite(narrow):
            raise ValueError(
                f'parameter "narrow" must be greater than or equal to zero, got {narrow}'
            )
        self.narrow = narrow if narrow > 0 else None
        self.mask = None if mask is None or not mask.any() else self.laid_out(mask, "mask", bool)

    def laid_out(self, b, name: str, dtype):
        """``b`` (of ``phi``'s shape) as a 3-D array in ``phi``'s memory order."""
        b = np.asarray(b)
        if b.shape != self.shape:
            raise ValueError(
                f"phi and {name} must have the same shape, got {self.shape} and {b.shape}"
            )
        b = b.reshape(self.phi.shape)
        if self.fortran:
            return np.asfortranarray(b, dtype=dtype)
        return np.ascontiguousarray(b, dtype=dtype)

    def speed(self, speed):
        """``speed`` as float32 laid out like ``phi``; its masked elements join the
        obstacles."""
        if isinstance(speed, np.ma.MaskedArray):
            m = np.ma.getmaskarray(speed)
            if np.shape(m) == self.shape and m.any():
                m3 = self.laid_out(m, "speed", bool)
                self.mask = m3 if self.mask is None else (self.mask | m3)
            speed = np.ma.getdata(speed)
        s = np.asarray(speed)
        if s.dtype.kind not in "fiub" or s.ndim == 0:
            raise ValueError(f"speed must be a real-valued array of phi's shape, got {speed!r}")
        return self.laid_out(s, "speed", np.float32)

    def result(self, values, reached):
        """An array of ``phi``'s shape and output dtype, masked where the march did not
        reach (as scikit-fmm: a plain array when every element was reached)."""
        out = values.reshape(self.shape).astype(self.out_dtype, copy=False)
        if reached.all():
            return out
        return np.ma.MaskedArray(out, ~reached.reshape(self.shape))


_FMM_NOTES = """
    As in scikit-fmm: the same arguments in the same order (``self_test`` is accepted and
    ignored: the heap is checked by the library's own tests); masked arrays as obstacles;
    ``periodic`` as a bool or one per axis; ``dx`` as a number or one per axis; elements
    with ``phi == 0`` exactly lie on the zero contour; the result is masked exactly where
    the march did not reach (obstacles, regions the obstacles cut off, beyond ``narrow``;
    masked elements hold 0), a plain array otherwise. Differences, each on purpose:

    * arrays of 1 to 3 dimensions (scikit-fmm: up to 12); the work is done in float32 and
      the result has the input's float dtype (float64 for float64, float32 otherwise;
      scikit-fmm always returns float64);
    * the elements next to the zero contour start from ``|phi| / |grad phi|`` (central
      differences, capped by the linearly interpolated crossings on their edges) rather
      than from the crossings alone: exact for a linear ``phi`` and blind to the scaling of
      ``phi``, hence more accurate when ``phi`` is not a distance;
    * a periodic axis respects the mask across its faces too (scikit-fmm reads masked
      neighbours there);
    * NaN in ``phi`` (outside the mask) is a ``ValueError``, like every other bad input
      (shapes that differ, a bad ``dx``, ``order``, ``narrow``, ``periodic`` or
      ``self_test``, no zero contour); Ctrl-C, or an exception raised by ``progress``,
      stops the call.
"""


def _with_fmm_notes(f):
    """Appends the notes on scikit-fmm compatibility to `f`'s docstring (none under -OO)."""
    if f.__doc__:
        f.__doc__ += _FMM_NOTES
    return f


@_with_fmm_notes
def distance(
    phi,
    dx: Union[float, Sequence[float]] = 1.0,
    self_test: bool = False,
    order: int = 2,
    narrow: Optional[float] = 0.0,
    periodic: Union[bool, Sequence[bool]] = False,
    *,
    progress: Progress = None,
):
    """Signed distance to the zero contour of ``phi`` by fast marching, as
    ``skfmm.distance`` (same arguments, same order).

    ``phi`` is a 1-, 2- or 3-D array (or ``numpy.ma`` masked array: masked elements are
    obstacles the front does not cross); negative values are inside, and the result has
    the sign of ``phi``. The zero contour is located between neighbouring values of
    opposite sign, the distance marched outward from it with first- or second-order
    (default) upwind updates (Sethian's high-accuracy fast marching for ``order=2``), each
    axis's differences divided by its spacing.

    Parameters
    ----------
    dx : grid spacing, one number or one per axis of ``phi`` (finite, > 0).
    self_test : accepted for compatibility (0 or 1), no effect.
    order : 1 or 2.
    narrow : march only up to this distance (world units, >= 0; 0 or ``None``: everywhere);
        elements farther away are masked.
    periodic : ``True`` for periodic boundaries along every axis, or one bool per axis.
    progress : optional callback (see the module docs).

    Returns an array of ``phi``'s shape, or a masked array when some element was not
    reached.
    """
    f = _Fmm(phi, dx, order, narrow, periodic, self_test)
    values, reached = _native.distance(
        f.phi, f.dx, int(order), f.narrow, f.periodic, f.mask, progress
    )
    return f.result(values, reached)


@_with_fmm_notes
def travel_time(
    phi,
    speed,
    dx: Union[float, Sequence[float]] = 1.0,
    self_test: bool = False,
    order: int = 2,
    narrow: Optional[float] = 0.0,
    periodic: Union[bool, Sequence[bool]] = False,
    *,
    progress: Progress = None,
):
    """Travel time of a front that starts at the zero contour of ``phi`` and moves with
    ``speed`` (world units per time unit), as ``skfmm.travel_time`` (same arguments, same
    order): the solution ``T >= 0`` of ``|grad T| * speed = 1`` on both sides of the
    contour.

    ``speed`` has ``phi``'s shape. Elements with ``speed`` below the double-precision
    epsilon (in particular 0), masked elements of ``phi`` or ``speed``, are obstacles and
    come back masked, as in scikit-fmm. A negative or non-finite speed raises
    ``ValueError`` (scikit-fmm masks negative speeds silently; a negative speed is a
    mistake, not an obstacle). The elements next to the contour start at their distance
    over their own speed, as in scikit-fmm. ``narrow`` bounds the travel time. The other
    arguments are those of :func:`distance`.
    """
    f = _Fmm(phi, dx, order, narrow, periodic, self_test)
    sp = f.speed(speed)
    values, reached = _native.travel_time(
        f.phi, sp, f.dx, int(order), f.narrow, f.periodic, f.mask, progress
    )
    return f.result(values, reached)


@_with_fmm_notes
def extension_velocities(
    phi,
    speed,
    dx: Union[float, Sequence[float]] = 1.0,
    self_test: bool = False,
    order: int = 2,
    ext_mask=None,
    narrow: Optional[float] = 0.0,
    periodic: Union[bool, Sequence[bool]] = False,
    *,
    progress: Progress = None,
):
    """The signed distance of :func:`distance` and ``speed`` extended from the zero contour
    of ``phi`` along the distance's normals (``grad f_ext . grad d = 0``, after
    Adalsteinsson and Sethian 1999), as ``skfmm.extension_velocities`` (same arguments,
    same order): returns ``(d, f_ext)``.

    Only ``speed`` next to the zero contour is read (any finite value): each of those
    elements takes ``speed`` interpolated to the nearest crossing along each axis,
    averaged over the axes with the weights of scikit-fmm; ``ext_mask`` (a boolean array of
    ``phi``'s shape) marks elements whose own value must not be used there (the
    neighbour's across the contour is taken instead). Every other element takes the
    average of its upwind neighbours' values weighted by their share in its distance: each
    axis's component of ``grad d``, from the second-order one-sided difference where the
    element two steps upwind is known (scikit-fmm always takes the first-order one; the
    second-order one follows the normals more closely, so the extension is more accurate).
    Masked elements of ``speed`` join the obstacles. The other arguments are those of
    :func:`distance`; both results are masked where the march did not reach.
    """
    f = _Fmm(phi, dx, order, narrow, periodic, self_test)
    sp = f.speed(speed)
    em = None if ext_mask is None else f.laid_out(ext_mask, "ext_mask", bool)
    d, reached, ext = _native.extension_velocities(
        f.phi, sp, f.dx, int(order), f.narrow, f.periodic, f.mask, em, progress
    )
    return f.result(d, reached), f.result(ext, reached)


def isosurface(
    volume,
    level: Optional[float] = 0.0,
    spacing: Sequence[float] = (1.0, 1.0, 1.0),
    *,
    gradient_direction: str = "descent",
    step_size: int = 1,
    allow_degenerate: bool = True,
    method: str = "lewiner",
    mask=None,
    closed: bool = False,
    inside: Optional[str] = None,
    progress: Progress = None,
):
    """The surface ``volume == level`` as a welded triangle mesh, in the form of
    ``skimage.measure.marching_cubes``: every keyword of ``marching_cubes`` is accepted
    with its meaning, and the result is ``(verts, faces, normals, values)``.

    * ``verts`` ``(n, 3)`` float32: positions in array-axis order times ``spacing``.
    * ``faces`` ``(m, 3)`` int32: vertex indices.
    * ``normals`` ``(n, 3)`` float32 unit vectors along ``-∇volume`` (toward lower values),
      as scikit-image's, whatever ``gradient_direction``; with anisotropic ``spacing`` they
      are the gradient in world units (scikit-image's are in index units).
    * ``values`` ``(n,)`` float32: per vertex, the largest value range (largest minus
      smallest corner value) of the cells whose triangles use it, as scikit-image defines
      them.

    ``level``: ``None`` takes the midpoint of the smallest and largest finite values (the
    default of scikit-image); the default here is ``0.0``, the zero level set of a signed
    distance. A given level must lie strictly inside the data range.

    ``gradient_direction``: as scikit-image, only the faces' winding depends on it:
    ``"ascent"`` gives faces counter-clockwise seen from where the normals point,
    ``"descent"`` (the default) the reverse. A value equal to ``level`` counts as below it.

    ``step_size``: mesh the lattice of every ``step_size``-th voxel along each axis.

    ``mask``: boolean array of the volume's shape. As in scikit-image, the cube at index
    ``(i, j, k)`` (corners ``(i, j, k)`` to ``(i + s, j + s, k + s)``, ``s = step_size``) is
    meshed only when ``mask[i + s, j + s, k + s]`` is true.

    ``allow_degenerate=False`` removes zero-area triangles; the simplicial surface has
    none (its vertices are kept apart), so both settings give the same mesh.

    ``method``: ``"lewiner"`` or ``"lorensen"``; both give this library's surface, which
    is simplicial (C. Min, "Simplicial Isosurfacing in Arbitrary Dimension and
    Codimension", 2003: every cube split into six tetrahedra, so no ambiguous cases and no
    holes), not either marching-cubes table: its vertices on the cubes' edges are
    scikit-image's, and it has about three times as many triangles.

    ``closed``: ``False`` (scikit-image's behaviour) leaves the surface open where the
    object reaches the array's border; ``True`` closes it with the array's faces (the
    outside continued beyond the array), so the mesh is watertight and encloses a volume.

    ``inside`` (this library's): ``"below"`` (values below ``level`` are inside, a signed
    distance) or ``"above"`` (a bright object) orients normals and faces consistently out
    of the inside region (faces counter-clockwise seen from outside); ``gradient_direction``
    must then keep its default. ``None`` (the default): scikit-image's orientation above.

    Raises ``ValueError`` for NaN, a level outside the data range, a bad keyword value or
    a mask of the wrong shape.
    """
    a = _float32(volume, "volume", allow_int=True)
    s = _spacing(spacing, 3)
    if method not in ("lewiner", "lorensen"):
        raise ValueError(f"method should be either 'lewiner' or 'lorensen', got {method!r}")
    if gradient_direction not in ("descent", "ascent"):
        raise ValueError(
            f"gradient_direction must be 'descent' or 'ascent', got {gradient_direction!r}"
        )
    if inside is None:
        side, reverse = "above", gradient_direction == "descent"
    elif inside in ("below", "above"):
        if gradient_direction != "descent":
            raise ValueError(
                "inside= orients the mesh out of the inside region; gradient_direction "
                "(scikit-image's orientation) applies only with inside=None"
            )
        side, reverse = inside, False
    else:
        raise ValueError(f'inside must be "below", "above" or None, got {inside!r}')
    step = int(step_size)
    if step < 1:
        raise ValueError(f"step_size must be at least one, got {step_size}")
    m = None
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape != a.shape:
            raise ValueError(f"volume and mask must have the same shape, got {a.shape} and {m.shape}")
        fortran = a.flags.f_contiguous and not a.flags.c_contiguous
        m = np.asfortranarray(m) if fortran else np.ascontiguousarray(m)
    lv = None if level is None else float(level)
    verts, faces, normals, values = _native.isosurface(
        a, lv, s, side, reverse, step, m, bool(closed), bool(allow_degenerate), progress
    )
    return verts, faces, normals, values


def save_mesh(path: Union[str, os.PathLike], verts, faces, normals=None) -> None:
    """Writes a triangle mesh to ``.ply`` (binary), ``.obj`` or ``.stl`` (binary),
    atomically. Normals are computed (area-weighted) when not given."""
    v = np.ascontiguousarray(verts, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    n = None if normals is None else np.ascontiguousarray(normals, dtype=np.float64)
    _native.save_mesh(os.fspath(path), v, f, n)


def load_mesh(path: Union[str, os.PathLike]):
    """Reads a triangle mesh (``.obj``, ``.ply``, ``.stl``): ``(verts, faces)``."""
    return _native.load_mesh(os.fspath(path))


def _flow_fields(speed, velocity, dims: int) -> dict:
    """The native keywords of a speed (a constant or a `dims`-D array) and a velocity (a
    constant of `dims` components or an array of them, one more axis)."""
    kw = {}
    if np.ndim(speed) == 0:
        kw["speed"] = float(speed)
    else:
        kw["speed_field"] = np.ascontiguousarray(_float32(speed, "speed", ndims=(dims,)))
    if velocity is not None:
        v = np.asarray(velocity)
        if v.ndim == 1:
            if v.shape != (dims,):
                names = ", ".join(("ux", "uy", "uz")[:dims])
                raise ValueError(f"velocity must be ({names}), got shape {v.shape}")
            kw["velocity"] = tuple(float(c) for c in v)
        else:
            kw["velocity_field"] = np.ascontiguousarray(
                _float32(v, "velocity", ndims=(dims + 1,))
            )
    return kw


class LevelSet:
    """A narrow-band signed distance field (φ < 0 inside, world units) on the Sorted Tile
    List: band voxels ``|φ| < γ`` are stored, every other voxel reads ``±γ`` (``γ =
    half_width * voxel_size``, :attr:`background`).

    Build one with :meth:`from_dense`, :meth:`from_mesh`, :meth:`sphere` /
    :meth:`shape`, or :meth:`load`. ``a | b``, ``a & b`` and ``a - b`` are union,
    intersection and difference (same voxel size, origin and half-width).
    """

    __slots__ = ("_ls",)

    def __init__(self, native):
        if not isinstance(native, _native.LevelSet):
            raise TypeError("use LevelSet.from_dense, from_mesh, shape, sphere or load")
        self._ls = native

    @classmethod
    def from_dense(
        cls,
        phi,
        voxel_size: float = 1.0,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        half_width: float = 3.0,
    ) -> "LevelSet":
        """From a dense signed distance field ``phi[z, y, x]`` (world units), element
        ``[0, 0, 0]`` at world ``origin`` (x, y, z). The field must be a distance near its
        zero contour (no sign change between neighbours both beyond ``γ``); use
        :func:`distance` first otherwise. ±inf counts as far away, NaN is an error."""
        a = np.ascontiguousarray(_float32(phi, "phi"))
        o = tuple(float(v) for v in origin)
        return cls(_native.LevelSet.from_dense(a, float(voxel_size), o, float(half_width)))

    @classmethod
    def from_mesh(
        cls,
        verts,
        faces,
        voxel_size: Optional[float] = None,
        half_width: float = 3.0,
        *,
        progress: Progress = None,
    ) -> "LevelSet":
        """Voxelises a closed triangle mesh (vertices ``(n, 3)`` world x, y, z; faces
        ``(m, 3)``): exact distances to the triangles in the band, the sign by ray parity
        (robust to small defects). ``voxel_size`` defaults to one chosen from the mesh."""
        v = np.ascontiguousarray(verts, dtype=np.float64)
        f = np.ascontiguousarray(faces, dtype=np.int64)
        vs = None if voxel_size is None else float(voxel_size)
        return cls(_native.LevelSet.from_mesh(v, f, vs, float(half_width), progress))

    @classmethod
    def shape(
        cls,
        kind: str,
        center: Sequence[float] = (0.0, 0.0, 0.0),
        voxel_size: float = 1.0,
        half_width: float = 3.0,
        *,
        radius: Optional[float] = None,
        minor_radius: Optional[float] = None,
        half_extents: Optional[Sequence[float]] = None,
        radii: Optional[Sequence[float]] = None,
    ) -> "LevelSet":
        """The exact signed distance band of an analytic shape: ``"sphere"`` (``radius``),
        ``"torus"`` around z (``radius`` of the centre circle, ``minor_radius``), ``"box"``
        (``half_extents``) or ``"ellipsoid"`` (``radii``)."""
        sizes = half_extents if half_extents is not None else radii
        sizes = None if sizes is None else tuple(float(v) for v in sizes)
        c = tuple(float(v) for v in center)
        return cls(
            _native.LevelSet.shape(
                kind, c, float(voxel_size), float(half_width), radius, minor_radius, sizes
            )
        )

    @classmethod
    def sphere(
        cls,
        radius: float,
        center: Sequence[float] = (0.0, 0.0, 0.0),
        voxel_size: float = 1.0,
        half_width: float = 3.0,
    ) -> "LevelSet":
        """A sphere's exact signed distance band (OpenVDB's ``createLevelSetSphere``)."""
        return cls.shape("sphere", center, voxel_size, half_width, radius=radius)

    @classmethod
    def load(
        cls,
        path: Union[str, os.PathLike],
        voxel_size: float = 1.0,
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        half_width: float = 3.0,
    ) -> "LevelSet":
        """Reads ``.sls`` (this library's format), ``.vdb`` (OpenVDB: the first float grid
        of class level set) or a dense ``.npy`` field ``[z, y, x]`` (placed by
        ``voxel_size``, ``origin`` and ``half_width``; the other formats carry their own).
        Every file is checked before use; a bad one raises ``OSError`` naming what is
        wrong."""
        o = tuple(float(v) for v in origin)
        return cls(_native.LevelSet.load(os.fspath(path), float(voxel_size), o, float(half_width)))

    def save(
        self, path: Union[str, os.PathLike], *, margin: int = 2, compression: str = "none"
    ) -> None:
        """Writes ``.sls``, ``.vdb`` (a float grid of class level set, background γ,
        inactive values left out; ``compression="zip"`` deflates the rest, a few percent
        smaller) or ``.npy`` (the band's box grown by ``margin`` voxels, ``[z, y, x]``). Writes are atomic: a failed write leaves an
        existing file as it was."""
        self._ls.save(os.fspath(path), int(margin), compression)

    def to_dense(self, bbox=None) -> np.ndarray:
        """φ on an inclusive voxel box ``((x0, y0, z0), (x1, y1, z1))`` (default: the band's
        :attr:`bbox`) as a float32 array ``[z, y, x]``; voxels outside the band read ±γ."""
        lo, hi = self.bbox if bbox is None else bbox
        return self._ls.to_dense(tuple(int(v) for v in lo), tuple(int(v) for v in hi))

    def value(self, points) -> np.ndarray:
        """φ at world points ``(n, 3)`` (or one point ``(3,)``), trilinear between voxel
        centres; float32 ``(n,)`` (a scalar for one point)."""
        p = np.asarray(points, dtype=np.float64)
        one = p.ndim == 1
        out = self._ls.value(np.ascontiguousarray(p.reshape(-1, 3) if one else p))
        return out[0] if one else out

    def filter(self, *ops: str) -> "LevelSet":
        """The level set filtered as OpenVDB's ``LevelSetFilter`` and ``vdb_tool`` do, the
        operations in the order given, each ``"NAME[:VALUE]"``: ``"offset:D"`` (outwards by D
        world units, inwards when negative), ``"dilate:D"``, ``"erode:D"``, ``"open:R"``,
        ``"close:R"``, ``"mean-curvature:T"`` (a sphere's r² shrinks by 2T), ``"gaussian:W"``,
        ``"mean:W"``, ``"median:W"`` (the (2W + 1)³ neighbourhood), ``"renormalize"``. The
        result is a signed distance on the same grid; ``ValueError`` for a bad operation or
        a level set the filters empty."""
        return LevelSet(self._ls.filter([str(o) for o in ops]))

    def measure(self, delta_width: float = 1.5) -> dict:
        """``{"band_voxels", "volume", "area"}`` in world units: the volume from the
        voxels' inside fractions, the area with the smoothed delta of width
        ``delta_width`` voxels."""
        return self._ls.measure(float(delta_width))

    @property
    def volume(self) -> float:
        return self.measure()["volume"]

    @property
    def area(self) -> float:
        return self.measure()["area"]

    def union(self, other: "LevelSet") -> "LevelSet":
        return LevelSet(self._ls.union(other._ls))

    def intersection(self, other: "LevelSet") -> "LevelSet":
        return LevelSet(self._ls.intersection(other._ls))

    def difference(self, other: "LevelSet") -> "LevelSet":
        return LevelSet(self._ls.difference(other._ls))

    __or__ = union
    __and__ = intersection
    __sub__ = difference

    def mesh(self, level: float = 0.0, coarsen: int = 1, *, progress: Progress = None):
        """The surface φ = ``level``: ``(verts (n, 3) float64 world x, y, z, faces (m, 3)
        int32, normals (n, 3) float32)``, closed and welded. ``coarsen=k`` meshes every
        k-th voxel (about k² fewer triangles)."""
        v, f, n = self._ls.mesh(float(level), int(coarsen), progress)
        return v, f.astype(np.int32), n

    def render(
        self,
        width: int = 640,
        height: int = 480,
        *,
        azimuth: float = -60.0,
        elevation: float = 30.0,
        fov: float = 35.0,
        samples: int = 2,
        ground: bool = True,
        shadows: bool = True,
        progress: Progress = None,
    ) -> np.ndarray:
        """A ray-traced picture of the surface, ``(height, width, 3)`` uint8 RGB."""
        return self._ls.render(
            int(width), int(height), float(azimuth), float(elevation), float(fov),
            int(samples), bool(ground), bool(shadows), progress,
        )

    def reinitialize(
        self, order: int = 2, half_width: Optional[float] = None, *, progress: Progress = None
    ) -> "LevelSet":
        """A signed distance band again, by fast marching from the interface (a new
        half-width if given)."""
        hw = None if half_width is None else float(half_width)
        return LevelSet(self._ls.reinitialize(int(order), hw, progress))

    def band(self):
        """The band voxels: ``(coords (n, 3) int32 x, y, z, values (n,) float32)``."""
        return self._ls.band()

    voxel_size = property(lambda self: self._ls.voxel_size, doc="World units per voxel.")
    origin = property(lambda self: tuple(self._ls.origin), doc="World position of voxel (0, 0, 0).")
    half_width = property(lambda self: self._ls.half_width, doc="Band half-width in voxels.")
    background = property(lambda self: self._ls.background, doc="γ: φ of voxels outside the band (−γ inside).")
    band_voxels = property(lambda self: self._ls.band_voxels, doc="Voxels with |φ| < γ.")
    memory = property(lambda self: self._ls.memory, doc="Bytes the tiles use.")
    checksum = property(lambda self: self._ls.checksum, doc="FNV-1a of the band (coordinates and value bits).")

    @property
    def bbox(self):
        """The band's inclusive voxel box ``((x0, y0, z0), (x1, y1, z1))``."""
        lo, hi = self._ls.bbox
        return tuple(lo), tuple(hi)

    def __repr__(self) -> str:
        return repr(self._ls)


class Simulation:
    """A level set moved by ``φ_t + u·∇φ + F|∇φ| = ε κ |∇φ|`` (F > 0 moves the surface
    outward; κ = ½∇·n is the mean curvature, 1/r on a sphere) on the tile engine.

    Parameters
    ----------
    levelset : the initial :class:`LevelSet` (copied).
    speed : F, a constant, or an array ``[z, y, x]`` on the level set's voxels starting at
        voxel ``field_origin`` (trilinear in between, nearest face value beyond).
    curvature : ε ≥ 0.
    velocity : u, a constant ``(ux, uy, uz)`` or an array ``[z, y, x, 3]`` like ``speed``.
    volume_conserving : add F = ε κ̄ so that curvature flow keeps the enclosed volume.
    scheme : ``"weno5"`` (HJ-WENO5) or ``"upwind1"``; integrator ``"rk3"`` (TVD-RK3) or
        ``"euler"``; ``cfl`` in (0, 1] or a fixed ``dt``.
    renormalization : ``"sweeps"`` (HJ-WENO5 pseudo-time sweeps after every step),
        ``"coupled"`` (the rescaling term in the PDE) or ``"off"``.
    grid : ``"tiles"`` (SIMD), ``"tiles-scalar"`` or ``"dtgrid"`` (the reference).
    threads : a pool of its own with this many threads (default: all cores).

    Every result is bitwise identical for any thread count.
    """

    __slots__ = ("_sim",)

    def __init__(
        self,
        levelset: LevelSet,
        *,
        speed=0.0,
        curvature: float = 0.0,
        velocity=None,
        field_origin: Sequence[int] = (0, 0, 0),
        volume_conserving: bool = False,
        scheme: str = "weno5",
        integrator: str = "rk3",
        cfl: float = 1.0,
        dt: Optional[float] = None,
        renormalization: str = "sweeps",
        renormalization_sweeps: int = 1,
        grid: str = "tiles",
        threads: Optional[int] = None,
    ):
        if not isinstance(levelset, LevelSet):
            raise TypeError("levelset must be a LevelSet")
        kw = _flow_fields(speed, velocity, 3)
        self._sim = _native.Simulation(
            levelset._ls,
            curvature=float(curvature),
            field_origin=tuple(int(c) for c in field_origin),
            volume_conserving=bool(volume_conserving),
            scheme=scheme,
            integrator=integrator,
            cfl=float(cfl),
            dt=None if dt is None else float(dt),
            renormalization=renormalization,
            renormalization_sweeps=int(renormalization_sweeps),
            grid=grid,
            threads=threads,
            **kw,
        )

    def step(self) -> dict:
        """One step; its report ``{"step", "time", "dt", "kappa_bar", "collapsed"}``. A step
        that fails leaves the simulation as it was."""
        return self._sim.step()

    def run_until(
        self,
        t: float,
        callback: Optional[Callable[["Simulation", dict], object]] = None,
        max_steps: Optional[int] = None,
    ) -> int:
        """Steps until time ``t`` (the last step lands on it exactly), a collapse, or
        ``max_steps`` steps; ``callback(sim, report)`` after every step (return ``False``
        to stop). Ctrl-C stops between steps. Returns the number of steps taken."""
        cb = None if callback is None else (lambda _native_sim, report: callback(self, report))
        n = (1 << 64) - 1 if max_steps is None else int(max_steps)
        return self._sim.run_until(float(t), cb, n)

    @property
    def levelset(self) -> LevelSet:
        """The current state as a :class:`LevelSet` (a copy)."""
        return LevelSet(self._sim.levelset)

    time = property(lambda self: self._sim.time, doc="Simulated time.")
    steps = property(lambda self: self._sim.steps, doc="Steps taken.")
    collapsed = property(lambda self: self._sim.collapsed, doc="No interface is left.")

    def measure(self) -> dict:
        """``{"band_voxels", "stored", "volume", "area", "bytes", "work_bytes"}``."""
        return self._sim.measure()

    def __repr__(self) -> str:
        return repr(self._sim)


Image = _native.Image
Image.__doc__ = """A 3-D image: voxels ``[i, j, k]`` along x, y, z, ``spacing`` and the ``affine``
(index → world, as nibabel). ``Image(array, spacing)`` from an array; :func:`load_image`
from a file."""


def evolve2d(
    phi,
    t: float,
    *,
    dx: float = 1.0,
    speed=0.0,
    curvature: float = 0.0,
    velocity=None,
    scheme: str = "weno5",
    integrator: str = "rk3",
    cfl: float = 1.0,
    threads: Optional[int] = None,
    max_steps: Optional[int] = None,
    full_output: bool = False,
    progress: Progress = None,
):
    """Moves the zero contour of the 2-D array ``phi`` by
    ``φ_t + u·∇φ + F|∇φ| = ε κ |∇φ|`` until time ``t`` and returns the new ``φ``.

    ``κ`` is the curvature of the contour (1/r on a circle): under ``curvature=ε`` alone a
    circle of radius r₀ has r² = r₀² − 2εt. F > 0 moves the contour outward (towards
    positive ``phi``). The band of half-width 3 ``dx`` around the contour is evolved on the
    tile engine's planar lattice (one layer of tiles, no padding along a third axis), kept
    close to a signed distance by the coupled rescaling term; values beyond the band are
    ±3 ``dx``. ``distance(result)`` gives the signed distance over the whole array.

    Only the zero contour of ``phi`` is read: it is located between neighbouring values
    of opposite sign (as ``distance`` locates it) and the run starts from its signed
    distance, so a mask (``np.where(mask, -1, 1)``), a steep or a shallow function start
    the same front.

    Parameters
    ----------
    phi : 2-D array, negative inside, with the contour as its zero level. NaN is a
        ``ValueError``, and so is an array without values of both signs.
    t : the end time (>= 0).
    dx : grid spacing (finite, > 0), the same along both axes.
    speed : F, a constant or an array of ``phi``'s shape.
    curvature : ε >= 0.
    velocity : u, a constant ``(ux, uy)`` or an array ``(ny, nx, 2)``. As everywhere in
        this package, x is the last axis (columns) and y the first (rows).
    scheme : ``"weno5"`` (HJ-WENO5) or ``"upwind1"``; integrator ``"rk3"`` (TVD-RK3) or
        ``"euler"``; ``cfl`` in (0, 1].
    threads : a pool of its own with this many threads (default: all cores). The result
        is bitwise identical for any thread count.
    max_steps : stop after this many steps.
    full_output : also return a dict ``{"steps", "time", "collapsed", "band_voxels"}``
        (``collapsed``: the contour vanished).
    progress : optional callback, called after every step with ``{"done": time, "total":
        t, "step"}``; an exception raised in it stops the call. So does Ctrl-C
        (``KeyboardInterrupt``).

    Beyond the array the level set starts outside (+3 ``dx``), as everywhere in this
    package: an inside region that touches the array's border is closed there. The contour
    may then move beyond the array (the fields are extended by their edge values and the
    band is unbounded), but only the array's part is returned.
    """
    a = np.ascontiguousarray(_float32(phi, "phi", ndims=(2,)))
    kw = _flow_fields(speed, velocity, 2)
    if max_steps is not None:
        if int(max_steps) < 0:
            raise ValueError(f"max_steps must be >= 0, got {max_steps}")
        kw["max_steps"] = int(max_steps)
    out, report = _native.evolve2d(
        a,
        float(t),
        dx=float(dx),
        curvature=float(curvature),
        scheme=scheme,
        integrator=integrator,
        cfl=float(cfl),
        threads=threads,
        progress=progress,
        **kw,
    )
    return (out, report) if full_output else out


def _image(image, spacing) -> "_native.Image":
    if isinstance(image, _native.Image):
        if spacing is not None:
            raise ValueError("spacing comes with the Image; give it to load_image instead")
        return image
    a = _float32(image, "image", ndims=(2, 3), allow_int=True)
    if a.ndim == 2:
        a = a[:, :, None]
    if spacing is None:
        spacing = 1.0
    if np.ndim(spacing) == 1 and len(spacing) == 2:
        spacing = tuple(spacing) + (1.0,)
    s = _spacing(spacing, 3)
    return _native.Image(np.asfortranarray(a), s)


def load_image(path: Union[str, os.PathLike], spacing: Optional[Sequence[float]] = None) -> Image:
    """Reads a NIfTI (``.nii``, ``.nii.gz``: voxels, spacing and placement from its header),
    MetaImage (``.mha``, ``.mhd``) or NRRD (``.nrrd``, ``.nhdr``) image (each in its own world
    frame: NIfTI's RAS, ITK's LPS), ``.npy`` (2-D or 3-D, any numeric dtype) or grey PNG
    image. ``spacing`` overrides the
    file's. The image is indexed ``[i, j, k]`` along the file's x, y, z (for ``.npy`` files
    that is ``np.load(path).T``)."""
    s = None if spacing is None else _spacing(spacing, 3)
    return _native.load_image(os.fspath(path), s)


class Segmentation:
    """What :func:`segment` returns: ``mask`` (uint8, 1 inside, the image's shape),
    ``levelset`` (the final level set on the image lattice), ``report`` (the parameters
    used with the defaults filled in, why it stopped, iterations, timings), ``mesh()``
    (the surface in world coordinates) and ``save_mask(path)``."""

    __slots__ = ("_seg", "_shape")

    def __init__(self, native, shape):
        self._seg = native
        self._shape = shape

    @property
    def mask(self) -> np.ndarray:
        m = self._seg.mask
        return m.reshape(self._shape) if m.shape != self._shape else m

    @property
    def levelset(self) -> LevelSet:
        return LevelSet(self._seg.levelset)

    @property
    def report(self) -> dict:
        return json.loads(self._seg.report_json)

    @property
    def vanished(self) -> bool:
        """Whether nothing is left inside (``report["stop"] == "vanished"``: the mask is
        empty): it then segments no object (see :class:`VanishedWarning`)."""
        return bool(self._seg.vanished)

    @property
    def leaked(self) -> bool:
        """Whether the leak guard stopped the run (``report["stop"] == "leaked"``, the
        reason in ``report["leak"]``): the mask is then not the seeded object."""
        return bool(self._seg.leaked)

    def mesh(self):
        """The surface: ``(verts (n, 3) float64 world, faces (m, 3) int32, normals)``. World
        is the image's placement (a NIfTI file's affine), or index × spacing in array-axis
        order for an array."""
        v, f, n = self._seg.mesh()
        return v, f.astype(np.int32), n

    def save_mask(self, path: Union[str, os.PathLike]) -> None:
        """Writes the mask like the image: NIfTI with the input's header, ``.npy`` or PNG."""
        self._seg.save_mask(os.fspath(path))


def segment(
    image,
    method: str = "gac",
    seeds: Optional[Sequence[Sequence[float]]] = None,
    *,
    spacing: Optional[Sequence[float]] = None,
    world: bool = False,
    init_mask=None,
    init_levelset=None,
    lower_threshold: Optional[float] = None,
    upper_threshold: Optional[float] = None,
    sigma: Optional[float] = None,
    propagation_scaling: Optional[float] = None,
    curvature_scaling: Optional[float] = None,
    advection_scaling: Optional[float] = None,
    edge_scale: Optional[float] = None,
    sigmoid: Optional[Tuple[float, float]] = None,
    lambda1: float = 1.0,
    lambda2: float = 1.0,
    nu: float = 0.0,
    maximum_rms_error: float = 0.01,
    volume_change: float = 2e-4,
    window: int = 10,
    number_of_iterations: int = 2000,
    terms: Optional[dict] = None,
    threads: Optional[int] = None,
    progress: Progress = None,
    feature_image=None,
    leak_guard: bool = True,
    first_edge: bool = True,
    fast_start: bool = True,
) -> Segmentation:
    """Segments a 3-D (or 2-D) image with a level set grown from seeds, with SimpleITK's
    parameter names.

    ``method``: ``"threshold"`` (ThresholdSegmentationLevelSet: grow where the smoothed
    intensity lies in [``lower_threshold``, ``upper_threshold``]), ``"gac"``
    (GeodesicActiveContourLevelSet on a sigmoid edge potential chosen from the image, or
    ``edge_scale`` K / ``sigmoid`` (α, β)), or ``"chan-vese"`` (region means, ``lambda1``,
    ``lambda2``, ``nu``). ``terms={"chan-vese": 0.5}`` adds methods with weights.

    ``image``: an :class:`Image`, or an array (2-D or 3-D) with ``spacing`` per array axis.
    ``seeds``: ``(i, j, k)`` or ``(i, j, k, radius)`` array indices (radius in voxels of the
    smallest spacing, default 3), or world coordinates with ``world=True``; or start from
    ``init_mask`` / ``init_levelset`` of the image's shape (φ < 0 inside; only its zero
    level is read, so its units and steepness do not matter).

    A threshold window may be open at one end: leave ``upper_threshold`` (or
    ``lower_threshold``) out, or give ``±inf``. ``propagation_scaling`` may be negative
    (threshold and GAC) to shrink onto an object from a larger ``init_mask``.
    ``feature_image`` (the image's shape), as SimpleITK's filters take one: for GAC the
    edge potential itself (1 in flat regions, near 0 on edges), for threshold and Chan–Vese
    the intensities compared in place of the image.

    A run whose region spreads over an image face the seeds did not touch (0.5 % of it),
    or grows past half the image (a start shrinking onto the objects, a negative
    ``propagation_scaling`` from ``init_mask``: past itself), is stopped (``leak_guard=False`` turns that off): the result's ``leaked`` is
    True and a :class:`LeakWarning` is issued, so that an interactive user sees it and a
    pipeline can make it an error (``warnings.simplefilter("error", LeakWarning)``). A
    Chan–Vese region whose mean ends within four noise levels of the outside's issues a
    :class:`ContrastWarning` the same way, and a run that ends with nothing inside (an
    empty mask, ``vanished`` True) a :class:`VanishedWarning`.

    The first edge that rays from the seeds cross shapes GAC and Chan–Vese: GAC's balloon
    turns inward beyond the intensity midway across it (``report["params"]["edge_level"]``),
    so that a weak stretch of edge does not let the front run on, and Chan–Vese's outside
    mean is no farther from the inside's than the intensity beyond it (the neighbouring
    tissue, not the whole outside). GAC shrinking a start (``propagation_scaling < 0``)
    likewise turns outward beyond the first edge that rays from the start's boundary cross
    inward, so that it does not eat an object the start cuts. ``first_edge=False`` gives
    SimpleITK's plain balloon and the textbook Chan–Vese.

    From seeds, the level set starts from the part of the image the front is sure to
    cover (a flood fill through the voxels where the method's speed is clearly outward,
    by openings curvature cannot close; ``report["params"]["start_voxels"]``): the same
    answer in fewer steps. GAC shrinking an ``init_mask`` (``propagation_scaling`` < 0)
    starts without the part of the mask the front from outside is sure to sweep (away from
    the edges, g ≥ ½). ``fast_start=False`` starts from the seeds' balls or the mask.

    ``sigma`` (Gaussian smoothing, world units), ``propagation_scaling`` β,
    ``curvature_scaling`` ε, ``advection_scaling`` α default to values chosen from the image
    (see ``report["params"]``). Stops when the RMS change of φ per unit time near the
    interface is below ``maximum_rms_error``, when the volume changed by less than
    ``volume_change`` over ``window`` steps, or after ``number_of_iterations``.
    """
    im = _image(image, spacing)
    shape = tuple(np.shape(image)) if not isinstance(image, _native.Image) else tuple(im.shape)
    if len(shape) == 2:
        shape = shape + (1,)
    if seeds is None and init_mask is None and init_levelset is None:
        raise ValueError("give seeds, init_mask or init_levelset")
    mask = None
    if init_mask is not None:
        m = np.asarray(init_mask)
        mask = np.asfortranarray((m.reshape(shape) if m.ndim == 2 else m) != 0, dtype=np.uint8)
    lvl = None
    if init_levelset is not None:
        lv = _float32(init_levelset, "init_levelset", ndims=(2, 3))
        lvl = np.asfortranarray(lv.reshape(shape) if lv.ndim == 2 else lv)
    feat = None
    if feature_image is not None:
        fa = _float32(feature_image, "feature_image", ndims=(2, 3))
        if fa.shape != shape[: fa.ndim]:
            raise ValueError("feature_image has shape %s, the image %s" % (fa.shape, shape))
        feat = np.asfortranarray(fa.reshape(shape) if fa.ndim == 2 else fa)
    seed_list = [] if seeds is None else [[float(c) for c in s] for s in seeds]
    term_list = [] if not terms else [(str(k), float(w)) for k, w in terms.items()]
    native = _native.segment(
        im, method, seed_list, bool(world), mask, lvl, lower_threshold, upper_threshold,
        sigma, propagation_scaling, curvature_scaling, advection_scaling, edge_scale,
        None if sigmoid is None else (float(sigmoid[0]), float(sigmoid[1])),
        float(lambda1), float(lambda2), float(nu), float(maximum_rms_error),
        float(volume_change), int(window), int(number_of_iterations), term_list, threads,
        progress, feat, bool(leak_guard), bool(first_edge), bool(fast_start),
    )
    out_shape = tuple(np.shape(image)) if not isinstance(image, _native.Image) else tuple(im.shape)
    result = Segmentation(native, out_shape)
    if result.leaked:
        warnings.warn(
            "the segmentation leaked and was stopped: %s" % result.report.get("leak"),
            LeakWarning,
            stacklevel=2,
        )
    if result.vanished:
        warnings.warn(
            "the segmentation vanished: nothing is left inside and the mask is empty (the "
            "method found no object where the front started; check the seeds or the initial "
            "mask, the window, and the sign of propagation_scaling)",
            VanishedWarning,
            stacklevel=2,
        )
    if result.report.get("weak_contrast"):
        warnings.warn(result.report["weak_contrast"], ContrastWarning, stacklevel=2)
    return result


class ContrastWarning(UserWarning):
    """A Chan–Vese region was not told apart from its surroundings: its mean lies within four
    noise levels of the outside's (``report["weak_contrast"]`` says by how much), so the mask
    segments nothing in particular, though the run stopped normally."""


class VanishedWarning(UserWarning):
    """A segmentation ended with nothing inside: the mask is empty (``report["stop"]`` is
    ``"vanished"``), so it segments no object. A start holding no object the method finds
    ends so, as does a front shrinking through edges too weak to stop it."""


class LeakWarning(UserWarning):
    """A segmentation's region spread over an image face its seeds did not touch, or grew past
    half the image (a shrinking start: past itself): the leak guard stopped it (see
    :func:`segment`)."""
