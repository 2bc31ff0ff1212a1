"""GNSS fix mode driven by the crop canopy over the antenna, plus random multipath slips.

**Sky.** The sky above the elevation mask is cut into azimuth × elevation cells. Along each
cell's ray from the antenna, the path length through the crop canopy is summed (each plant's
canopy is a vertical cylinder of the catalog canopy width, from the bare lower stalk to the
plant's top, holding its share of the row's foliage where neighbours overlap); the signal loses
``foliage_db_per_m`` per metre of canopy. The foliage fills each cylinder evenly
(``foliage_profile`` uniform) or thins from the stalk to the canopy's edge (``stalk``: density
2(1 − r²/ρ²), the same foliage in all), which makes the sky over the lane centre clearer than
over a row. A satellite in that cell can
be carrier-phase tracked (RTK) while the loss is below ``carrier_db`` and code tracked (a
standalone fix) below ``code_db``. The solid-angle-weighted fractions of the sky where each
holds are ``q_carrier`` and ``q_code``.

**Modes.** Fixed needs ``q_carrier ≥ fixed_sky``, float ``≥ float_sky``, a standalone fix
``q_code ≥ standalone_sky``: the mode the sky *supports* (capped by the receiver's best mode,
e.g. no RTK without base-station corrections). The receiver's mode is a Markov chain over
none < standalone < float < fixed evaluated at each fix epoch: above the supported mode it drops
to it after a mean ``loss_s`` (lock is lost within a few epochs); below it, it climbs one level
after a mean ``acquire_*_s`` (reacquisition, corrections, ambiguity resolution). In the
supported fixed mode, multipath slips it to float at a mean interval ``multipath_mtbf_s``
times the clear-sky fraction (fewer clean satellites, more slips). With
``refix_sky_exponent`` k > 0 the mean time from float to fixed is ``acquire_fixed_s /
q_carrier^k`` (fewer clean satellites, slower ambiguity resolution). Every draw comes from
the rng passed in: same seed, same modes. Multipath jumps and false fixes are
``sensors.gnss_faults``.
"""

from __future__ import annotations

import ctypes
import math
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from scenario_gen import Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.crops import scaled_by_height

from ..config import GnssFixConfig
from ..interface import FIX_LEVELS
from ..render import native as _native

LEVELS = FIX_LEVELS  # the chain's states, worst to best
#: the lower stalk bears no green leaves (as the proxy camera's leaf band starts above it)
LEAF_BASE = 0.2
#: canopy farther than this from the antenna is ignored: a low ray that crossed this much
#: foliage is far past every tracking threshold anyway
MAX_RANGE_M = 8.0
#: the kernel's plant grid: a reach of 8 m reads 9 × 9 cells (a few plants each in rows)
GRID_CELL_M = 2.0


class Canopy:
    """Every plant's foliage as a cylinder: centre, radius, bottom and top height (ENU)."""

    def __init__(self, scn: Scenario) -> None:
        p = scn.plants
        radius = scaled_by_height(
            p.species, p.stage, p.height, lambda sp, g: 0.5 * sp.canopy_width(g)
        )
        self.xy = np.column_stack([p.x, p.y]).astype(np.float64)
        self.radius = np.ascontiguousarray(radius, np.float64)
        self.bottom = np.asarray(p.z + LEAF_BASE * p.height, np.float64)
        self.top = np.asarray(p.z + p.height, np.float64)
        self.tree = cKDTree(self.xy if len(self.xy) else np.zeros((1, 2)))
        # Neighbours' canopies overlap along a row (0.18 m apart, 1 m wide): each cylinder
        # holds its share s/(2ρ) of the row's foliage, so the summed paths through overlapping
        # cylinders equal the path through the row's canopy (exactly along the row).
        self.share = np.ones(len(p))
        if len(p) > 1:
            gap, _ = self.tree.query(self.xy, k=2)
            self.share = np.minimum(1.0, gap[:, 1] / np.maximum(2.0 * radius, 1e-9))
        self.max_radius = float(radius.max()) if len(radius) else 0.0
        self.max_top = float(self.top.max()) if len(self.top) else -math.inf
        #: unit vector across the rows (ENU): ``across_row_update_m`` measures moves along it
        self.across = np.asarray(scn.rows.n, np.float64)

    @cached_property
    def grid(self) -> _native.CellGrid:
        """The plants by cells of a few metres, as the kernel's search reads them."""
        return _native.cell_grid(self.xy, GRID_CELL_M)

    def __len__(self) -> int:
        return len(self.radius)


class SkyModel:
    """Usable-sky fractions for carrier and code tracking at an antenna position.

    The foliage loss runs in the compiled kernel ``sky_attenuation`` where the extension is
    built (``native`` None: when available), else in numpy (``attenuation_numpy``, the
    reference): the same loss to a few units in a double's last place."""

    def __init__(self, cfg: GnssFixConfig, canopy: Canopy, native: bool | None = None) -> None:
        self.cfg = cfg
        self.canopy = canopy
        az = (np.arange(cfg.azimuth_cells) + 0.5) * (2 * math.pi / cfg.azimuth_cells)
        mask = math.radians(cfg.elevation_mask_deg)
        edges = np.linspace(mask, 0.5 * math.pi, cfg.elevation_cells + 1)
        el = 0.5 * (edges[:-1] + edges[1:])
        self.cos_az, self.sin_az = np.cos(az), np.sin(az)
        self.tan_el, self.sec_el = np.tan(el), 1.0 / np.cos(el)
        # solid angle of a band: ∫cos(el) d(el), the same for every azimuth cell
        band = np.sin(edges[1:]) - np.sin(edges[:-1])
        self.weight = np.broadcast_to(band / band.sum() / len(az), (len(az), len(el)))
        self.mask_tan = math.tan(mask)
        self._args: _native.SkyAttenuationArgs | None = None
        if _native.available() if native is None else native:
            sky = _native.Sky(
                n=len(canopy),
                xy=canopy.xy,
                radius=canopy.radius,
                bottom=canopy.bottom,
                top=canopy.top,
                share=canopy.share,
                n_az=len(az),
                n_el=len(el),
                cos_az=self.cos_az,
                sin_az=self.sin_az,
                tan_el=self.tan_el,
                sec_el=self.sec_el,
                stalk=int(cfg.foliage_profile == "stalk"),
                db_per_m=float(cfg.foliage_db_per_m),
                **canopy.grid.fields(),
            )
            self._out = np.zeros((len(az), len(el)))
            self._args = _native.SkyAttenuationArgs(
                sky=sky, x=0.0, y=0.0, z=0.0, reach=0.0, out=self._out, n_found=0
            )
            self._call = _native.kernel("sky_attenuation")
            self._ref = ctypes.byref(self._args)

    def _reach(self, z: float) -> float | None:
        """How far from the antenna at height ``z`` a plant can shade a ray above the mask
        (None: no canopy rises above the antenna)."""
        c = self.canopy
        above = c.max_top - z
        if len(c) == 0 or above <= 0.0:
            return None
        return min(MAX_RANGE_M, above / self.mask_tan + c.max_radius)

    def attenuation(self, antenna: FloatArray) -> FloatArray:
        """Foliage loss in dB of every (azimuth, elevation) cell's ray from ``antenna``."""
        if self._args is None:
            return self.attenuation_numpy(antenna)
        x, y, z = antenna.tolist()
        reach = self._reach(z)
        if reach is None:
            return np.zeros(self.weight.shape)
        a = self._args
        a.x, a.y, a.z, a.reach = x, y, z, reach  # floats: the checked ``set`` is not needed
        status = self._call(self._ref)
        if status:
            raise _native.failed("sky_attenuation", status)
        return self._out.copy()

    def attenuation_numpy(self, antenna: FloatArray) -> FloatArray:
        """``attenuation`` in numpy: the kernel's reference and twin."""
        c = self.canopy
        out = np.zeros(self.weight.shape)
        reach = self._reach(float(antenna[2]))
        if reach is None:
            return out
        # summed in index order (the tree returns one point's neighbours in its own order)
        idx = np.sort(np.asarray(c.tree.query_ball_point(antenna[:2], reach), dtype=np.intp))
        if len(idx) == 0:
            return out
        idx = idx[c.top[idx] > antenna[2]]
        d = c.xy[idx] - antenna[:2]
        rho = c.radius[idx, None]
        # along- and cross-track offsets of each plant from each azimuth's vertical plane
        t = d[:, :1] * self.cos_az + d[:, 1:] * self.sin_az
        x = -d[:, :1] * self.sin_az + d[:, 1:] * self.cos_az
        half = np.sqrt(np.maximum(rho * rho - x * x, 0.0))  # half chord, 0 if missed
        lo = np.maximum(t - half, 0.0)[..., None]
        hi = (t + half)[..., None]
        # the ray is within the foliage's height band for s in [s_bottom, s_top]
        s_bot = np.maximum(c.bottom[idx] - antenna[2], 0.0)[:, None, None] / self.tan_el
        s_top = (c.top[idx] - antenna[2])[:, None, None] / self.tan_el
        a, b = np.maximum(lo, s_bot), np.minimum(hi, s_top)
        if self.cfg.foliage_profile == "uniform":
            length = np.maximum(b - a, 0.0)
        else:  # "stalk": density 2(1 − r²/ρ²), integrated along the chord
            u1, u2 = a - t[..., None], b - t[..., None]
            rho2 = rho[..., None] ** 2
            w = 1.0 - (x * x)[..., None] / rho2
            length = 2.0 * (w * (u2 - u1) - (u2**3 - u1**3) / (3.0 * rho2))
            length = np.where(b > a, np.maximum(length, 0.0), 0.0)
        path = np.einsum("i,ijk->jk", c.share[idx], length) * self.sec_el
        out += self.cfg.foliage_db_per_m * path
        return out

    def usable(self, antenna: FloatArray) -> tuple[float, float]:
        """(q_carrier, q_code): solid-angle fractions of the sky each kind of tracking sees."""
        a = self.attenuation(antenna)
        return (
            float(self.weight[a < self.cfg.carrier_db].sum()),
            float(self.weight[a < self.cfg.code_db].sum()),
        )


class FixModeChain:
    """The receiver's fix mode as a Markov chain over LEVELS, stepped at each fix epoch."""

    def __init__(self, cfg: GnssFixConfig, best: str, epoch_s: float) -> None:
        self.cfg = cfg
        self.best = LEVELS.index(best)
        self.epoch_s = epoch_s
        acquire = (cfg.acquire_standalone_s, cfg.acquire_float_s, cfg.acquire_fixed_s)
        self.p_up = [1.0 - math.exp(-epoch_s / t) for t in acquire]
        self.p_loss = 1.0 - math.exp(-epoch_s / cfg.loss_s)
        self.level = self.best

    def _p_up(self, level: int, q_carrier: float) -> float:
        """Probability of climbing from ``level`` in one epoch."""
        k = self.cfg.refix_sky_exponent
        if level != 2 or k == 0.0:
            return self.p_up[level]
        mean = self.cfg.acquire_fixed_s / max(q_carrier, 0.05) ** k
        return 1.0 - math.exp(-self.epoch_s / mean)

    def supported(self, q_carrier: float, q_code: float) -> int:
        c = self.cfg
        if q_code < c.standalone_sky:
            return 0
        if self.best >= 3 and q_carrier >= c.fixed_sky:
            return 3
        if self.best >= 2 and q_carrier >= c.float_sky:
            return 2
        return 1

    def reset(self, q_carrier: float, q_code: float) -> str:
        """Start converged: the receiver has been running before the episode."""
        self.level = self.supported(q_carrier, q_code)
        return LEVELS[self.level]

    def step(self, q_carrier: float, q_code: float, rng: np.random.Generator) -> str:
        sup = self.supported(q_carrier, q_code)
        u = float(rng.random())  # one draw per epoch, whatever happens
        if self.level > sup:
            if u < self.p_loss:
                self.level = sup
        elif self.level < sup:
            if u < self._p_up(self.level, q_carrier):
                self.level += 1
        elif self.level == 3:
            rate = 1.0 / (self.cfg.multipath_mtbf_s * max(q_carrier, 0.05))
            if u < 1.0 - math.exp(-self.epoch_s * rate):
                self.level = 2
        return LEVELS[self.level]
