"""The compiled kernels (``src/agrinav_gym/render/csrc``) through ctypes: the sensors', the tyre
model's (``sim/tyres.py``), the filters' (``estimation/ekf.py``, ``robot_localization.py``) and
the route's (``routes.py``, ``metrics.py``: the trackers, the route observation, the metrics'
nearest segment) and the GNSS sky model's foliage loss (``sensors/fixmode.py``).

The kernels are plain C functions in the optional extension ``agrinav_gym.render._native`` (built by
``pip install``/``make`` where a C compiler exists). ctypes releases the GIL during each call,
so two threads can render two views at once. Where the extension is missing, or the
environment sets ``AGRINAV_NATIVE=0``, ``lib()`` returns None and the sensors use their numpy
and Embree paths, which give the same images more slowly (tests compare the two).
``AGRINAV_NATIVE_LIB=/path/to/_native.so`` loads that build instead of the installed one (``make
sanitize`` points it at a build under AddressSanitizer and UBSan); a path that does not load is
an error, not a fallback.

The boundary is declared here once, as in ``csrc/native.h``: every kernel takes one argument,
a pointer to its own struct (an ``Args`` subclass naming the kernel), and returns an int
status. A call site fills the struct's fields by name, every one of them, and each value is
checked on the way in: an array must be C-contiguous and of the field's dtype (or None for
NULL), a block (``Camera``, ``Geometry``, ...) of the field's type, an int within its C type.
``call`` raises ``KernelError`` naming the kernel and its status where the kernel refuses
(out of memory, a size out of bounds, a missing array, ...). A build whose structs are laid
out otherwise than declared here is refused when loaded (``layout_mismatches``), as is one
built from other sources (``stale``).
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

_LIB: Any = None
_FUNCS: dict[str, Any] = {}
_TRIED = False
_REFUSED: str | None = None  # why a build was refused
_ORIGIN: str | None = None  # the file the loaded build came from


class NativeUnavailable(RuntimeError):
    """The compiled kernels were asked for but are not built (or disabled)."""


class KernelError(RuntimeError):
    """A kernel refused its arguments or failed (its status is not 0)."""

    def __init__(self, kernel: str, status: int, meaning: str) -> None:
        super().__init__(f"kernel {kernel} failed with status {status}: {meaning}")
        self.kernel, self.status = kernel, status


# ------------------------------------------------------------------ field types
class _Array(ctypes.c_void_p):
    """A pointer field: a C-contiguous numpy array of ``dtype``, or None (NULL)."""

    dtype: ClassVar[np.dtype[Any]]


class _Block(ctypes.c_void_p):
    """A pointer field: a ``Struct`` of type ``struct`` (kept alive by the holder), or None."""

    struct: ClassVar[type[Struct]]


class Address(ctypes.c_void_p):
    """A pointer field given as an address (memory numpy does not own: Embree's), or None."""


_ARRAYS: dict[Any, type[_Array]] = {}


def array(dtype: Any) -> type[_Array]:
    """The field type of a pointer to a C-contiguous array of ``dtype``."""
    dt = np.dtype(dtype)
    if dt not in _ARRAYS:
        _ARRAYS[dt] = type(f"{dt.name}_array", (_Array,), {"dtype": dt})
    return _ARRAYS[dt]


def block(struct: type[Struct]) -> type[_Block]:
    """The field type of a pointer to a ``struct`` block."""
    return type(f"{struct.__name__}_ptr", (_Block,), {"struct": struct})


F64, F32, I64, I32, U8 = (array(t) for t in (np.float64, np.float32, np.int64, np.int32, np.uint8))
i32, i64, u64, f64 = ctypes.c_int32, ctypes.c_int64, ctypes.c_uint64, ctypes.c_double


def vec(n: int) -> Any:
    """The field type of a fixed array of ``n`` doubles held in the struct."""
    return ctypes.c_double * n


#: Every struct at the boundary, and every kernel: its C name and its one argument (a pointer to
#: that struct); each kernel returns an int status, 0 when done (``agrinav_status`` says what
#: the others mean).
STRUCTS: list[type[Struct]] = []
KERNELS: dict[str, type[Args]] = {}


_SCALAR, _I32, _ARRAY, _BLOCK, _VEC = range(5)


def _kind(t: Any) -> tuple[int, Any]:
    """How a field of C type ``t`` takes its value (``Struct._convert``)."""
    if isinstance(t, type) and issubclass(t, _Array):
        return _ARRAY, t.dtype
    if isinstance(t, type) and issubclass(t, _Block):
        return _BLOCK, t.struct
    if isinstance(t, type) and issubclass(t, ctypes.Array):
        return _VEC, t
    return (_I32 if t is i32 else _SCALAR), None


class Struct(ctypes.Structure):
    """A struct of csrc/native.h (``c`` names it there), filled by name — every field given to
    the constructor, any of them later through ``set`` — each value checked against its
    field's type (assigning attributes directly skips the checks). Arrays and blocks a struct
    points to are kept alive by it."""

    c: ClassVar[str]
    _kinds: ClassVar[dict[str, tuple[int, Any]]]

    def __init_subclass__(cls, c: str = "", **kw: Any) -> None:
        super().__init_subclass__(**kw)
        cls.c = c
        cls._kinds = {name: _kind(t) for name, t in cls.__dict__.get("_fields_", ())}
        if cls._kinds:
            STRUCTS.append(cls)

    def __init__(self, **fields: Any) -> None:
        if len(fields) != len(self._kinds) or fields.keys() != self._kinds.keys():
            missing = self._kinds.keys() - fields.keys()
            if missing:
                raise TypeError(f"{type(self).__name__}: no value for {', '.join(sorted(missing))}")
        super().__init__(**self._convert(fields))

    def set(self, **fields: Any) -> None:
        """Change some fields (checked as the constructor checks them)."""
        for name, value in self._convert(fields).items():
            setattr(self, name, value)

    def _convert(self, fields: dict[str, Any]) -> dict[str, Any]:
        kinds, out = self._kinds, {}
        for name, value in fields.items():
            kind = kinds.get(name)
            if kind is None:
                raise AttributeError(f"{type(self).__name__} has no field {name!r}")
            code, arg = kind
            if value is None or code == _SCALAR:
                pass
            elif code == _ARRAY:
                if not isinstance(value, np.ndarray) or value.dtype != arg:
                    got = value.dtype if isinstance(value, np.ndarray) else type(value).__name__
                    raise TypeError(f"{type(self).__name__}.{name}: an array of {arg}, not {got}")
                if not value.flags.c_contiguous:
                    raise ValueError(f"{type(self).__name__}.{name}: not C-contiguous")
                self._keep(name, value)
                value = value.ctypes.data
            elif code == _BLOCK:
                if not isinstance(value, arg):
                    got = type(value).__name__
                    raise TypeError(f"{type(self).__name__}.{name}: a {arg.__name__}, not {got}")
                self._keep(name, value)
                value = ctypes.addressof(value)
            elif code == _VEC:
                if len(value) != arg._length_:
                    raise ValueError(f"{type(self).__name__}.{name}: {arg._length_} values")
                value = arg(*value)
            elif not -(2**31) <= value < 2**31:
                raise OverflowError(
                    f"{type(self).__name__}.{name}: {value} is out of int32's range"
                )
            out[name] = value
        return out

    def _keep(self, name: str, value: Any) -> None:
        self.__dict__.setdefault("_refs", {})[name] = value


class Args(Struct):
    """The one argument of kernel ``kernel`` (C: ``<kernel>_args_t``); it returns a status."""

    kernel: ClassVar[str]

    def __init_subclass__(cls, kernel: str = "", **kw: Any) -> None:
        super().__init_subclass__(c=f"{kernel}_args_t", **kw)
        cls.kernel = kernel
        if kernel:
            KERNELS[kernel] = cls


# ------------------------------------------------------------------ shared blocks
class Camera(Struct, c="camera_t"):
    """A pinhole camera (raster_view.camera_params)."""

    _fields_ = [
        ("origin", vec(3)),
        ("rot", vec(9)),
        ("fx", f64),
        ("fy", f64),
        ("cx", f64),
        ("cy", f64),
        ("znear", f64),
        ("zfar", f64),
        ("width", i32),
        ("height", i32),
    ]


class Geometry(Struct, c="geometry_t"):
    """Instance slots, prototypes (tables of addresses) and the terrain's height grid."""

    _fields_ = [
        ("n_slots", i32),
        ("n_protos", i32),
        ("slot_proto", I32),
        ("xfm", F32),
        ("proto_vertices", I64),
        ("proto_faces", I64),
        ("proto_nv", I32),
        ("proto_nf", I32),
        ("proto_sphere", F32),
        ("proto_adj", I64),
        ("proto_clusters", I64),
        ("cluster", i32),
        ("heights", F64),
        ("nx", i32),
        ("ny", i32),
        ("x0", f64),
        ("y0", f64),
        ("spacing", f64),
    ]


def grid_geometry(heights: np.ndarray, x0: float, y0: float, spacing: float) -> Geometry:
    """The geometry block of a height grid alone (float64, C-contiguous; kept alive by it)."""
    ny, nx = heights.shape
    return Geometry(
        n_slots=0, n_protos=0, slot_proto=None, xfm=None, proto_vertices=None,
        proto_faces=None, proto_nv=None, proto_nf=None, proto_sphere=None, proto_adj=None,
        proto_clusters=None, cluster=0, heights=heights, nx=nx, ny=ny, x0=x0, y0=y0,
        spacing=spacing,
    )  # fmt: skip


@dataclass(frozen=True)
class CellGrid:
    """Points by square cell, as the kernels' grid searches read them: cell (i, j) of an
    ``ncx`` × ``ncy`` grid whose first cell is (``cx0``, ``cy0``) in units of ``cell`` lists
    ``items[start[c]:start[c + 1]]``, c = j·ncx + i, each cell's points in index order."""

    cell: float
    cx0: int
    cy0: int
    ncx: int
    ncy: int
    start: NDArray[np.int32]
    items: NDArray[np.int32]

    def fields(self) -> dict[str, Any]:
        """The grid as a kernel struct's fields (``cell`` … ``cell_items``) take it."""
        return {
            "cell": self.cell,
            "cx0": self.cx0,
            "cy0": self.cy0,
            "ncx": self.ncx,
            "ncy": self.ncy,
            "cell_start": self.start,
            "cell_items": self.items,
        }


#: the most cells a grid gets: past it the cell doubles (fewer, larger cells; the candidates a
#: search reads are a superset, its answer the same)
MAX_GRID_CELLS = 1 << 20


def cell_grid(xy: np.ndarray, cell: float) -> CellGrid:
    """The points ``xy`` (n, 2) by cells of side ``cell`` (doubled while the points' box
    would need more than ``MAX_GRID_CELLS``)."""
    pts = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return CellGrid(cell, 0, 0, 1, 1, np.zeros(2, np.int32), np.zeros(0, np.int32))
    while True:
        ij = np.floor(pts / cell).astype(np.int64)
        lo = ij.min(axis=0)
        ncx, ncy = (ij.max(axis=0) - lo + 1).tolist()
        if ncx * ncy <= MAX_GRID_CELLS:
            break
        cell *= 2.0
    ids = (ij[:, 1] - lo[1]) * ncx + (ij[:, 0] - lo[0])
    order = np.argsort(ids, kind="stable")  # by cell, each cell's points in order
    start = np.searchsorted(ids[order], np.arange(ncx * ncy + 1)).astype(np.int32)
    return CellGrid(cell, int(lo[0]), int(lo[1]), ncx, ncy, start, order.astype(np.int32))


class ProxyScene(Struct, c="proxy_scene_t"):
    """The proxy camera's terrain and plant cylinders (proxy_geometry.ProxyGeometry)."""

    _fields_ = [
        ("heights", F64),
        ("nx", i32),
        ("ny", i32),
        ("x0", f64),
        ("y0", f64),
        ("spacing", f64),
        ("block_max", F64),
        ("block", i32),
        ("bnx", i32),
        ("bny", i32),
        ("gnx", i32),
        ("gny", i32),
        ("gx", f64),
        ("gy", f64),
        ("cell", f64),
        ("cell_start", I32),
        ("cell_items", I32),
        ("cylinders", F64),
        ("ztop", f64),
    ]


class Materials(Struct, c="materials_t"):
    """Face colours and normals, textures by address, the tiled soil texture."""

    _fields_ = [
        ("face_offset", I64),
        ("face_rgb", U8),
        ("face_normal", F32),
        ("tex_image", I64),
        ("tex_uv", I64),
        ("tex_hw", I32),
        ("soil", F32),
        ("soil_n", i32),
    ]


class Shading(Struct, c="shading_t"):
    """The light of a colour frame (render/shading.py)."""

    _fields_ = [
        ("soil_rgb", vec(3)),
        ("light", vec(3)),
        ("sky_horizon", vec(3)),
        ("sky_zenith", vec(3)),
        ("ambient", f64),
        ("far", f64),
        ("origin", vec(2)),
        ("texel", f64),
    ]


# ------------------------------------------------------------------ the kernels
class ProxyCastArgs(Args, kernel="proxy_cast"):
    _fields_ = [
        ("scene", block(ProxyScene)),
        ("n", i32),
        ("origin", vec(3)),
        ("dirs", F64),
        ("rot", F64),
        ("tlim", F64),
        ("t", F64),
        ("what", I32),
    ]


class RasterViewArgs(Args, kernel="raster_view"):
    _fields_ = [
        ("cam", block(Camera)),
        ("geom", block(Geometry)),
        ("terrain", i32),
        ("hiz", i32),
        ("iz", F32),
        ("inst", I32),
        ("prim", I32),
        ("row0", i32),
        ("row1", i32),
    ]


class ResolveViewArgs(Args, kernel="resolve_view"):
    _fields_ = [
        ("cam", block(Camera)),
        ("geom", block(Geometry)),
        ("forward", F64),
        ("vis_iz", F32),
        ("vis_inst", I32),
        ("vis_prim", I32),
        ("slot_plant", I32),
        ("proto_label", U8),
        ("refine_terrain", i32),
        ("robot_t", F64),
        ("robot_prim", I32),
        ("t", F64),
        ("label", U8),
        ("plant", I32),
        ("proto", I32),
        ("prim", I32),
        ("row0", i32),
        ("row1", i32),
    ]


class StereoPrepareArgs(Args, kernel="stereo_prepare"):
    _fields_ = [
        ("width", i32),
        ("height", i32),
        ("fx", f64),
        ("baseline", f64),
        ("t", F64),
        ("forward", F64),
        ("scratch", F64),
        ("row0", i32),
        ("row1", i32),
    ]


class StereoInvalidArgs(Args, kernel="stereo_invalid"):
    _fields_ = [
        ("cam", block(Camera)),
        ("geom", block(Geometry)),
        ("baseline", f64),
        ("nearest", f64),
        ("t", F64),
        ("forward", F64),
        ("left_inst", I32),
        ("left_prim", I32),
        ("right_iz", F32),
        ("right_inst", I32),
        ("right_prim", I32),
        ("scratch", F64),
        ("bad", U8),
        ("row0", i32),
        ("row1", i32),
    ]


class FinishDepthArgs(Args, kernel="finish_depth"):
    _fields_ = [
        ("i0", i32),
        ("i1", i32),
        ("t", F64),
        ("forward", F64),
        ("noise_tables", F64),
        ("noise_key", u64),
        ("k_sigma", f64),
        ("min_range", f64),
        ("max_range", f64),
        ("bad", U8),
        ("depth", F32),
        ("label", U8),
        ("plant", I32),
    ]


class PixelNormalsArgs(Args, kernel="pixel_normals"):
    _fields_ = [("tables", F64), ("key", u64), ("i0", i32), ("i1", i32), ("out", F64)]


class RefineRaysArgs(Args, kernel="refine_rays"):
    _fields_ = [
        ("geom", block(Geometry)),
        ("n", i32),
        ("origin", vec(3)),
        ("dirs", F32),
        ("t", F64),
        ("ground", U8),
    ]


class ShadeViewArgs(Args, kernel="shade_view"):
    _fields_ = [
        ("cam", block(Camera)),
        ("geom", block(Geometry)),
        ("materials", block(Materials)),
        ("shading", block(Shading)),
        ("forward", F64),
        ("t", F64),
        ("label", U8),
        ("vis_inst", I32),
        ("proto", I32),
        ("prim", I32),
        ("robot_rot", F64),
        ("robot_rgb", U8),
        ("robot_normal", F32),
        ("rgb", U8),
        ("row0", i32),
        ("row1", i32),
    ]


class EmbreePacketsArgs(Args, kernel="embree_packets"):
    _fields_ = [
        ("fn", Address),
        ("valid", Address),
        ("scene", Address),
        ("first", Address),
        ("count", i64),
        ("stride", i64),
    ]


class TyreGround(Struct, c="tyre_ground_t"):
    """The terrain's height grid and the soil under the tyres (sim/tyres.py)."""

    _fields_ = [
        ("heights", F64),
        ("heights0", F64),
        ("nx", i32),
        ("ny", i32),
        ("x0", f64),
        ("y0", f64),
        ("spacing", f64),
        ("radius", f64),
        ("dt", f64),
        ("kz", f64),
        ("cz", f64),
        ("friction", f64),
        ("shear_modulus", f64),
        ("contact_length", f64),
        ("rolling_resistance", f64),
        ("shear_damping", f64),
        ("contact_width", f64),
        ("slices", i32),
        ("bearing", i32),
        ("bear_cohesive", f64),
        ("bear_weight", f64),
        ("bear_k3", f64),
    ]


class TyreForcesArgs(Args, kernel="tyre_forces"):
    _fields_ = [
        ("ground", block(TyreGround)),
        ("n", i32),
        ("wheels", F64),
        ("shear", F64),
        ("normal", F64),
        ("out", F64),
    ]


class EkfConfig(Struct, c="ekf_config_t"):
    """The EKF's constants (estimation/ekf.py)."""

    _fields_ = [
        ("chi", f64),
        ("phi_b", f64),
        ("q_bias", f64),
        ("pose_noise", f64),
        ("yaw_noise", f64),
        ("velocity_noise", f64),
        ("yaw_accel_noise", f64),
        ("accel_noise", f64),
        ("odom_scale_noise", f64),
        ("tau", vec(4)),
        ("r_step", vec(7)),
        ("odom_speed_rel", f64),
        ("odom_yaw_rel", f64),
        ("odom_floor", f64),
        ("gnss_white", f64),
        ("history_s", f64),
        ("use_accel", i32),
    ]


class EkfFilter(Struct, c="ekf_filter_t"):
    """The EKF's state and history, which ``ekf_update`` reads and writes."""

    _fields_ = [
        ("s", F64),
        ("P", F64),
        ("mode", i32),
        ("gnss_var", f64),
        ("k", i32),
        ("capacity", i32),
        ("count", i32),
        ("head", i32),
        ("hist_s", F64),
        ("hist_P", F64),
        ("hist_r", F64),
        ("hist_var", F64),
        ("hist_mode", I32),
    ]


#: values per step in ``EkfUpdateArgs.reading`` and ``.gnss`` (csrc/native.h)
EKF_READING, EKF_GNSS = 8, 9
#: the status of a matrix that must be positive definite and is not (csrc/native.h)
NOT_POSITIVE = 7


class EkfUpdateArgs(Args, kernel="ekf_update"):
    _fields_ = [
        ("config", block(EkfConfig)),
        ("filter", block(EkfFilter)),
        ("dt", f64),
        ("reading", F64),
        ("gnss", F64),
    ]


class RlConfig(Struct, c="rl_config_t"):
    """robot_localization's planar filter's constants (estimation/robot_localization.py);
    a threshold of NaN never rejects."""

    _fields_ = [
        ("chi", f64),
        ("dt", f64),
        ("q", vec(8)),
        ("odom_var", vec(3)),
        ("yaw_var", f64),
        ("rate_var", f64),
        ("accel_var", vec(2)),
        ("odom_threshold", f64),
        ("imu_threshold", f64),
        ("accel_threshold", f64),
        ("gps_threshold", f64),
        ("history_s", f64),
        ("smooth", i32),
        ("fuse_rate", i32),
        ("fuse_accel", i32),
        ("lever_arm", i32),
    ]


class RlMeasurement(Struct, c="rl_measurement_t"):
    """One queued reading (its rings are byte arrays of these, filled by the kernel)."""

    _fields_ = [
        ("time", f64),
        ("order", i32),
        ("m", i32),
        ("index", ctypes.c_int32 * 3),
        ("z", vec(3)),
        ("var", vec(3)),
        ("threshold", f64),
    ]


class RlFilter(Struct, c="rl_filter_t"):
    """robot_localization's planar filter's state and history, which ``rl_update`` reads and
    writes."""

    _fields_ = [
        ("s", F64),
        ("P", F64),
        ("t_last", f64),
        ("k", i32),
        ("anchored", i32),
        ("rejected", ctypes.c_int32 * 3),
        ("capacity", i32),
        ("count", i32),
        ("head", i32),
        ("hist_t", F64),
        ("hist_s", F64),
        ("hist_P", F64),
        ("done_capacity", i32),
        ("done_count", i32),
        ("done_head", i32),
        ("done", U8),
        ("queue_capacity", i32),
        ("queue", U8),
    ]


#: values per step in ``RlUpdateArgs.reading`` (csrc/native.h's RL_READING)
RL_READING = 16


class RlUpdateArgs(Args, kernel="rl_update"):
    _fields_ = [
        ("config", block(RlConfig)),
        ("filter", block(RlFilter)),
        ("reading", F64),
    ]


class Route(Struct, c="route_t"):
    """A route's waypoints and its lookup table (routes.RoutePath)."""

    _fields_ = [
        ("xy", F64),
        ("arc", F64),
        ("n", i32),
        ("table", F64),
        ("tags", U8),
        ("m", i32),
        ("table_step", f64),
        ("end", vec(2)),
        ("direction", vec(2)),
        ("length", f64),
        ("furrow_last", i32),
    ]


class RouteTrackArgs(Args, kernel="route_track"):
    _fields_ = [
        ("route", block(Route)),
        ("x", f64),
        ("y", f64),
        ("k", i32),
        ("cte", f64),
        ("s", f64),
    ]


class RoutePointsArgs(Args, kernel="route_points"):
    _fields_ = [
        ("route", block(Route)),
        ("s", f64),
        ("n", i32),
        ("offsets", F64),
        ("x", f64),
        ("y", f64),
        ("cos_yaw", f64),
        ("sin_yaw", f64),
        ("lo", f64),
        ("hi", f64),
        ("out", F32),
    ]


class RouteGrid(Struct, c="route_grid_t"):
    """The nearest-segment search's segments and vertex grid (metrics.RouteProjector)."""

    _fields_ = [
        ("n", i32),
        ("segs", F64),
        ("seg_len", F64),
        ("arc", F64),
        ("half", f64),
        ("cell", f64),
        ("cx0", i32),
        ("cy0", i32),
        ("ncx", i32),
        ("ncy", i32),
        ("cell_start", I32),
        ("cell_items", I32),
        ("xy", F64),
    ]


class RouteNearestArgs(Args, kernel="route_nearest"):
    _fields_ = [
        ("grid", block(RouteGrid)),
        ("x", f64),
        ("y", f64),
        ("bound", f64),
        ("d", f64),
        ("s", f64),
        ("k", i32),
    ]


class Sky(Struct, c="sky_t"):
    """The GNSS sky model's canopy and cells (sensors/fixmode.py)."""

    _fields_ = [
        ("n", i32),
        ("xy", F64),
        ("radius", F64),
        ("bottom", F64),
        ("top", F64),
        ("share", F64),
        ("n_az", i32),
        ("n_el", i32),
        ("cos_az", F64),
        ("sin_az", F64),
        ("tan_el", F64),
        ("sec_el", F64),
        ("stalk", i32),
        ("db_per_m", f64),
        ("cell", f64),
        ("cx0", i32),
        ("cy0", i32),
        ("ncx", i32),
        ("ncy", i32),
        ("cell_start", I32),
        ("cell_items", I32),
    ]


class SkyAttenuationArgs(Args, kernel="sky_attenuation"):
    _fields_ = [
        ("sky", block(Sky)),
        ("x", f64),
        ("y", f64),
        ("z", f64),
        ("reach", f64),
        ("out", F64),
        ("n_found", i32),
    ]


def call(args: Args) -> None:
    """Run ``args``'s kernel; a status other than 0 raises ``KernelError``."""
    kernel = args.kernel
    require(f"the kernel {kernel}")
    status = _FUNCS[kernel](ctypes.byref(args))
    if status:
        raise KernelError(kernel, status, _LIB.agrinav_status(status).decode())


def kernel(name: str) -> Any:
    """Kernel ``name``'s foreign function, for a loop that calls it every step: it calls
    ``f(ctypes.byref(args))`` on an ``Args`` it filled once (by name, checked) and hands a
    status other than 0 to ``failed``."""
    require(f"the kernel {name}")
    return _FUNCS[name]


def failed(kernel: str, status: int) -> KernelError:
    """The error of kernel ``kernel`` returning ``status`` (to raise)."""
    return KernelError(kernel, status, _LIB.agrinav_status(status).decode())


# ------------------------------------------------------------------ loading
def source_hash(csrc: Path) -> str:
    """setup.py's hash of the kernels' sources in ``csrc``."""
    h = hashlib.sha256()
    for f in sorted(csrc.glob("*.[ch]")):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


def stale(handle: Any) -> str | None:
    """Why a loaded build does not match the sources beside it (None: it does, or there are
    none to compare, as in an installed wheel). A build left from other sources would be called
    with the wrong arguments: wrong images, not an error."""
    try:
        fn = handle.agrinav_source_hash
    except AttributeError:
        return "it predates the source check"
    fn.restype = ctypes.c_char_p
    built = fn().decode()
    csrc = Path(__file__).resolve().parent / "csrc"
    if not any(csrc.glob("*.c")):
        return None
    here = source_hash(csrc)
    return None if built == here else f"built from sources {built}, these are {here}"


def layout_mismatches(handle: Any) -> list[str]:
    """Where the build lays out a struct otherwise than its declaration here (every size and
    field offset compared with the compiler's, ``agrinav_layout``); empty when none."""
    fn = handle.agrinav_layout
    fn.restype, fn.argtypes = ctypes.c_int64, [ctypes.c_char_p, ctypes.c_char_p]
    out = []
    for s in STRUCTS:
        if not s.c:
            continue
        for name, value in [("", ctypes.sizeof(s))] + [(f, getattr(s, f).offset) for f in s._kinds]:
            built = fn(s.c.encode(), name.encode())
            if built != value:
                what = f"{s.c}.{name} at {built}" if name else f"sizeof({s.c}) {built}"
                out.append(f"{what}, declared {value}")
    return out


def disabled() -> bool:
    return os.environ.get("AGRINAV_NATIVE", "1").strip().lower() in ("0", "false", "no", "off")


def origin() -> str | None:
    """The file the kernels were loaded from (None: not loaded)."""
    return _ORIGIN if _LIB is not None else None


def _find() -> str | None:
    chosen = os.environ.get("AGRINAV_NATIVE_LIB", "").strip()
    if chosen:
        if not Path(chosen).is_file():
            raise NativeUnavailable(f"AGRINAV_NATIVE_LIB={chosen}: no such file")
        return chosen
    spec = importlib.util.find_spec("agrinav_gym.render._native")
    return spec.origin if spec is not None else None


def lib() -> Any:
    """The loaded kernels, or None where the extension is not built or is disabled."""
    global _LIB, _TRIED, _REFUSED, _ORIGIN
    if disabled():
        return None
    if not _TRIED:
        _TRIED = True
        path = _find()
        handle = None
        if path is not None:
            try:
                handle = ctypes.CDLL(path)
            except OSError:
                if os.environ.get("AGRINAV_NATIVE_LIB", "").strip():
                    raise
        if handle is not None:
            why = stale(handle)
            if why is None:
                bad = layout_mismatches(handle)
                if bad:
                    why = "its structs differ from render/native.py's: " + "; ".join(bad[:4])
            if why is not None:
                _REFUSED = why
                warnings.warn(
                    f"agrinav_gym.render._native is refused ({why}); the sensors use their numpy "
                    "and Embree paths until it is rebuilt (pip install -e . or make test)",
                    RuntimeWarning,
                    stacklevel=2,
                )
            else:
                for name, args in KERNELS.items():
                    f = getattr(handle, name)
                    f.restype, f.argtypes = ctypes.c_int, [ctypes.POINTER(args)]
                    _FUNCS[name] = f
                handle.agrinav_status.restype = ctypes.c_char_p
                handle.agrinav_status.argtypes = [ctypes.c_int]
                _LIB, _ORIGIN = handle, path
    return _LIB


def available() -> bool:
    return lib() is not None


def require(what: str) -> Any:
    """The kernels, or an error saying how to get them."""
    handle = lib()
    if handle is None:
        if disabled():
            why = "disabled by AGRINAV_NATIVE=0"
        elif _REFUSED is not None:
            why = f"refused, {_REFUSED} (rebuild: pip install -e . or make test)"
        else:
            why = "not built (reinstall with a C compiler: pip install -e . or make test)"
        raise NativeUnavailable(
            f"{what} needs the compiled kernels agrinav_gym.render._native: {why}"
        )
    return handle
