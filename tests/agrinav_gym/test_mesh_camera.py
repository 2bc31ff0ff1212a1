"""The mesh camera: D455 depth over the plant meshes, labels, stereo invalidation, RGB."""

import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

from agrinav_gym.config import EnvConfig
from agrinav_gym.render import native
from agrinav_gym.render.classes import CROP, SOIL
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.render.plant_meshes import PlantMeshes, Prototype
from agrinav_gym.robot import RobotGeometry, robot_interface
from agrinav_gym.sensors import d455
from agrinav_gym.sensors.mesh_camera import MeshCamera
from scenario_gen import Terrain, generate, preset

from .helpers import TINY, make_camera

BASE = np.array([0.0, 0.0, 0.11])  # base_link on flat ground at z = 0


def camera(
    robot: dict[str, Any] | None = None,
    cam: dict[str, Any] | None = None,
    renderer: str = "auto",
    threads: int = 1,
) -> MeshCamera:
    cfg = EnvConfig.from_dict(
        {"robot": robot or {}, "camera": {**(cam or {}), "renderer": renderer}}
    )
    return MeshCamera(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera, threads)


def boxes(items: list[tuple[float, float, tuple[float, float, float]]]) -> PlantMeshes:
    """Upright boxes (x, y, size) standing on z = 0, as plants with a prototype each."""
    protos = []
    for _, _, size in items:
        box = trimesh.creation.box(extents=size)
        box.apply_translation([0, 0, size[2] / 2])
        protos.append(Prototype.from_trimesh(box, f"box{len(protos)}", CROP))
    n = len(items)
    zero = np.zeros(n)
    return PlantMeshes(
        tuple(protos),
        np.arange(n, dtype=np.int16),
        np.ones(n, np.float32),
        np.array([x for x, _, _ in items]),
        np.array([y for _, y, _ in items]),
        zero,
        zero,
        zero,
        zero,
    )


def flat() -> Terrain:
    return Terrain(np.zeros((120, 120)), -7.0, -7.0, 0.12)


def test_d455_intrinsics_and_colour_extrinsic() -> None:
    assert d455.focal_848() == pytest.approx(424 / math.tan(math.radians(43.5)))
    assert d455.focal_848() == pytest.approx(446.8, abs=0.05)
    big, small = camera(cam={"width": 848, "height": 480}), camera()
    assert big.fx == pytest.approx(446.8, abs=0.05)
    assert small.fx == pytest.approx(d455.focal_848() * 64 / 848, rel=1e-9)  # FOV kept
    # the colour camera: 59 mm to the right along the baseline, 90° wide
    shift = np.asarray(big.color.position) - np.asarray(big.model.position)
    right = big.model.rotation @ np.array([0.0, -1.0, 0.0])
    assert shift == pytest.approx(d455.COLOR_OFFSET * right, abs=1e-12)
    assert 2 * math.degrees(math.atan(424 / big.color.fx)) == pytest.approx(90.0)


def test_depth_of_a_box_at_a_known_distance_follows_the_noise_law(renderer: str) -> None:
    cam = camera({"camera_pitch_deg": 0.0}, {"width": 16, "height": 12}, renderer)
    x_cam = 0.25  # the camera sits 0.25 m ahead of base_link
    scene = MeshScene(flat(), boxes([(x_cam + 3.05, 0.0, (0.1, 3.0, 2.0))]))
    truth = cam.draw(np.eye(3), BASE, scene, None)
    z = float(truth.depth[6, 8])
    assert z == pytest.approx(3.0, abs=1e-4)  # the box's near face, along the optical axis
    rng = np.random.default_rng(0)
    samples = np.array([cam.draw(np.eye(3), BASE, scene, rng).depth[6, 8] for _ in range(2500)])
    # σ_z = z²·s/(f·B) with f of the 1280-px sensor mode the 16-px image is resampled from
    # (the image's own f made the mesh camera's noise 80 × the proxy camera's here)
    f = 0.5 * 1280 / math.tan(math.radians(87.0) / 2)
    sigma = z**2 * 0.08 / (f * 0.095)
    assert samples.mean() == pytest.approx(z, abs=4 * sigma / math.sqrt(len(samples)))
    assert samples.std() == pytest.approx(sigma, rel=0.06)
    proxy = make_camera({"camera_pitch_deg": 0.0}, {"width": 16, "height": 12})
    assert cam.noise_sigma(np.array([z])) == pytest.approx(proxy.noise_sigma(np.array([z])))


def test_noisy_frames_are_deterministic_per_seed(renderer: str) -> None:
    scn = generate(preset("default", **TINY), 0)
    scene = MeshScene.from_scenario(scn)
    cam = camera(renderer=renderer)
    pos = np.array([scn.route.xy[30][0], scn.route.xy[30][1], 0.0])
    pos[2] = float(scn.terrain.height_at(pos[0], pos[1])) + 0.11
    a = cam.draw(np.eye(3), pos, scene, np.random.default_rng(3)).depth
    b = cam.draw(np.eye(3), pos, scene, np.random.default_rng(3)).depth
    c = cam.draw(np.eye(3), pos, scene, np.random.default_rng(4)).depth
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_instance_ids_name_the_plant_each_ray_hits(renderer: str) -> None:
    """Checked against an independent closest-point query on every nearby plant's mesh."""
    scn = generate(preset("default", **TINY), 0)
    scene = MeshScene.from_scenario(scn)
    cam = camera(cam={"width": 128, "height": 96, "min_range": 0.0}, renderer=renderer)
    xy = scn.route.xy[40]
    pos = np.array([xy[0], xy[1], float(scn.terrain.height_at(*xy)) + 0.11])
    c, s = math.cos(scn.rows.angle), math.sin(scn.rows.angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    f = cam.draw(rot, pos, scene, None, labels=True, stereo=False)
    inst = f.instance.ravel()
    on = np.flatnonzero(inst >= 0)
    assert len(on) > 200 and (f.label.ravel()[on] == CROP).all()
    o, d = cam.rays.world(rot, pos)
    pick = on[:: max(1, len(on) // 150)]
    hit = o + d[pick] * (f.depth.ravel()[pick] / cam.rays.forward[pick])[:, None]
    pm = scene.plants
    for p, i in zip(hit, inst[pick], strict=True):
        near = np.flatnonzero(np.hypot(pm.x - p[0], pm.y - p[1]) < 1.5)
        dist = {}
        for j in near:
            tri = pm.world_vertices(int(j))[pm.prototypes[int(pm.proto[j])].faces]
            q = trimesh.triangles.closest_point(tri, np.repeat(p[None], len(tri), axis=0))
            dist[int(j)] = float(np.linalg.norm(q - p, axis=1).min())
        assert dist[int(i)] < 1e-3  # float32 rays over a few metres
        assert dist[int(i)] == min(dist.values())


def test_occlusion_shadow_is_left_of_a_foreground_post(renderer: str) -> None:
    """A post 1 m ahead of a wall at 3 m hides a strip of wall from the right imager only: the
    invalid strip is on the post's left in the image, fx·B·(1/1 − 1/3) pixels wide."""
    cam = camera(
        {"camera_pitch_deg": 0.0, "camera_height": 0.55}, {"width": 200, "height": 40}, renderer
    )
    x_cam = 0.25
    both = MeshScene(
        flat(),
        boxes([(x_cam + 3.05, 0.0, (0.1, 6.0, 2.0)), (x_cam + 1.05, 0.0, (0.1, 0.12, 2.0))]),
    )
    geo = cam.draw(np.eye(3), BASE, both, None, stereo=False).depth
    img = cam.draw(np.eye(3), BASE, both, None).depth
    row = 20
    cols = np.flatnonzero(np.abs(geo[row] - 1.0) < 0.01)  # the post
    left, right = cols.min(), cols.max()
    width = cam.fx * 0.095 * (1 / 1.0 - 1 / 3.0)
    run = 0  # invalid wall pixels touching the post's left edge
    while img[row, left - 1 - run] == 0 and geo[row, left - 1 - run] > 2.9:
        run += 1
    assert run == pytest.approx(width, abs=1.0)
    # elsewhere on the wall only the image's left band, which the right imager cannot see
    band = cam.fx * 0.095 / 3.0
    assert ((img[row, : left - run] == 0).sum()) == pytest.approx(band, abs=1.0)
    assert (img[row, right + 1 : right + 40] > 0).all()  # nothing missing on its right
    assert (img[row, left : right + 1] > 0).all()  # the post itself is seen by both


def test_a_user_zip_model_appears_in_depth_and_rgb(tmp_path: Path, renderer: str) -> None:
    """A textured OBJ in a zip (mesh + .mtl + .png) becomes every crop; its texture is seen."""
    mesh = trimesh.creation.box(extents=(0.3, 0.3, 1.0))
    mesh.apply_translation([0, 0, 0.5])
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[...] = (200, 30, 30)  # plain red: unlike any catalog plant or the soil
    from PIL import Image

    uv = np.column_stack([mesh.vertices[:, 0] + 0.5, mesh.vertices[:, 2]])
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(tex))
    obj, files = trimesh.exchange.obj.export_obj(mesh, return_texture=True, mtl_name="plant.mtl")
    archive = tmp_path / "plant.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("plant.obj", obj)
        for name, data in files.items():
            z.writestr(name, data)
    scn = generate(preset("default", **TINY, crop={"model": str(archive), "stage": 3}), 0)
    scene = MeshScene.from_scenario(scn)
    assert scene.plants.prototypes[0].texture is not None
    cam = camera(cam={"width": 96, "height": 72}, renderer=renderer)
    xy = scn.route.xy[40]
    pos = np.array([xy[0], xy[1], float(scn.terrain.height_at(*xy)) + 0.11])
    c, s = math.cos(scn.rows.angle + 0.4), math.sin(scn.rows.angle + 0.4)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    f = cam.draw(rot, pos, scene, None, rgb=True, labels=True)
    crop = f.rgb_label == CROP
    assert (f.label == CROP).mean() > 0.02 and crop.mean() > 0.02
    assert (f.depth[f.label == CROP] > 0).sum() > 100  # in depth (nearer than 0.4 m: 0)
    rgb = f.rgb[crop].astype(float)
    assert (rgb[:, 0] > 2 * rgb[:, 1]).mean() > 0.95  # red: the texture, lit
    soil = f.rgb[f.rgb_label == SOIL].astype(float)
    assert (soil[:, 0] > 2 * soil[:, 1]).mean() < 0.05


def test_a_saved_user_model_is_found_after_the_folder_moves(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The sensors read the scenario's own copy: original gone, folder moved, cwd elsewhere."""
    import shutil

    from scenario_gen import load, save

    src = tmp_path / "src"
    src.mkdir()
    mesh = trimesh.creation.box(extents=(0.3, 0.3, 1.0))
    mesh.apply_translation([0, 0, 0.5])
    archive = src / "plant.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("plant.obj", trimesh.exchange.obj.export_obj(mesh))
    scn = generate(preset("default", **TINY, crop={"model": str(archive), "stage": 3}), 0)
    out = save(scn, tmp_path / "a" / "scn")
    shutil.rmtree(src)
    moved = Path(shutil.move(str(out), str(tmp_path / "b")))
    elsewhere = tmp_path / "c"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    back = load(Path("..") / moved.name)
    scene = MeshScene.from_scenario(back)
    user = [p for p in scene.plants.prototypes if p.name == "plant.zip"]
    assert len(user) == 1 and float(np.ptp(user[0].vertices[:, 2])) > 0.1


CROP_MODELS = Path(__file__).resolve().parents[1] / "data" / "crop_models"


def _cutout_scene(x: float = 1.5) -> MeshScene:
    """The test plant (a leaf quad facing -x whose outer quarters are cut out, a stalk behind
    it) 1 m tall, ``x`` m ahead of the robot on flat ground."""
    from scenario_gen.models import load_model

    proto = Prototype.from_trimesh(
        load_model(CROP_MODELS / "cutout_plant" / "meshes" / "plant.dae", 1.0), "cutout", CROP
    )
    assert proto.alpha is not None and 0.3 < proto.alpha.mean() < 0.7
    one = np.zeros(1)
    plants = PlantMeshes(
        (proto,), np.zeros(1, np.int16), np.ones(1, np.float32), one + x, one, one, one, one, one
    )
    return MeshScene(flat(), plants)


def _on_quad(cam: MeshCamera, rays: Any, x_quad: float) -> tuple[Any, Any, Any]:
    """Pixels whose rays cross the leaf quad's plane inside the quad: on its opaque strip, on
    its cut-out quarters (margins of 1 cm left out), and the distance along the axis there."""
    o, d = rays.world(np.eye(3), BASE)
    t = (x_quad - o[0]) / d[:, 0]
    p = o + d * t[:, None]
    inside = (p[:, 2] > 0.21) & (p[:, 2] < 0.99) & (np.abs(p[:, 1]) < 0.29) & (t > 0)
    strip = inside & (np.abs(p[:, 1]) < 0.14)
    cut = inside & (np.abs(p[:, 1]) > 0.16)
    return strip, cut, t * rays.forward


def test_textured_model_colours_are_its_texels(renderer: str) -> None:
    """The leaf, lit head-on (sun behind the camera), reads its texture's colour: mean RGB
    within 10 levels of the texel (haze at 1.3 m moves it by < 7)."""
    from ..data.crop_models.make_models import LEAF

    cam = camera(cam={"width": 160, "height": 120}, renderer=renderer)
    cam.set_lighting(None, 180.0, 0.0)  # light along -x: the quad's face towards the camera
    f = cam.draw(np.eye(3), BASE, _cutout_scene(), None, rgb=True, labels=True, stereo=False)
    strip, _, _ = _on_quad(cam, cam.color_rays, 1.5 - 0.03)
    leaf = f.rgb.reshape(-1, 3)[strip & (f.rgb_label.ravel() == CROP)].astype(float)
    assert len(leaf) > 200
    assert np.abs(leaf.mean(axis=0) - LEAF).max() < 10, leaf.mean(axis=0)


def test_alpha_cutouts_let_rays_through(renderer: str) -> None:
    """A ray through a cut-out texel is no hit: depth, labels, instance and colour there are
    those of the same view without the plant; rays through its opaque strip see the leaf."""
    from ..data.crop_models.make_models import CUT

    cam = camera(cam={"width": 160, "height": 120}, renderer=renderer)
    # the model stands on its stem's foot (x 0.05 in its file): its quad lies 5 cm in front
    x_quad = 1.5 - 0.05
    kw: dict[str, Any] = {"rgb": True, "labels": True, "stereo": False}
    f = cam.draw(np.eye(3), BASE, _cutout_scene(), None, **kw)
    bare = cam.draw(np.eye(3), BASE, MeshScene(flat()), None, **kw)
    strip, cut, z_quad = _on_quad(cam, cam.rays, x_quad)
    label, depth = f.label.ravel(), f.depth.ravel()
    assert strip.sum() > 200 and cut.sum() > 200
    assert (label[strip] == CROP).all() and (f.instance.ravel()[strip] == 0).all()
    assert np.allclose(depth[strip], z_quad[strip], atol=2e-3)
    assert (f.instance.ravel()[cut] == -1).all()
    assert np.array_equal(label[cut], bare.label.ravel()[cut])
    assert np.allclose(depth[cut], bare.depth.ravel()[cut], atol=1e-5)
    assert (bare.label.ravel()[cut] == SOIL).sum() > 50  # the ground is seen through them
    # no cut-out texel's colour anywhere in the colour image
    rgb = f.rgb.reshape(-1, 3).astype(int)
    assert not (np.abs(rgb - CUT).max(axis=1) < 60).any()
    c_strip, c_cut, _ = _on_quad(cam, cam.color_rays, x_quad)
    assert np.array_equal(f.rgb_label.ravel()[c_cut], bare.rgb_label.ravel()[c_cut])
    assert np.array_equal(f.rgb.reshape(-1, 3)[c_cut], bare.rgb.reshape(-1, 3)[c_cut])
    assert (f.rgb_label.ravel()[c_strip] == CROP).all()


def test_alpha_cutouts_hide_nothing_from_the_stereo_pair() -> None:
    """The right imager's occlusion test passes through cut-outs too: behind the cut-out
    quarters a ground pixel is invalid exactly where the segment from the right imager to it
    crosses the leaf's opaque strip."""
    cam = camera(cam={"width": 160, "height": 120}, renderer="raycast")
    x_quad = 1.5 - 0.05
    with_plant = cam.draw(np.eye(3), BASE, _cutout_scene(), None).depth.ravel()
    bare = cam.draw(np.eye(3), BASE, MeshScene(flat()), None).depth.ravel()
    _, cut, _ = _on_quad(cam, cam.rays, x_quad)
    seen = cut & (bare > 0)
    o, d = cam.rays.world(np.eye(3), BASE)
    ground = o + d * (np.where(seen, bare, 1.0) / cam.rays.forward)[:, None]
    right = cam.right_world(np.eye(3), BASE)
    s = (x_quad - right[0]) / (ground[:, 0] - right[0])
    q = right + (ground - right) * s[:, None]  # where the right imager's view crosses the quad
    y, z = np.abs(q[:, 1]), q[:, 2]
    on_strip = (y < 0.14) & (z > 0.21) & (z < 0.99)
    clear = (y > 0.16) | (z < 0.19) | (z > 1.01)
    assert (seen & on_strip).sum() > 10 and (seen & clear).sum() > 100
    assert (with_plant[seen & on_strip] == 0).all()  # the opaque strip hides them
    assert (with_plant[seen & clear] > 0).all()  # through the cut-out: still matched


def test_scenes_with_cutouts_are_drawn_by_rays() -> None:
    """The compiled rasteriser knows no cut-outs: a scene with them is cast by Embree whatever
    ``camera.renderer`` says, so both settings give the same frame."""
    if not native.available():
        pytest.skip("compiled kernels not built (test_native checks the build in CI)")
    scene = _cutout_scene()
    kw = {"cam": {"width": 96, "height": 72}}
    a = camera(**kw, renderer="raster").draw(np.eye(3), BASE, scene, None, rgb=True, labels=True)
    b = camera(**kw, renderer="raycast").draw(np.eye(3), BASE, scene, None, rgb=True, labels=True)
    assert np.array_equal(a.depth, b.depth) and np.array_equal(a.rgb, b.rgb)
    assert np.array_equal(a.label, b.label)


def test_a_textured_mesh_without_its_image_keeps_its_material_colour() -> None:
    """A texture that did not load leaves a TextureVisuals without an image: its faces take
    the material's colour (it used to be an AttributeError on face_colors)."""
    mesh = trimesh.creation.box(extents=(0.2, 0.2, 1.0))
    material = trimesh.visual.material.SimpleMaterial(diffuse=[10, 200, 30, 255])
    mesh.visual = trimesh.visual.TextureVisuals(material=material)
    proto = Prototype.from_trimesh(mesh, "untextured", CROP)
    assert proto.texture is None and (proto.face_rgb == (10, 200, 30)).all()


def test_a_crop_model_whose_texture_is_gone_is_refused_by_name(tmp_path: Path) -> None:
    """A scenario folder that kept only the COLLADA file (as folders did before a model's
    files were kept with it): the mesh camera refuses it naming the texture, one line."""
    import json
    import shutil

    from scenario_gen import InputError, load, save

    shutil.copytree(CROP_MODELS / "cutout_plant", tmp_path / "plant")
    model = str(tmp_path / "plant" / "meshes" / "plant.dae")
    out = save(generate(preset("default", **TINY, crop={"model": model}), 0), tmp_path / "s")
    meta = json.loads((out / "scenario.json").read_text())
    del meta["crop_model"]["files"]
    (out / "scenario.json").write_text(json.dumps(meta))
    shutil.rmtree(out / "models" / "plant" / "materials")
    with pytest.raises(InputError, match=r"leaf\.png.*missing") as info:
        MeshScene.from_scenario(load(out))
    assert "\n" not in str(info.value)
