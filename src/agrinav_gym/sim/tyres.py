"""Wheel–ground forces of the skid-steer robot, computed explicitly each physics step.

pybullet's own wheel contact was measured unfit for a skid-steer (docs/physics.md): its friction
pyramid is aligned with the world axes, so an in-place turn ran 0.27–0.42 rad/s for one
command depending on the heading; the turn rate changed with the physics rate (0.56 → 0.81 of
the kinematic rate from 240 to 960 Hz); and spheres rolling over the heightfield's triangles
chattered (normal force 0–300 N per wheel, contact normals tilted 15° on flat ground). So the
wheels do not collide with the ground at all; each physics step every wheel gets

* a **normal force** from the tyre and soil's vertical compliance: a spring–damper on the
  wheel's penetration of the terrain's bilinear surface (the surface the sensors see), at a
  point under the wheel centre or, with ``soil.contact_width``, summed over discs across the
  tread;
* a **shear (traction) force** from the Janosi–Hanamoto law ``τ = τ_max (1 − e^(−j/K))``,
  ``τ_max = μ N``, where the shear displacement ``j`` of the contact patch is a state: it
  grows with the slip velocity and relaxes as the tread leaves the patch, over the contact
  length ``l`` (``dj/dt = s − (|u|/l) j``, the first-order "relaxation length" tyre model).
  Rolling, the steady shear is ``j = l·s/|u|`` — the slip ratio times ``l``, as in the brush
  and terramechanics models; at rest ``j`` is the elastic deflection that holds the robot on a
  slope (no creep);
* a **rolling (motion) resistance** ``c_rr N`` against the wheel's travel.

The forces act at the contact point on the wheel link, so the velocity-controlled wheel motors
feel their reaction torque. The arithmetic runs in a compiled kernel (``render/csrc/tyres.c``)
with this module's Python as its twin and reference, bit for bit; per physics step what is left
in Python is pybullet's calls (two queries and four forces, docs/physics.md "Cost").
"""

from __future__ import annotations

import ctypes
import math
import struct
from collections.abc import Sequence
from typing import Any

import numpy as np
import pybullet as p

from scenario_gen import Terrain

from ..config import SoilConfig
from ..render import native as _native
from .terramechanics import DiscBearing, disc_bearing

#: plastic limit of the shear state, in units of K: beyond it τ is within 2 % of τ_max
SHEAR_CAP = 4.0
#: below this travel speed (m/s) the motion resistance fades in linearly, so it never pushes
#: a robot at rest
RR_SPEED = 0.01
WHEELS = 4
#: the most discs a tread is cut into (a 0.5 m tread on a 3 cm grid)
MAX_SLICES = 32
WORLD = p.WORLD_FRAME
#: the kernel's wheel states in (14 doubles a wheel) and forces out (7 a wheel)
_PACK_IN = struct.Struct(f"{14 * WHEELS}d")
_UNPACK_OUT = struct.Struct(f"{7 * WHEELS}d")
#: one wheel's contact: normal force N, unit normal xyz, wheel centre -> contact point xyz
_Contact = tuple[float, float, float, float, float, float, float]


#: Stable corner damping, as fractions of ω·dt (ω = √(k_z / corner mass), dt the physics
#: step): the rigid chassis on four explicitly integrated spring–dampers rocks itself over
#: below ζ ≈ 0.5-0.65·ω·dt (measured at 240 Hz, 10 s standing still: k_z 6·10⁴ N/m ζ 0.10
#: tips over; 1.5·10⁵ ζ 0.23 rocks 4°, 0.30 holds within 0.7°; 3·10⁵ ζ 0.32 rocks 15°, 0.45
#: holds), and an explicit damper overshoots once ζ·ω·dt approaches 1 (3·10⁵ with ζ 2 tips
#: over; ζ·ω·dt 0.8 holds).
MIN_DAMPING_PER_OMEGA_DT = 0.65
MAX_DAMPING_OMEGA_DT = 0.8


def check_corner_stability(soil: SoilConfig, corner_mass: float, dt: float) -> None:
    """Refuse soil values whose vertical spring-damper the physics step cannot integrate. The
    error names what the user changed: the physics rate when the soil holds its defaults, the
    stiffness when only it was changed, else the damping."""
    from scenario_gen.errors import InputError

    omega = math.sqrt(soil.vertical_stiffness / corner_mass)
    r = omega * dt
    lo, hi = MIN_DAMPING_PER_OMEGA_DT * r, MAX_DAMPING_OMEGA_DT / r
    zeta = soil.damping_ratio
    if lo <= zeta <= hi:
        return
    # both bounds narrow as dt grows: a faster physics rate is the other way out
    rate = ""
    if zeta > 0:
        need = omega * max(MIN_DAMPING_PER_OMEGA_DT / zeta, zeta / MAX_DAMPING_OMEGA_DT)
        rate = f"; this damping and stiffness need robot.physics_hz >= {math.ceil(need)}"
        if soil.at_defaults("damping_ratio", "vertical_stiffness"):
            raise InputError(
                "config.robot.physics_hz",
                round(1.0 / dt),
                f"allowed with soil.damping_ratio {zeta:g} and vertical_stiffness "
                f"{soil.vertical_stiffness:g} N/m: at least {math.ceil(need)} (slower, the "
                "wheels' spring-damper rocks the robot over standing still)",
            )
        if soil.at_defaults("damping_ratio"):
            # both bounds cap ω for a given ζ: ζ >= a·ω·dt and ζ <= b / (ω·dt)
            w_max = min(zeta / MIN_DAMPING_PER_OMEGA_DT, MAX_DAMPING_OMEGA_DT / zeta) / dt
            raise InputError(
                "config.soil.vertical_stiffness",
                soil.vertical_stiffness,
                f"allowed with damping_ratio {zeta:g} at robot.physics_hz {round(1.0 / dt)}: "
                f"at most {corner_mass * w_max**2:.0f} N/m (stiffer, the wheels' spring-damper "
                f"rocks the robot over standing still){rate}",
            )
    raise InputError(
        "config.soil.damping_ratio",
        zeta,
        f"allowed with vertical_stiffness {soil.vertical_stiffness:g} N/m at robot."
        f"physics_hz {round(1.0 / dt)}: {lo:.2f}..{hi:.2f} (outside it the robot rocks "
        f"itself over standing still){rate}",
    )


def check_bearing(soil: SoilConfig) -> None:
    """Refuse a yielding ground without a tread: the bearing limit is a pressure on a patch."""
    from scenario_gen.errors import InputError

    if soil.cohesion_kpa is not None and soil.contact_width <= 0.0:
        raise InputError(
            "config.soil.cohesion_kpa",
            soil.cohesion_kpa,
            "allowed only with a tread (soil.contact_width > 0, e.g. 0.15): the ground's "
            "bearing limit is a pressure over the tread's contact patch; null for a rigid ground",
        )


def tread_slices(width: float, spacing: float) -> int:
    """Discs across a tread ``width`` wide on a height grid ``spacing`` apart (0: a point
    contact): at most half a cell each, so the bilinear surface's creases across the tread are
    resolved; at least 3, at most ``MAX_SLICES``."""
    if width <= 0.0:
        return 0
    return min(MAX_SLICES, max(3, math.ceil(width / (0.5 * spacing))))


class TyreModel:
    """Per-wheel normal, shear and rolling-resistance forces from the soil parameters.

    Each physics step ``apply`` reads the wheels' link states from pybullet, computes the
    forces — in the compiled kernel ``tyre_forces`` (``render/csrc/tyres.c``) where the
    extension is built, else in ``_forces``, its Python twin: the same expressions in the same
    order, so both give the same bits (tests compare them) — and applies them. ``native``
    forces a choice (None: the kernel when available; ``AGRINAV_NATIVE=0`` disables it).
    """

    def __init__(
        self,
        soil: SoilConfig,
        radius: float,
        corner_mass: float,
        dt: float,
        native: bool | None = None,
    ) -> None:
        self.soil = soil
        self.radius = radius
        self.dt = dt
        self.kz = soil.vertical_stiffness
        self.cz = 2.0 * soil.damping_ratio * math.sqrt(soil.vertical_stiffness * corner_mass)
        self.native = _native.available() if native is None else native
        if self.native:
            _native.require("the tyre model's kernel")
        self.shear = np.zeros((WHEELS, 3))  # per wheel: the contact patch's shear state, m
        self.normal = np.zeros(WHEELS)  # per wheel: the last step's normal force, N
        self._out = np.zeros((WHEELS, 7))
        self._wheels = np.zeros((WHEELS, 14))
        self._in = self._wheels.data.cast("B")
        self._outv = self._out.data.cast("B")
        self.slices = 0  # discs across the tread (0: a point contact)
        self.bearing: DiscBearing | None = None  # each disc's force limit (None: rigid ground)
        self._terrain: Terrain | None = None
        self._args: _native.TyreForcesArgs | None = None

    def reset(self, terrain: Terrain) -> None:
        self._terrain = terrain
        self.slices = tread_slices(self.soil.contact_width, terrain.spacing)
        self.bearing = disc_bearing(self.soil, self.slices)
        # a yielding ground is cut where the tread sinks: the model's own copy, whole again
        # at every reset (the terrain the sensors and cameras see is never cut)
        self._h0 = np.ascontiguousarray(terrain.heights, np.float64)
        if self.bearing is not None:
            self._h = self._h0.copy()
        else:
            self._h = self._h0
        self._x0, self._y0, self._sp = terrain.x0, terrain.y0, terrain.spacing
        self._ny, self._nx = terrain.heights.shape
        self.shear[:] = 0.0
        self.normal[:] = 0.0
        if self.native:
            s = self.soil
            ground = _native.TyreGround(
                heights=self._h, heights0=self._h0 if self.bearing else None,
                nx=self._nx, ny=self._ny, x0=self._x0, y0=self._y0, spacing=self._sp,
                radius=self.radius, dt=self.dt, kz=self.kz, cz=self.cz,
                friction=s.friction, shear_modulus=s.shear_modulus,
                contact_length=s.contact_length, rolling_resistance=s.rolling_resistance,
                shear_damping=s.shear_damping, contact_width=s.contact_width,
                slices=self.slices, bearing=int(self.bearing is not None),
                bear_cohesive=self.bearing.cohesive if self.bearing else 0.0,
                bear_weight=self.bearing.weight if self.bearing else 0.0,
                bear_k3=self.bearing.k3 if self.bearing else 0.0,
            )  # fmt: skip
            self._args = _native.TyreForcesArgs(
                ground=ground, n=WHEELS, wheels=self._wheels, shear=self.shear,
                normal=self.normal, out=self._out,
            )  # fmt: skip
            self._call = _native.kernel("tyre_forces")
            self._ref = ctypes.byref(self._args)

    def _cell(self, x: float, y: float) -> tuple[int, int, float, float]:
        """The grid cell (row, column) under (x, y), clamped to the grid, and where in it."""
        sp = self._sp
        u = min(max((x - self._x0) / sp, 0.0), self._nx - 1.0)
        v = min(max((y - self._y0) / sp, 0.0), self._ny - 1.0)
        j = min(int(u), self._nx - 2)
        i = min(int(v), self._ny - 2)
        return i, j, u - j, v - i

    def surface(
        self, x: float, y: float, grid: np.ndarray | None = None
    ) -> tuple[float, float, float]:
        """Height and slope (∂z/∂x, ∂z/∂y) of the bilinear terrain at (x, y) (of ``grid``: by
        default the ground the tyres stand on)."""
        sp = self._sp
        i, j, fu, fv = self._cell(x, y)
        h = self._h if grid is None else grid
        a, b = h.item(i, j), h.item(i, j + 1)
        c, d = h.item(i + 1, j), h.item(i + 1, j + 1)
        z0, z1 = a + (b - a) * fu, c + (d - c) * fu
        return z0 + (z1 - z0) * fv, ((b - a) * (1.0 - fv) + (d - c) * fv) / sp, (z1 - z0) / sp

    def _cut(self, x: float, y: float, z: float) -> None:
        """Lower the corners of the grid cell under (x, y) to z where they are above it (the
        cell ``surface`` reads there)."""
        i, j, _, _ = self._cell(x, y)
        h = self._h
        for a, b in ((i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1)):
            if h.item(a, b) > z:
                h[a, b] = z

    @property
    def ground(self) -> np.ndarray:
        """The height grid the tyres stand on (a yielding ground's, as cut so far)."""
        return self._h

    def apply(self, client: int, robot: int, wheels: Sequence[int]) -> None:
        """Compute and apply this step's forces on the four wheel links (fl, fr, bl, br)."""
        # positional arguments: pybullet parses keywords on every call (≈ 2 µs a physics step)
        links = p.getLinkStates(robot, wheels, 1, 0, client)  # with velocities
        spins = p.getJointStates(robot, wheels, client)
        o = self.forces(links, spins)
        w0, w1, w2, w3 = wheels
        if o[0]:
            p.applyExternalForce(robot, w0, o[1:4], o[4:7], WORLD, client)
        if o[7]:
            p.applyExternalForce(robot, w1, o[8:11], o[11:14], WORLD, client)
        if o[14]:
            p.applyExternalForce(robot, w2, o[15:18], o[18:21], WORLD, client)
        if o[21]:
            p.applyExternalForce(robot, w3, o[22:25], o[25:28], WORLD, client)

    def forces(self, links: Sequence[Any], spins: Sequence[Any]) -> tuple[float, ...]:
        """This step's forces from pybullet's link states (``getLinkStates`` with velocities)
        and joint states of the wheels: per wheel (in contact 1 or 0, force xyz, world point
        xyz); updates the shear state and the normal forces."""
        if not self.native:
            return self._forces(links, spins)
        (a, b, c, d), (e, f, g, h) = links, spins  # the four wheels, unrolled
        _PACK_IN.pack_into(
            self._in, 0,
            *a[0], *a[5], *a[6], *a[7], e[1], *b[0], *b[5], *b[6], *b[7], f[1],
            *c[0], *c[5], *c[6], *c[7], g[1], *d[0], *d[5], *d[6], *d[7], h[1],
        )  # fmt: skip
        status = self._call(self._ref)
        if status:
            raise _native.failed("tyre_forces", status)
        return _UNPACK_OUT.unpack_from(self._outv, 0)

    def _point(self, c: Sequence[float], v: Sequence[float]) -> _Contact | None:
        """Normal force, unit normal and centre-to-contact vector of a point contact: the
        wheel as a sphere of its radius on the tangent plane under its centre."""
        r = self.radius
        h, hx, hy = self.surface(c[0], c[1])
        inv = 1.0 / math.sqrt(hx * hx + hy * hy + 1.0)
        nx, ny, nz = -hx * inv, -hy * inv, inv
        dist = (c[2] - h) * nz  # wheel centre to the local tangent plane
        n_force = self.kz * (r - dist) - self.cz * (v[0] * nx + v[1] * ny + v[2] * nz)
        if dist >= r or n_force <= 0.0:
            return None
        return n_force, nx, ny, nz, -dist * nx, -dist * ny, -dist * nz

    def _tread(
        self,
        c: Sequence[float],
        axle: tuple[float, float, float],
        v: Sequence[float],
        w: Sequence[float],
    ) -> _Contact | None:
        """The same for a cylindrical tread ``contact_width`` wide: ``slices`` discs across it,
        each a spring–damper of 1/slices of the stiffness and damping pressing along the
        surface normal under it (a Winkler foundation across the tread), summed into one force
        that acts on the line through their resultant: the normal force, its direction and the
        point that gives the slices' moment about the wheel centre (up to a couple about the
        force, which one force cannot carry), on the ground. On a yielding ground a disc bears
        at most the soil's bearing capacity on the slope under it (``sim.terramechanics``)."""
        r, n, width, bear = self.radius, self.slices, self.soil.contact_width, self.bearing
        ks, cs = self.kz / n, self.cz / n
        ax, ay, az = axle
        fx = fy = fz = mx = my = mz = gx = gy = gz = total = 0.0
        for k in range(n):
            off = width * ((k + 0.5) / n - 0.5)
            ox, oy, oz = off * ax, off * ay, off * az  # wheel centre -> the disc's centre
            h, hx, hy = self.surface(c[0] + ox, c[1] + oy)
            inv = 1.0 / math.sqrt(hx * hx + hy * hy + 1.0)
            nx, ny, nz = -hx * inv, -hy * inv, inv
            dist = (c[2] + oz - h) * nz  # the disc's centre to the tangent plane under it
            na = nx * ax + ny * ay + nz * az
            px, py, pz = nx - na * ax, ny - na * ay, nz - na * az  # the normal in the disc
            pl = math.sqrt(px * px + py * py + pz * pz)
            if pl < 1e-9:  # the disc lies flat on the ground: it has no lowest point
                continue
            depth = r * pl - dist  # the disc's lowest point below the plane
            if depth <= 0.0:
                continue
            # centre -> the disc's lowest point, then up the normal onto the ground
            lx = ox - r * px / pl + depth * nx
            ly = oy - r * py / pl + depth * ny
            lz = oz - r * pz / pl + depth * nz
            vx = v[0] + w[1] * lz - w[2] * ly
            vy = v[1] + w[2] * lx - w[0] * lz
            vz = v[2] + w[0] * ly - w[1] * lx
            spring = ks * depth
            if bear is not None:
                # the slope the soil stands at: the field's, or a cut bench's where flatter (a
                # rut's wall stands at the field's: cohesion holds a cut far deeper than a rut)
                _, fx0, fy0 = self.surface(c[0] + ox, c[1] + oy, self._h0)
                tan_b = min(math.sqrt(hx * hx + hy * hy), math.sqrt(fx0 * fx0 + fy0 * fy0))
                cap = bear.limit(tan_b)
                if spring > cap:
                    # the soil flows: the ground under the disc is cut down to where it holds
                    # the disc at its capacity (the elastic part of the sinkage, cap/k, stays)
                    spring = cap
                    self._cut(
                        c[0] + lx - depth * nx,
                        c[1] + ly - depth * ny,
                        c[2] + lz - depth * nz + cap / ks,
                    )
            f = spring - cs * (vx * nx + vy * ny + vz * nz)
            if f <= 0.0:
                continue
            ex, ey, ez = f * nx, f * ny, f * nz  # this disc's force
            fx, fy, fz = fx + ex, fy + ey, fz + ez
            mx, my, mz = (
                mx + (ly * ez - lz * ey),
                my + (lz * ex - lx * ez),
                mz + (lx * ey - ly * ex),
            )
            gx, gy, gz, total = gx + f * lx, gy + f * ly, gz + f * lz, total + f
        n_force = math.sqrt(fx * fx + fy * fy + fz * fz)
        if n_force <= 0.0:
            return None
        nx, ny, nz = fx / n_force, fy / n_force, fz / n_force
        # the resultant's line nearest the centre (F × M / |F|²), then along it to the slices'
        # load-weighted depth
        n2 = n_force * n_force
        depth = (gx * nx + gy * ny + gz * nz) / total
        rx = (fy * mz - fz * my) / n2 + depth * nx
        ry = (fz * mx - fx * mz) / n2 + depth * ny
        rz = (fx * my - fy * mx) / n2 + depth * nz
        return n_force, nx, ny, nz, rx, ry, rz

    def _forces(self, links: Sequence[Any], spins: Sequence[Any]) -> tuple[float, ...]:
        """The Python twin of the kernel (and the model's reference)."""
        s = self.soil
        dt, r, big_k, length = self.dt, self.radius, s.shear_modulus, s.contact_length
        out: list[float] = []
        for i, link in enumerate(links):
            c, q, v, w = link[0], link[5], link[6], link[7]
            qx, qy, qz, qw = q  # the axle: the wheel frame's y axis
            ax, ay, az = (
                2 * (qx * qy - qw * qz),
                1 - 2 * (qx * qx + qz * qz),
                2 * (qy * qz + qw * qx),
            )
            if self.slices:
                contact = self._tread(c, (ax, ay, az), v, w)
            else:
                contact = self._point(c, v)
            if contact is None:  # airborne: the patch's shear is gone
                self.shear[i] = 0.0
                self.normal[i] = 0.0
                out += (0.0,) * 7
                continue
            n_force, nx, ny, nz, rx, ry, rz = contact
            self.normal[i] = n_force
            # velocity of the tyre material at the contact point, tangential part = slip
            vx = v[0] + w[1] * rz - w[2] * ry
            vy = v[1] + w[2] * rx - w[0] * rz
            vz = v[2] + w[0] * ry - w[1] * rx
            vn = vx * nx + vy * ny + vz * nz
            sx, sy, sz = vx - vn * nx, vy - vn * ny, vz - vn * nz
            jx, jy, jz = self.shear[i].tolist()
            u = abs(spins[i][1]) * r  # tread speed through the patch
            if u > 1e-6:  # exact step of dj/dt = s − (u/l) j
                decay = math.exp(-u * dt / length)
                gain = length / u * (1.0 - decay)
                kx, ky, kz = jx * decay + sx * gain, jy * decay + sy * gain, jz * decay + sz * gain
            else:
                kx, ky, kz = jx + sx * dt, jy + sy * dt, jz + sz * dt
            kn = kx * nx + ky * ny + kz * nz
            kx, ky, kz = kx - kn * nx, ky - kn * ny, kz - kn * nz
            mag = math.sqrt(kx * kx + ky * ky + kz * kz)
            if mag > SHEAR_CAP * big_k:
                f = SHEAR_CAP * big_k / mag
                kx, ky, kz, mag = kx * f, ky * f, kz * f, SHEAR_CAP * big_k
            tmax = s.friction * n_force
            elastic = tmax * (1.0 - math.exp(-mag / big_k)) / mag if mag > 0.0 else 0.0
            # soil viscosity on the deflection rate: damps the stiction spring at rest, zero in
            # steady rolling (dj/dt = 0 there)
            damp = tmax / big_k * s.shear_damping / dt
            fx = -elastic * kx - damp * (kx - jx)
            fy = -elastic * ky - damp * (ky - jy)
            fz = -elastic * kz - damp * (kz - jz)
            ft = math.sqrt(fx * fx + fy * fy + fz * fz)
            if ft > tmax:
                f = tmax / ft
                fx, fy, fz = fx * f, fy * f, fz * f
            self.shear[i] = (kx, ky, kz)
            # rolling direction = axle × normal
            ex, ey, ez = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
            en = math.sqrt(ex * ex + ey * ey + ez * ez)
            travel = (v[0] * ex + v[1] * ey + v[2] * ez) / en
            rr = -s.rolling_resistance * n_force * max(-1.0, min(1.0, travel / RR_SPEED)) / en
            out += (
                1.0,
                fx + rr * ex + n_force * nx,
                fy + rr * ey + n_force * ny,
                fz + rr * ez + n_force * nz,
                c[0] + rx,
                c[1] + ry,
                c[2] + rz,
            )
        return tuple(out)


def in_place_turn_ratio(soil: SoilConfig, wheelbase: float, track: float) -> float:
    """True yaw rate / kinematic yaw rate ``(v_r − v_l)/track`` of a steady in-place turn.

    Moment balance of four wheels at (±a, ±b) whose treads run at ±U while the body turns at
    Ω = k·U/b: each patch slips by U·(k − 1, ±k·a/b), its shear is ``l·n`` (n the slip's
    length over U), its force ``μN (1 − e^(−l n/K))`` against the slip, and the rolling
    resistance ``c_rr N`` opposes each wheel's travel. The yaw moment vanishes where

        (1 − e^(−l n/K)) · ((1 − k) − (a/b)² k) / n = c_rr / μ.

    With no resistance and saturated shear, k = 1/(1 + (a/b)²): the rigid-Coulomb limit that
    depends on the wheelbase/track ratio alone. The skid-steer "effective track" χ = 1/k.
    """
    a, b = 0.5 * wheelbase, 0.5 * track
    ab2 = (a / b) ** 2
    target = soil.rolling_resistance / soil.friction
    lk = soil.contact_length / soil.shear_modulus

    def moment(k: float) -> float:
        n = math.hypot(k - 1.0, k * a / b)
        return (1.0 - math.exp(-lk * n)) * ((1.0 - k) - ab2 * k) / n - target

    lo, hi = 1e-6, 1.0 / (1.0 + ab2)
    if moment(lo) <= 0.0:  # resistance beats every shear: the robot cannot turn in place
        return lo
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if moment(mid) > 0.0 else (lo, mid)
    return 0.5 * (lo + hi)
