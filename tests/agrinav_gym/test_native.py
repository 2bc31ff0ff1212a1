"""The compiled sensor kernels against their references: the rasterised mesh-camera frame
against Embree's ray casts, the proxy kernel against the numpy marches, both cameras' whole
frames with and without the kernels, and the build and its boundary (struct layout, field
checks, statuses)."""

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from agrinav_gym.config import EnvConfig
from agrinav_gym.render import native, pixel_noise, raster_view
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.render.proxy_plants import PlantField
from agrinav_gym.robot import RobotGeometry, robot_interface
from agrinav_gym.sensors.mesh_camera import MeshCamera
from scenario_gen import generate, preset

from .helpers import TINY, lane_pose, make_camera, mesh_camera
from .oracles import ground_hits, plant_hits

needs_kernels = pytest.mark.skipif(not native.available(), reason="compiled kernels not built")
#: Embree intersects in float32 around the field's centre (~1 µm), which a ray grazing a
#: surface stretches along itself by up to ~100x: how far the two renderers' depths may part
EMBREE_DEPTH = 1e-4


@pytest.fixture(scope="module")
def maize() -> MeshScene:
    """Tall maize (2.5 m) in 1 m rows: leaves hang into the lane and hide each other. The
    scene keeps its scenario as ``scene.scenario``."""
    over = {**TINY, "crop": {"stage": 5}, "layout": {"row_spacing": 1.0, "headland": 2.0}}
    scn = generate(preset("ridged", **over), 0)  # micro-relief: the harder geometry
    scene = MeshScene.from_scenario(scn)
    scene.scenario = scn  # type: ignore[attr-defined]
    return scene


def maize_scenario(scene: MeshScene):  # type: ignore[no-untyped-def]
    return scene.scenario  # type: ignore[attr-defined]


def test_compiled_kernels_are_built_in_ci() -> None:
    """CI installs a compiler: there the fast paths must be the ones under test."""
    if os.environ.get("CI", "").lower() in ("", "0", "false"):
        pytest.skip("outside CI the extension is optional")
    assert native.available(), "agrinav_gym._native did not build (see pip's build log)"


def test_a_build_from_other_sources_is_refused(tmp_path: Path) -> None:
    """An extension left from other sources (an edit or a pull without a rebuild) would be
    called with the wrong arguments and draw wrong images without an error: it is refused."""
    csrc = Path(native.__file__).resolve().parent / "csrc"
    here = native.source_hash(csrc)

    class Build:
        def __init__(self, built: bytes) -> None:
            self.agrinav_source_hash = lambda: built

    assert native.stale(Build(here.encode())) is None
    assert "built from sources 0000" in str(native.stale(Build(b"0000")))
    assert "predates" in str(native.stale(object()))
    (tmp_path / "a.c").write_text("int f(void) { return 1; }\n")
    before = native.source_hash(tmp_path)
    (tmp_path / "a.c").write_text("int f(void) { return 2; }\n")
    assert native.source_hash(tmp_path) != before
    if native.available():  # the build under test is this tree's
        assert native.stale(native.lib()) is None


@needs_kernels
def test_the_structs_are_laid_out_as_the_compiler_lays_them_out() -> None:
    """Every struct of native.h has the size and field offsets native.py declares (a build
    that differs is refused when loaded), and every declared kernel is exported."""
    handle = native.lib()
    assert native.layout_mismatches(handle) == []
    assert {s.c for s in native.STRUCTS} >= {f"{k}_args_t" for k in native.KERNELS}
    for name in native.KERNELS:
        assert hasattr(handle, name), name


def test_a_struct_takes_every_field_by_name_and_checks_it() -> None:
    """Fields are named, all of them given; arrays must have the field's dtype and be
    C-contiguous (or None: NULL); blocks the field's type; ints their C type's range."""
    out = np.zeros(4)
    ok = {"tables": np.zeros(3), "key": 1, "i0": 0, "i1": 4, "out": out}
    native.PixelNormalsArgs(**ok)
    with pytest.raises(TypeError, match="no value for i1"):
        native.PixelNormalsArgs(**{k: v for k, v in ok.items() if k != "i1"})
    with pytest.raises(AttributeError, match="no field 'n'"):
        native.PixelNormalsArgs(**ok, n=4)
    with pytest.raises(TypeError, match=r"PixelNormalsArgs.out: an array of float64, not float32"):
        native.PixelNormalsArgs(**{**ok, "out": out.astype(np.float32)})
    with pytest.raises(TypeError, match="an array of float64, not list"):
        native.PixelNormalsArgs(**{**ok, "out": [0.0] * 4})
    with pytest.raises(ValueError, match="not C-contiguous"):
        native.PixelNormalsArgs(**{**ok, "out": np.zeros(8)[::2]})
    with pytest.raises(OverflowError, match="i1: 2147483648"):
        native.PixelNormalsArgs(**{**ok, "i1": 2**31})
    with pytest.raises(TypeError, match="cam: a Camera, not Geometry"):
        geom = native.grid_geometry(np.zeros((2, 2)), 0.0, 0.0, 1.0)
        native.RasterViewArgs(
            cam=geom, geom=geom, terrain=1, hiz=1, iz=None, inst=None, prim=None, row0=0, row1=0
        )
    with pytest.raises(ValueError, match="origin: 3 values"):
        native.RefineRaysArgs(geom=None, n=0, origin=(0.0, 0.0), dirs=None, t=None, ground=None)


def _sky_view(soil_n: int, w: int = 4, h: int = 2) -> tuple[native.ShadeViewArgs, np.ndarray]:
    """shade_view's arguments for a view of nothing but sky, with a soil texture soil_n wide,
    and the image they shade."""
    n = w * h
    cam = native.Camera(
        origin=(0, 0, 1), rot=np.eye(3).ravel(), fx=2.0, fy=2.0, cx=(w - 1) / 2,
        cy=(h - 1) / 2, znear=1e-3, zfar=10.0, width=w, height=h,
    )  # fmt: skip
    materials = native.Materials(
        face_offset=np.zeros(1, np.int64), face_rgb=np.zeros((1, 3), np.uint8),
        face_normal=np.zeros((1, 3), np.float32), tex_image=np.zeros(1, np.int64),
        tex_uv=np.zeros(1, np.int64), tex_hw=np.zeros(2, np.int32),
        soil=np.ones((8, 8), np.float32), soil_n=soil_n,
    )  # fmt: skip
    light = native.Shading(
        soil_rgb=(0.4, 0.3, 0.2), light=(0, 0, 1), sky_horizon=(0.8, 0.8, 0.9),
        sky_zenith=(0.3, 0.4, 0.8), ambient=0.35, far=10.0, origin=(0, 0), texel=0.01,
    )  # fmt: skip
    none = np.full(n, -1, np.int32)
    rgb = np.zeros((n, 3), np.uint8)
    args = native.ShadeViewArgs(
        cam=cam, geom=native.grid_geometry(np.zeros((2, 2)), -1.0, -1.0, 2.0),
        materials=materials, shading=light, forward=np.ones(n), t=np.full(n, np.inf),
        label=np.zeros(n, np.uint8), vis_inst=none, proto=none, prim=none, robot_rot=None,
        robot_rgb=None, robot_normal=None, rgb=rgb, row0=0, row1=h,
    )  # fmt: skip
    return args, rgb


@needs_kernels
def test_a_kernel_that_refuses_its_arguments_raises_an_error_naming_it(maize: MeshScene) -> None:
    """A status other than 0 is an error naming the kernel and the status, not an image left
    unwritten: shade_view with a soil texture that is no power of two (it used to return
    without a word), a band of rows past the image, a camera without a focal length."""
    good, rgb = _sky_view(8)
    native.call(good)
    assert rgb.all()  # the sky, shaded
    bad, rgb = _sky_view(6)
    with pytest.raises(
        native.KernelError, match=r"kernel shade_view failed with status 2: a count, size"
    ) as e:
        native.call(bad)
    assert e.value.kernel == "shade_view" and e.value.status == 2
    assert not rgb.any()
    geo = raster_view.SceneGeometry(maize)
    cam = mesh_camera(64, 48, "raster")
    rot, pos = lane_pose(maize_scenario(maize))
    c = raster_view.camera_params(cam.model, rot, pos, maize.origin, 6.05)
    vis = raster_view.new_vis(64 * 48)
    geo.draw(c, vis, 0, 48)
    with pytest.raises(native.KernelError, match="kernel raster_view failed with status 2"):
        geo.draw(c, vis, 0, 49)
    c.set(fx=0.0)
    with pytest.raises(
        native.KernelError, match="raster_view failed with status 5: an invalid camera"
    ):
        geo.draw(c, vis, 0, 48)
    with pytest.raises(native.KernelError, match="pixel_normals failed with status 2"):
        native.call(native.PixelNormalsArgs(tables=np.zeros(3), key=1, i0=2, i1=1, out=np.zeros(1)))


def test_raster_without_kernels_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AGRINAV_NATIVE", "0")
    with pytest.raises(native.NativeUnavailable, match=r"camera.renderer='raster'.*AGRINAV_NATIVE"):
        mesh_camera(64, 48, "raster")
    assert not mesh_camera(848, 480, "auto").rasterises  # auto falls back to the rays


@needs_kernels
def test_auto_rasterises_only_large_frames() -> None:
    assert mesh_camera(848, 480, "auto").rasterises
    assert not mesh_camera(64, 48, "auto").rasterises
    assert not mesh_camera(848, 480, "raycast").rasterises


@needs_kernels
def test_raster_frame_is_the_ray_cast_frame(maize: MeshScene) -> None:
    """The same geometry: where both renderers see the same surface, the same depth to Embree's
    precision; the same plant in every pixel but ties at shared edges (where float32 rays and
    double scan conversion may pick the neighbouring triangle); the same colours but rounding."""
    rot, pos = lane_pose(maize_scenario(maize))
    r = mesh_camera(848, 480, "raster").draw(
        rot, pos, maize, None, rgb=True, labels=True, stereo=False
    )
    e = mesh_camera(848, 480, "raycast").draw(
        rot, pos, maize, None, rgb=True, labels=True, stereo=False
    )
    n = r.depth.size
    assert (r.instance >= 0).mean() > 0.3  # a canopy, not an empty lane
    ties = (r.instance != e.instance) | (r.label != e.label)
    assert ties.sum() <= 1e-4 * n and ((r.depth > 0) != (e.depth > 0)).sum() <= 1e-4 * n
    same = (r.depth > 0) & (e.depth > 0) & ~ties
    assert same.mean() > 0.5
    assert np.abs(r.depth[same] - e.depth[same]).max() < EMBREE_DEPTH
    colour_ties = (r.rgb_instance != e.rgb_instance) | (r.rgb_label != e.rgb_label)
    assert colour_ties.sum() <= 1e-4 * n
    diff = np.abs(r.rgb.astype(int) - e.rgb.astype(int)).max(axis=2)[~colour_ties]
    # float32 normals and rounding: a level or two; a hit on a texel's edge may take the next
    assert (diff > 2).mean() < 1e-4


@needs_kernels
def test_stereo_shadow_misses_only_what_the_right_view_cannot_show(maize: MeshScene) -> None:
    """The rasterised stereo test decides each candidate on the triangles the right imager's
    own view shows around the point's image (and those sharing an edge with them). So it may
    keep a pixel the exact ray finds hidden only when that ray's occluder is none of them — an
    occluder narrower than a pixel there; and it never hides a pixel the exact ray sees."""
    scn = maize_scenario(maize)
    rot, pos = lane_pose(scn)
    cam = mesh_camera(848, 480, "raster")
    r = cam.draw(rot, pos, maize, None, labels=True)
    e = mesh_camera(848, 480, "raycast").draw(rot, pos, maize, None, labels=True)
    geo = cam.draw(rot, pos, maize, None, labels=True, stereo=False)
    occluded = (geo.depth > 0) & (e.depth == 0)
    assert occluded.mean() > 0.05  # a frame with a real shadow
    # Hidden here but seen by the exact ray: only where its float32 segment grazes an
    # occluder's silhouette, i.e. at the edge of a shadow both paths find.
    extra = (r.depth == 0) & (e.depth > 0) & (geo.depth > 0)
    both = np.pad((r.depth == 0) & (e.depth == 0) & (geo.depth > 0), 1)
    beside = np.zeros_like(extra)
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            beside |= both[1 + dv : 1 + dv + 480, 1 + du : 1 + du + 848]
    assert not (extra & ~beside).any()
    missed = np.flatnonzero(((r.depth > 0) & (e.depth == 0)).ravel())
    assert len(missed) <= 0.01 * occluded.sum()  # a guard: a few tenths of a per cent here
    # what the exact rays hit for the missed pixels
    o, d = cam.rays.world(rot, pos)
    rw = cam.right_world(rot, pos)
    z = geo.depth.ravel()[missed].astype(float)
    seg = o + d[missed] * (z / cam.rays.forward[missed])[:, None] - rw
    maize.view(cam._view_points(rot, pos, False))
    hit = maize.caster.intersect(
        maize.top, (rw - maize.origin).astype(np.float32), seg.astype(np.float32), 0.0, 1.0
    )
    geo_r = cam._geometry[1]
    right = raster_view.new_vis(848 * 480)
    cr = raster_view.camera_params(cam.model, rot, pos, maize.origin, 6.05, cam.cfg.baseline)
    geo_r.draw(cr, right, 0, 480)
    adj = {
        k: raster_view.face_adjacency(p.vertices, p.faces)
        for k, p in enumerate(maize.plants.prototypes)
    }
    for m, k in enumerate(missed):
        plant = int(hit.inst[m])
        if not (0 <= plant < len(maize.plants)):
            continue  # the terrain: its cells are tested through the grid's adjacency
        v, u = divmod(int(k), 848)
        ur = u - cam.fx * cam.cfg.baseline / z[m]
        cols = [c for c in range(math.floor(ur) - 1, math.floor(ur) + 3) if 0 <= c < 848]
        slots = right.inst[v * 848 + np.array(cols)]
        prims = right.prim[v * 848 + np.array(cols)]
        shown = set()
        for s, p in zip(slots, prims, strict=True):
            if s >= 0 and int(geo_r.slot_plant[s]) == plant:
                proto = int(maize.plants.proto[plant])
                shown |= {int(p), *(int(a) for a in adj[proto][p] if a >= 0)}
        assert int(hit.prim[m]) not in shown


@needs_kernels
def test_two_threads_draw_the_same_frame(maize: MeshScene) -> None:
    """The bands of rows are disjoint and each pixel depends only on the frame: the split
    between threads (which moves from frame to frame) changes nothing, noise included."""
    rot, pos = lane_pose(maize_scenario(maize), turn=0.3)
    one, two = mesh_camera(424, 240, "raster", 1), mesh_camera(424, 240, "raster", 2)
    for k in range(3):  # the split adapts between frames
        a = one.draw(rot, pos, maize, np.random.default_rng(k), rgb=True, labels=True)
        b = two.draw(rot, pos, maize, np.random.default_rng(k), rgb=True, labels=True)
        for f in ("depth", "label", "instance", "rgb", "rgb_label", "rgb_instance"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f


@needs_kernels
def test_vector_and_scalar_kernels_draw_the_same_frame(
    maize: MeshScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The batched loops (soil and plant colour, the terrain's Newton step) run as AVX2 where
    the CPU has it and as the baseline build otherwise; with contraction off both round every
    operation alike, so the frames are bit-identical (on a CPU without AVX2 both runs take the
    baseline and the test holds trivially)."""
    rot, pos = lane_pose(maize_scenario(maize), turn=0.2)
    cam = mesh_camera(424, 240, "raster", 1)
    frames = []
    for flag in ("1", "0"):
        monkeypatch.setenv("AGRINAV_AVX2", flag)
        frames.append(cam.draw(rot, pos, maize, np.random.default_rng(3), rgb=True, labels=True))
    for f in ("depth", "label", "instance", "rgb", "rgb_label", "rgb_instance"):
        assert np.array_equal(getattr(frames[0], f), getattr(frames[1], f)), f
    assert (frames[0].label == 1).mean() > 0.05 and (frames[0].instance >= 0).mean() > 0.05


@needs_kernels
def test_raster_noise_is_the_ray_cast_noise(maize: MeshScene) -> None:
    """Both paths take one key from the rng and the same draw per pixel from it (pixel_noise):
    the noise each adds, divided by its σ = z²·s/(f·B), is the same number in every pixel (to
    the float32 rounding of the depths, < 1e-3 σ from 0.4 to 6 m)."""
    rot, pos = lane_pose(maize_scenario(maize))
    cams = {k: mesh_camera(424, 240, k) for k in ("raster", "raycast")}
    draws = {}
    for k, cam in cams.items():
        noisy = cam.draw(rot, pos, maize, np.random.default_rng(7), stereo=False).depth
        clean = cam.draw(rot, pos, maize, None, stereo=False).depth
        ok = (noisy > 0) & (clean > 0)
        z = np.where(ok, clean, 1.0).astype(float)  # σ of the valid pixels only
        draws[k] = (np.where(ok, (noisy - z) / cam.noise_sigma(z), np.nan), ok)
    (nr, okr), (ne, oke) = draws["raster"], draws["raycast"]
    both = okr & oke
    assert both.mean() > 0.5 and np.nanstd(nr) == pytest.approx(1.0, abs=0.05)
    assert np.abs(nr[both] - ne[both]).max() < 1e-3


FRAME = ("depth", "label", "instance", "rgb", "rgb_label", "rgb_instance")


def depth_tolerance(cam: Any, seed: int, z: np.ndarray) -> np.ndarray:
    """How far two noisy depth images may part per pixel where their ray lengths part by up to
    EMBREE_DEPTH: the noise σ(z)·n = k·z²·n (the same draw n in both: pixel_noise) follows z
    by 2·k·z·|n| times that, and float32 rounds each image (< 1e-6 m within 8 m)."""
    key = pixel_noise.frame_key(np.random.default_rng(seed))
    n = pixel_noise.normals(key, z.size).reshape(z.shape)
    zz = np.where(z > 0, z, 1.0)
    return EMBREE_DEPTH * (1 + 2 * cam.noise_sigma(zz) / zz * np.abs(n)) + 1e-6


def with_and_without_kernels(monkeypatch: pytest.MonkeyPatch, draw: Any) -> tuple[Any, Any]:
    """``draw()`` (a fresh camera each time: cameras keep per-path state) through the compiled
    kernels, then through the numpy/Embree fallback (AGRINAV_NATIVE=0)."""
    monkeypatch.delenv("AGRINAV_NATIVE", raising=False)
    compiled = draw()
    monkeypatch.setenv("AGRINAV_NATIVE", "0")
    fallback = draw()
    monkeypatch.delenv("AGRINAV_NATIVE")
    return compiled, fallback


@needs_kernels
@pytest.mark.parametrize("turn", [0.0, 0.6, -1.2])
def test_the_proxy_camera_draws_the_same_frame_without_the_kernels(
    turn: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The proxy camera end to end, compiled (proxycast.c's exact double-precision cast, noise
    and validity in finish_depth) and without the kernels (Embree's float32 cast refined onto
    the terrain by numpy's Newton steps, numpy noise): the same scene, pose and noise seed.
    The noise draws are the same bits (pixel_noise), so depths part only by the casts'
    precision, EMBREE_DEPTH, and the noise's dependence on depth (``depth_tolerance``). A pixel
    may change class or validity only at a tie — a silhouette edge, or a depth within that
    precision of a range limit. RGB: sky and plant colours depend on the class and the ray
    alone (equal); the soil's on the hit point's normal, which moving the point by 1e-4 m
    changes by far less than one level: at most a rounding step."""
    scn = generate(preset("ridged", **TINY, crop={"stage": 4}), 0)
    plants = PlantField.from_scenario(scn)
    rot, pos = lane_pose(scn, 30, turn)
    cam = make_camera(None, {"width": 160, "height": 120})

    def draw() -> Any:
        fresh = make_camera(None, {"width": 160, "height": 120})
        rng = np.random.default_rng(8)
        return fresh.draw(rot, pos, scn.terrain, plants, rng, rgb=True, labels=True)

    a, b = with_and_without_kernels(monkeypatch, draw)
    cfg = cam.cfg
    ties = a.label != b.label
    assert ties.sum() <= 1e-3 * ties.size
    assert (a.label == 1).mean() > 0.1 and (a.label >= 2).mean() > 0.05  # soil and plants
    va, vb = a.depth > 0, b.depth > 0
    z = np.maximum(a.depth, b.depth).astype(float)
    at_limit = (np.abs(z - cfg.min_range) < EMBREE_DEPTH) | (
        np.abs(z - cfg.max_range) < EMBREE_DEPTH
    )
    assert not ((va != vb) & ~ties & ~at_limit).any()
    both = va & vb & ~ties
    assert both.mean() > 0.5
    gap = np.abs(a.depth.astype(float) - b.depth)
    assert (gap <= depth_tolerance(cam, 8, z))[both].all()
    diff = np.abs(a.rgb.astype(int) - b.rgb.astype(int)).max(axis=2)
    soil = a.label == 1
    assert (diff[~ties & ~soil] == 0).all() and (diff[~ties & soil] <= 1).all()


@needs_kernels
@pytest.mark.parametrize("turn", [0.0, 0.3])
def test_the_mesh_camera_draws_the_same_small_frame_without_the_kernels(
    turn: float, maize: MeshScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Small frames go through Embree's rays either way; the kernels only take over its packet
    loop (packets.c), the terrain's Newton steps (refine_rays: refine_ground step for step)
    and the noise's draws (the same bits): the frame, noise, stereo pair and colour included,
    is bit-identical."""
    rot, pos = lane_pose(maize_scenario(maize), turn=turn)

    def draw() -> Any:
        cam = mesh_camera(64, 48, "auto")
        return cam.draw(rot, pos, maize, np.random.default_rng(3), rgb=True, labels=True)

    a, b = with_and_without_kernels(monkeypatch, draw)
    assert (a.instance >= 0).mean() > 0.3 and (a.depth > 0).mean() > 0.1
    for f in FRAME:
        assert np.array_equal(getattr(a, f), getattr(b, f)), f


@needs_kernels
def test_the_mesh_camera_draws_the_same_large_frame_without_the_kernels(
    maize: MeshScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A large frame is rasterised where the kernels are built (auto) and cast ray by ray by
    Embree and numpy without them: the same frame to the precision the two renderers share
    (test_raster_frame_is_the_ray_cast_frame), here with the noise and the stereo pair. Depth
    within ``depth_tolerance`` where both see the same surface (the same noise draw per pixel);
    the same plant in every pixel but ties at shared edges; validity differing in at most
    1e-3 of the pixels: ties, and the stereo shadow of occluders narrower than a pixel in the
    rasterised right view (the rasteriser's stereo test can miss those, docs/camera.md);
    colours within two levels (float32 normals, rounding)."""
    rot, pos = lane_pose(maize_scenario(maize), turn=0.3)
    cam = mesh_camera(424, 240, "auto")

    def draw() -> Any:
        fresh = mesh_camera(424, 240, "auto")
        assert fresh.rasterises == native.available()
        return fresh.draw(rot, pos, maize, np.random.default_rng(3), rgb=True, labels=True)

    a, b = with_and_without_kernels(monkeypatch, draw)
    n = a.depth.size
    assert (a.instance >= 0).mean() > 0.3
    ties = (a.instance != b.instance) | (a.label != b.label)
    assert ties.sum() <= 1e-4 * n
    assert ((a.depth > 0) != (b.depth > 0)).sum() <= 1e-3 * n
    same = (a.depth > 0) & (b.depth > 0) & ~ties
    assert same.mean() > 0.1
    gap = np.abs(a.depth.astype(float) - b.depth)
    assert (gap <= depth_tolerance(cam, 3, np.maximum(a.depth, b.depth)))[same].all()
    colour_ties = (a.rgb_instance != b.rgb_instance) | (a.rgb_label != b.rgb_label)
    assert colour_ties.sum() <= 1e-4 * n
    diff = np.abs(a.rgb.astype(int) - b.rgb.astype(int)).max(axis=2)[~colour_ties]
    assert (diff > 2).mean() < 1e-4


@needs_kernels
def test_the_robot_in_its_own_camera_is_the_same_on_both_renderers(maize: MeshScene) -> None:
    """A camera on a short mast behind base_link, pitched down, sees the chassis: its pixels
    (class 4, constant per mount) merge into the rasterised frame as into the ray-cast one."""
    cfg = EnvConfig.from_dict(
        {
            "robot": {"camera_x": -0.4, "camera_height": 0.5, "camera_pitch_deg": 40.0},
            "camera": {"width": 424, "height": 240},
        }
    )
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    rot, pos = lane_pose(maize_scenario(maize))
    frames = {}
    for renderer in ("raster", "raycast"):
        c = EnvConfig.from_dict(
            {**cfg.to_dict(), "camera": {**cfg.to_dict()["camera"], "renderer": renderer}}
        )
        cam = MeshCamera(c.camera, model)
        frames[renderer] = cam.draw(rot, pos, maize, None, rgb=True, labels=True, stereo=False)
    r, e = frames["raster"], frames["raycast"]
    robot = e.label == 4
    assert 0.05 < robot.mean() < 0.9 and (e.rgb_label == 4).mean() > 0.05
    assert np.array_equal(r.label == 4, robot) and np.array_equal(
        r.rgb_label == 4, e.rgb_label == 4
    )
    near = (r.depth > 0) & (e.depth > 0) & (r.instance == e.instance) & (r.label == e.label)
    assert np.abs(r.depth[near] - e.depth[near]).max() < EMBREE_DEPTH
    diff = np.abs(r.rgb.astype(int) - e.rgb.astype(int)).max(axis=2)
    assert (diff[e.rgb_label == 4] <= 2).all()  # the chassis shaded alike


def test_face_adjacency_joins_faces_across_shared_edges() -> None:
    """A quad split in two, its diagonal's vertices repeated (a texture seam), and a third
    triangle on one outer edge: faces meet across edges by position, not by vertex index."""
    v = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0], [1, 1, 0], [2, 0, 0]], np.float32
    )
    f = np.array([[0, 1, 2], [4, 5, 3], [1, 6, 2]], np.uint32)
    adj = raster_view.face_adjacency(v, f)
    assert adj.tolist() == [[-1, 2, 1], [0, -1, -1], [-1, -1, 0]]


def test_cluster_spheres_hold_their_faces(maize: MeshScene) -> None:
    """Each run of faces lies inside its sphere, as float32 stores it (the rasteriser skips a
    run whose sphere is out of view: a vertex outside would be a hole in the image)."""
    assert maize.plants is not None
    for proto in maize.plants.prototypes:
        v = np.asarray(proto.vertices, np.float32)
        f = np.asarray(proto.faces, np.int64)
        for size in (1, 7, raster_view.CLUSTER_FACES):
            cs = raster_view.cluster_spheres(v, f, size)
            assert cs.dtype == np.float32 and len(cs) == -(-len(f) // size)
            run = np.arange(len(f)) // size
            reach = np.linalg.norm(
                v[f].astype(np.float64) - cs[run, None, :3].astype(np.float64), axis=2
            )
            assert (reach <= cs[run, 3:4].astype(np.float64)).all()
            if size == 1:  # a triangle's sphere is no larger than the triangle
                assert (cs[:, 3] <= np.ptp(v[f], axis=1).max(axis=1) + 1e-5).all()


def test_face_adjacency_of_a_closed_mesh_is_complete() -> None:
    box = trimesh.creation.box()
    adj = raster_view.face_adjacency(np.asarray(box.vertices, np.float32), box.faces)
    assert (adj >= 0).all()
    for i, row in enumerate(adj):  # symmetric
        for j in row:
            assert i in adj[j]


@needs_kernels
@pytest.mark.parametrize("turn", [0.0, 0.6, -1.2])
def test_proxy_kernel_hits_the_first_surface_exactly(
    turn: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a furrowed field of maize proxies, looking along and across the rows: every hit of
    the compiled proxy lies on the bilinear terrain or on its cylinder (to rounding), and it is
    the first: the numpy references (``ground_hits``'s march, ``plant_hits``'s azimuth
    intervals) and the Embree path find a hit on the same rays, of the same class, and Embree
    at the same distance to its float32 precision. The camera stands in the lane under leaf
    bands whose discs reach over it: from below, their undersides are seen."""
    from agrinav_gym.sensors.depth import ProxyGeometry

    scn = generate(preset("ridged", **TINY, crop={"stage": 4}), 0)
    plants = PlantField.from_scenario(scn)
    cam = make_camera(None, {"width": 64, "height": 48})
    rot, pos = lane_pose(scn, 30, turn)
    o, rays = cam.pose(rot, pos)
    g = ProxyGeometry(scn.terrain, plants)
    t, what = g.cast_raw(o, rays, cam.t_lim)
    lab = g.labels(what)
    p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * rays
    ground = what == -1
    assert ground.mean() > 0.05 and (what >= 0).mean() > 0.05
    assert np.abs(p[ground, 2] - scn.terrain.height_at(p[ground, 0], p[ground, 1])).max() < 1e-9
    k = what[what >= 0]
    q = p[what >= 0]
    off = np.hypot(q[:, 0] - plants.xy[k, 0], q[:, 1] - plants.xy[k, 1])
    side = np.abs(off - plants.radius[k]) < 1e-9
    cap = (np.abs(q[:, 2] - plants.top[k]) < 1e-9) | (np.abs(q[:, 2] - plants.z[k]) < 1e-9)
    assert (side & (q[:, 2] >= plants.z[k] - 1e-9) & (q[:, 2] <= plants.top[k] + 1e-9) | cap).all()
    assert (off <= plants.radius[k] + 1e-9).all()
    # the references: the march extends the grid's edge heights beyond it and plant_hits has
    # no far limit (callers cut both): compare within the grid and the range
    tg = ground_hits(o, rays, scn.terrain, cam.t_lim)
    tp, _ = plant_hits(o, rays, plants, cam.t_lim)
    ref = np.minimum(tg, tp)
    ref = np.where(ref <= cam.t_lim, ref, np.inf)
    r = o + np.where(np.isfinite(ref), ref, 0.0)[:, None] * rays
    x0, y0, x1, y1 = scn.terrain.bounds
    inside = ~np.isfinite(ref) | (
        (r[:, 0] >= x0) & (r[:, 0] <= x1) & (r[:, 1] >= y0) & (r[:, 1] <= y1)
    )
    assert inside.mean() > 0.9
    assert np.array_equal(np.isfinite(t)[inside], np.isfinite(ref)[inside])
    assert np.array_equal(
        (tp < tg)[inside & np.isfinite(ref)], (what >= 0)[inside & np.isfinite(ref)]
    )
    monkeypatch.setenv("AGRINAV_NATIVE", "0")
    te, le = cam.cast(o, rays, scn.terrain, plants, cam.t_lim)
    assert np.array_equal(le, lab) and np.array_equal(np.isfinite(te), np.isfinite(t))
    fin = np.isfinite(t)
    assert np.abs(te[fin] - t[fin]).max() < EMBREE_DEPTH


@needs_kernels
def test_the_rasterised_chase_view_is_the_ray_cast_one(maize: MeshScene) -> None:
    """The video's frame drawn by the rasteriser (with the robot cast into it in its true,
    tilted pose) against every pixel ray-cast: the same picture to a few stray edge pixels."""
    from agrinav_gym.chase_view import ChaseView
    from agrinav_gym.config import RenderConfig
    from agrinav_gym.robot import RobotState

    cfg = EnvConfig.from_dict({"render": {"width": 320, "height": 240}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    rot, pos = lane_pose(maize_scenario(maize))
    roll, pitch = 0.08, -0.05  # on a slope: the robot tilts, the chase camera does not
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    tilt = np.array([[cp, sp * sr, sp * cr], [0, cr, -sr], [-sp, cp * sr, cp * cr]])
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    s = RobotState(pos, rot @ tilt, np.array([roll, pitch, yaw]), np.zeros(3), np.zeros(3), [])
    frames = {}
    for raster in (True, False):
        view = ChaseView(RenderConfig(320, 240), model, cfg.camera)
        view.rasterises = raster
        frames[raster] = view.render(maize, s).astype(int)
    diff = np.abs(frames[True] - frames[False]).max(axis=2)
    assert frames[True].shape == (240, 320, 3)
    assert (diff > 8).mean() < 0.002, (diff > 8).mean()
    # the robot is in the picture: without its hits a patch below the centre changes
    none = (np.full(320 * 240, np.inf), np.full(320 * 240, -1, np.int32))
    view = ChaseView(RenderConfig(320, 240), model, cfg.camera)
    view._robot_in_chase = lambda *_: none  # type: ignore[method-assign]
    bare = np.abs(view.render(maize, s).astype(int) - frames[True]).max(axis=2) > 8
    rows, cols = np.nonzero(bare)
    assert bare.sum() > 100 and rows.min() > 100 and 100 < cols.mean() < 220
