"""Things in the lane: surface stones, litter and fallen (lodged) maize stalks.

Each obstacle is a small rigid object resting on the terrain's bilinear surface (the surface
the robot's tyres and the cameras see). Its pose is the ground point under its centre and
R = Rz(yaw)·Ry(pitch)·Rx(roll); its size is the box it fills in that frame (length along its
own x, width, height). The shape is procedural and regenerates from the file: a stone is the
convex hull of an icosphere scaled to its diameters with its radii roughened by a per-stone
seed (``shape``), a fallen stalk an octagonal prism, litter a box. One mesh per object serves
every consumer: the mesh camera, the proxy camera's stand-ins, the collision body, the exports.

Sources for the ranges (docs/design.md "Obstacles"): stone sizes are the FAO coarse-fragment
class "stones", 6-20 cm (FAO 2006, Guidelines for soil description, 4th ed., "Coarse surface
fragments"); how many there are, and the litter's count and size, are assumed (virtual_maize_field
places a handful of litter items per field, its ``--litters``); stalk lodging takes the fraction
of plants fallen, whose order is the 5-20 % yield loss to lodging reported for maize
(Flint-Garcia et al. 2003, Crop Science 43:13-22). Every count defaults to zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

from .arrays import FloatArray, IntArray
from .spec import ObstacleSpec
from .terrain import Terrain

#: what an obstacle can be (one word each: files, labels, metrics and exports use these)
OBSTACLE_KINDS = ("stone", "litter", "stalk")
STONE, LITTER, STALK = OBSTACLE_KINDS

#: fraction of a stone's height below the ground surface (assumed: surface stones sit partly
#: buried; only what is above the surface matters to the robot and the cameras)
STONE_BURIED = 0.25
#: relative roughness of a stone's radii before the convex hull (assumed)
STONE_ROUGHNESS = 0.2
#: sides of a fallen stalk's prism
STALK_SIDES = 8
#: a lodged plant falls from its base: the stalk lying on the ground is this share of its height
#: (the tassel and the top leaves fold over; assumed)
STALK_LENGTH_SHARE = 0.9
#: no obstacle within this distance (m) of the route's first waypoint, beyond the robot's reach
START_CLEAR = 0.6


@dataclass(frozen=True, eq=False)
class Obstacles:
    """One entry per obstacle (file ``obstacles.csv``)."""

    kind: NDArray[np.str_]
    x: FloatArray  # centre of the footprint, ENU m
    y: FloatArray
    z: FloatArray  # the local frame's origin: on the ground under the centre
    roll: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    length: FloatArray  # along the object's x, m
    width: FloatArray
    height: FloatArray  # above its frame's origin (a stone's buried part not included), m
    shape: IntArray  # per-object seed of the procedural outline (stones)

    def __len__(self) -> int:
        return len(self.x)

    @classmethod
    def empty(cls) -> Obstacles:
        f = np.empty(0)
        return cls(np.empty(0, "<U6"), f, f, f, f, f, f, f, f, f, np.empty(0, np.int64))

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def counts(self) -> dict[str, int]:
        return {k: int((self.kind == k).sum()) for k in OBSTACLE_KINDS}

    def rotation(self, i: int) -> FloatArray:
        return rotation(float(self.roll[i]), float(self.pitch[i]), float(self.yaw[i]))

    def local_mesh(self, i: int) -> tuple[FloatArray, NDArray[np.int64]]:
        """Vertices (object frame, metres) and faces (outward, counter-clockwise) of ``i``."""
        k = str(self.kind[i])
        size = (float(self.length[i]), float(self.width[i]), float(self.height[i]))
        if k == STONE:
            return stone_mesh(*size, int(self.shape[i]))
        if k == STALK:
            return stalk_mesh(*size)
        return box_mesh(*size)

    def mesh(self, i: int) -> tuple[FloatArray, NDArray[np.int64]]:
        """Obstacle ``i``'s mesh in ENU."""
        v, f = self.local_mesh(i)
        pos = np.array([self.x[i], self.y[i], self.z[i]])
        return v @ self.rotation(i).T + pos, f

    def meshes(self) -> tuple[FloatArray, NDArray[np.int64], IntArray]:
        """Every obstacle's mesh in ENU as one: vertices, faces and each face's obstacle."""
        vs, fs, owner = [], [], []
        base = 0
        for i in range(len(self)):
            v, f = self.mesh(i)
            vs.append(v)
            fs.append(f + base)
            owner.append(np.full(len(f), i, np.int64))
            base += len(v)
        if not vs:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
        return np.concatenate(vs), np.concatenate(fs), np.concatenate(owner)

    def footprints(self) -> FloatArray:
        """(n, 4, 2): each obstacle's footprint rectangle (length × width about its centre,
        turned by its yaw) seen from above, corners counter-clockwise."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        hl, hw = 0.5 * self.length, 0.5 * self.width
        corners = np.array([(1, 1), (-1, 1), (-1, -1), (1, -1)], float)
        lx = corners[None, :, 0] * hl[:, None]
        ly = corners[None, :, 1] * hw[:, None]
        x = self.x[:, None] + c[:, None] * lx - s[:, None] * ly
        y = self.y[:, None] + s[:, None] * lx + c[:, None] * ly
        return np.stack([x, y], axis=-1)


def rotation(roll: float, pitch: float, yaw: float) -> FloatArray:
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


# ---------------------------------------------------------------------- shapes
@lru_cache(maxsize=1)
def _icosphere() -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
    """Unit icosphere (162 vertices) and its neighbour-averaging matrix."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2)
    v = np.asarray(s.vertices, float)
    avg = np.zeros((len(v), len(v)))
    for i, nbr in enumerate(s.vertex_neighbors):
        avg[i, nbr] = 1.0 / len(nbr)
    return v, np.asarray(s.faces, np.int64), avg


@lru_cache(maxsize=4096)
def _stone(length: float, width: float, height: float, seed: int) -> tuple[bytes, bytes, int]:
    import trimesh

    v, _, avg = _icosphere()
    rng = np.random.default_rng(seed)
    # smooth radial roughness: random per vertex, averaged with the neighbours twice, so the
    # outline has a few facets rather than spikes
    r = rng.uniform(-1.0, 1.0, len(v))
    for _ in range(2):
        r = 0.5 * r + 0.5 * (avg @ r)
    r = 1.0 + STONE_ROUGHNESS * r / max(float(np.abs(r).max()), 1e-9)
    p = v * r[:, None] * np.array([0.5 * length, 0.5 * width, 0.5 * height / (1 - STONE_BURIED)])
    hull = trimesh.Trimesh(p, process=False).convex_hull
    hv = np.asarray(hull.vertices, float)
    # rescale to the drawn diameters exactly, then sink: the top is `height` above the ground
    lo, hi = hv.min(axis=0), hv.max(axis=0)
    full = np.array([length, width, height / (1 - STONE_BURIED)])
    hv = (hv - 0.5 * (lo + hi)) * (full / np.maximum(hi - lo, 1e-9))
    hv[:, 2] += 0.5 * full[2] - STONE_BURIED * full[2]
    faces = np.asarray(hull.faces, np.int64)
    return hv.tobytes(), faces.tobytes(), len(faces)


def stone_mesh(
    length: float, width: float, height: float, seed: int
) -> tuple[FloatArray, NDArray[np.int64]]:
    """A rough convex stone of these diameters; its top ``height`` above z = 0."""
    vb, fb, n = _stone(length, width, height, seed)
    return np.frombuffer(vb).reshape(-1, 3).copy(), np.frombuffer(fb, np.int64).reshape(n, 3).copy()


def stalk_mesh(length: float, width: float, height: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """An octagonal prism along x, centred, lying on z = 0 (diameter ``width``, top ``height``)."""
    a = np.linspace(0.0, 2 * math.pi, STALK_SIDES, endpoint=False)
    ry, rz = 0.5 * width, 0.5 * height
    ring = np.column_stack([ry * np.cos(a), rz + rz * np.sin(a)])
    hl = 0.5 * length
    v = np.concatenate(
        [
            np.column_stack([np.full(STALK_SIDES, -hl), ring]),
            np.column_stack([np.full(STALK_SIDES, hl), ring]),
            [[-hl, 0.0, rz], [hl, 0.0, rz]],
        ]
    )
    n = STALK_SIDES
    f = []
    for k in range(n):
        k1 = (k + 1) % n
        f += [[k, k1, n + k1], [k, n + k1, n + k]]  # side
        f += [[2 * n, k1, k], [2 * n + 1, n + k, n + k1]]  # end caps
    return v, _outward(v, np.array(f, np.int64))


def box_mesh(length: float, width: float, height: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """A box centred over the origin, standing on z = 0."""
    hl, hw = 0.5 * length, 0.5 * width
    v = np.array(
        [[sx * hl, sy * hw, z] for z in (0.0, height) for sy in (-1, 1) for sx in (-1, 1)], float
    )
    f = np.array(
        [
            [0, 2, 1], [1, 2, 3],  # bottom
            [4, 5, 6], [5, 7, 6],  # top
            [0, 1, 4], [1, 5, 4],
            [2, 6, 3], [3, 6, 7],
            [0, 4, 2], [2, 4, 6],
            [1, 3, 5], [3, 7, 5],
        ],
        np.int64,
    )  # fmt: skip
    return v, _outward(v, f)


def _outward(v: FloatArray, f: NDArray[np.int64]) -> NDArray[np.int64]:
    """Faces of a convex solid wound counter-clockwise seen from outside."""
    c = v.mean(axis=0)
    a, b, d = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, d - a)
    flip = np.einsum("ij,ij->i", n, (a + b + d) / 3 - c) < 0
    out = f.copy()
    out[flip] = out[flip][:, ::-1]
    return out


# ---------------------------------------------------------------------- placement
def _uniform_in(
    area: BaseGeometry, count: int, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray]:
    if count == 0 or area.is_empty:
        return np.empty(0), np.empty(0)
    xmin, ymin, xmax, ymax = area.bounds
    fill = area.area / max((xmax - xmin) * (ymax - ymin), 1e-12)
    xs, ys, have = [], [], 0
    while have < count:
        m = int((count - have) / fill * 1.2) + 16
        x, y = rng.uniform(xmin, xmax, m), rng.uniform(ymin, ymax, m)
        inside = shapely.contains_xy(area, x, y)
        xs.append(x[inside])
        ys.append(y[inside])
        have += int(inside.sum())
    return np.concatenate(xs)[:count], np.concatenate(ys)[:count]


def _log_uniform(rng: np.random.Generator, lo: float, hi: float, n: int) -> FloatArray:
    return np.exp(rng.uniform(math.log(lo), math.log(hi), n))


def _on_ground(
    terrain: Terrain, x: FloatArray, y: FloatArray, yaw: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Ground height and (roll, pitch) putting the object's z on the bilinear surface's
    normal (as plants are oriented: ``generate.orientation``)."""
    z = terrain.height_at(x, y)
    nrm = terrain.normal_at(x, y).reshape(-1, 3)
    zx, zy = -nrm[:, 0] / nrm[:, 2], -nrm[:, 1] / nrm[:, 2]
    c, s = np.cos(yaw), np.sin(yaw)
    zxp, zyp = zx * c + zy * s, -zx * s + zy * c
    pitch = np.arctan(-zxp)
    roll = np.arctan(zyp * np.cos(pitch))
    return z, roll, pitch


def _lying(
    terrain: Terrain, x: FloatArray, y: FloatArray, yaw: FloatArray, length: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A stiff stalk on uneven ground rests on its highest points: the line between its ends'
    heights, lifted until no ground along it (sampled every centimetre) is above it. Returns
    z at the centre, roll (the slope across) and pitch (along; the stalk's horizontal reach is
    its length times cos(pitch))."""
    n = int(min(max(np.ceil(length.max(initial=0.0) / 0.01), 2), 2000)) + 1
    t = np.linspace(-0.5, 0.5, n)
    c, s = np.cos(yaw), np.sin(yaw)
    pitch = np.zeros(len(x))
    z = np.zeros(len(x))
    for _ in range(2):  # the second pass samples the reach the first pass's tilt leaves
        reach = length * np.cos(pitch)
        g = terrain.height_at(
            x[:, None] + t[None, :] * (reach * c)[:, None],
            y[:, None] + t[None, :] * (reach * s)[:, None],
        )
        line = g[:, :1] + (t[None, :] + 0.5) * (g[:, -1:] - g[:, :1])
        z = 0.5 * (g[:, 0] + g[:, -1]) + np.max(g - line, axis=1)
        pitch = -np.arcsin(np.clip((g[:, -1] - g[:, 0]) / np.maximum(length, 1e-9), -1.0, 1.0))
    _, roll, _ = _on_ground(terrain, x, y, yaw)
    return z, roll, pitch


def place_obstacles(
    spec: ObstacleSpec,
    field: BaseGeometry,
    terrain: Terrain,
    crops_xy: FloatArray,
    stems: FloatArray,
    fallen_xy: FloatArray,
    fallen_stems: FloatArray,
    fallen_heights: FloatArray,
    start: tuple[float, float] | None,
    rng: np.random.Generator,
) -> Obstacles:
    """The obstacles of one field.

    ``crops_xy`` and ``stems`` (stalk radii) are the standing crop plants'; each fallen plant
    (``fallen_*``: base, stalk radius, height) becomes a stalk lying from its base towards the
    field's wind direction (drawn once), spread by ``lodging_spread_deg``. Stones and litter
    are uniform over the field (Poisson counts of their densities), never on a standing stalk
    nor within ``START_CLEAR`` of the route's start."""
    o = spec
    area = float(field.area)
    n_st = int(rng.poisson(o.stone_density * area)) if o.stone_density > 0 else 0
    n_li = int(rng.poisson(o.litter_density * area)) if o.litter_density > 0 else 0
    wind = rng.uniform(-math.pi, math.pi)
    parts: list[dict[str, np.ndarray]] = []
    tree = cKDTree(crops_xy) if len(crops_xy) and (n_st or n_li) else None  # stones, litter
    stem_max = float(stems.max()) if len(stems) else 0.0

    def clear(x: FloatArray, y: FloatArray, reach: FloatArray) -> NDArray[np.bool_]:
        ok = np.ones(len(x), bool)
        if tree is not None and len(x):
            d, _ = tree.query(np.column_stack([x, y]))
            ok &= d > reach + stem_max
        if start is not None:
            ok &= np.hypot(x - start[0], y - start[1]) > reach + START_CLEAR
        return ok

    for kind, count in ((STONE, n_st), (LITTER, n_li)):
        if count == 0:
            continue
        lo, hi = o.stone_size if kind == STONE else o.litter_size
        length = _log_uniform(rng, lo, hi, count)
        width = length * rng.uniform(0.5 if kind == STONE else 0.3, 1.0, count)
        if kind == STONE:  # stones lie on their flattest side
            height = width * rng.uniform(0.4, 0.8, count)
        else:  # bags and sheets to bottles and cans lying down
            height = width * _log_uniform(rng, 0.05, 1.0, count)
        yaw = rng.uniform(-math.pi, math.pi, count)
        shape = rng.integers(0, 2**31, count)
        x, y = _uniform_in(field, count, rng)
        keep = clear(x, y, 0.5 * np.hypot(length, width))
        z, roll, pitch = _on_ground(terrain, x, y, yaw)
        parts.append(
            dict(
                kind=np.full(count, kind), x=x, y=y, z=z, roll=roll, pitch=pitch, yaw=yaw,
                length=length, width=width, height=height, shape=shape, keep=keep,
            )
        )  # fmt: skip
    n_sk = len(fallen_xy)
    if n_sk:
        bx, by = fallen_xy[:, 0], fallen_xy[:, 1]
        yaw = wind + np.radians(o.lodging_spread_deg) * rng.standard_normal(n_sk)
        length = STALK_LENGTH_SHARE * fallen_heights
        dia = 2.0 * fallen_stems
        x, y = bx + 0.5 * length * np.cos(yaw), by + 0.5 * length * np.sin(yaw)
        z, roll, pitch = _lying(terrain, x, y, yaw, length)
        keep = np.ones(n_sk, bool)
        if start is not None:  # a stalk across the start is dropped: its plant is a gap
            keep &= _segment_distance(start, bx, by, yaw, length) > START_CLEAR
        parts.append(
            dict(
                kind=np.full(n_sk, STALK), x=x, y=y, z=z, roll=roll, pitch=pitch, yaw=yaw,
                length=length, width=dia, height=dia, shape=np.zeros(n_sk, np.int64), keep=keep,
            )
        )  # fmt: skip
    if not parts:
        return Obstacles.empty()
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    keep = cat.pop("keep")
    return Obstacles(
        kind=cat["kind"][keep].astype("<U6"),
        x=cat["x"][keep],
        y=cat["y"][keep],
        z=cat["z"][keep],
        roll=cat["roll"][keep],
        pitch=cat["pitch"][keep],
        yaw=cat["yaw"][keep],
        length=cat["length"][keep],
        width=cat["width"][keep],
        height=cat["height"][keep],
        shape=cat["shape"][keep].astype(np.int64),
    )


def _segment_distance(
    p: tuple[float, float], bx: FloatArray, by: FloatArray, yaw: FloatArray, length: FloatArray
) -> FloatArray:
    """Distance from ``p`` to each segment from (bx, by) along ``yaw`` for ``length``."""
    dx, dy = np.cos(yaw), np.sin(yaw)
    t = np.clip((p[0] - bx) * dx + (p[1] - by) * dy, 0.0, length)
    return np.hypot(p[0] - (bx + t * dx), p[1] - (by + t * dy))
