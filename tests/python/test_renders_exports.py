"""Condition renders in the exports of Hunyuan3D-2.1 and Step1X-3D (issue 61 item 4): a job
with `[samples]` and `[renders]` exported as `hunyuan3d-2.1` gets `<item>/render_cond/000.png …
023.png`, read here as `hy3dshape/data/dit_asl.py` `AlignedShapeLatentDataset` reads them
(`decode` L247-249 names the 24 files, `load_render` L210-245 composites each on white and crops
to its alpha box; with PIL instead of OpenCV, whose `imread` gives the same bytes in BGR order),
and as `step1x-3d` gets `images/<uid>/NNNN_rgb.png`, read as `step1x3d_geometry/data/base.py`
`BaseDataset._load_image` reads them (L204-243: crop to the alpha box on a background, 0.9 of
the frame, square, 512²). Every item and every view; the cameras of each `transforms.json` are
in the export's own frame: the source moved by its `scale` and `offset` and projected through
them is each view's alpha (IoU ≥ 0.99), and the export's own surface samples lie in it."""

import json

import numpy as np
import pytest

from sparc3d_cli import ROOT, run
from test_cond_renders import silhouette

EXAMPLES = ROOT / "examples"
MESHES = ["cube.off", "wuson.stl"]
SIZE = 96


def make_job(tmp, views):
    manifest = tmp / "m.csv"
    manifest.write_text("path\n" + "".join(f"{EXAMPLES / n}\n" for n in MESHES))
    config = tmp / "job.toml"
    config.write_text(f"[samples]\nseed = 3\n[renders]\nenabled = true\nrecipe = \"trellis\"\n"
                      f"views = {views}\nsize = {SIZE}\n")
    job = tmp / "job"
    run("init", job, "--manifest", manifest, "--resolution", 64, "--config", config,
        "--for", "dora")
    run("run", job, "--workers", "2")
    return job


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    return make_job(tmp_path_factory.mktemp("renders_exports"), 24)


def exported(job, fmt, out):
    r = run("export", job, "--format", fmt, "--out", out)
    return r.stderr, json.loads((out / ".sparc3d-export.json").read_text())


def sources(job):
    import trimesh
    from sparc3d_cli import frozen_records
    return {r["id"]: trimesh.load(r["uri"], force="mesh", process=False)
            for r in frozen_records(job)}


def alpha_of(path):
    from PIL import Image
    with Image.open(path) as im:
        assert im.mode == "RGBA", im.mode
        return np.asarray(im)


def check_views(folder, source, names, surface=None):
    """Each listed view's alpha against the source's silhouette through the exported camera,
    and the export's own surface points inside it."""
    transforms = json.loads((folder / "transforms.json").read_text())
    assert [f["file_path"] for f in transforms["frames"]] == names
    placed = np.asarray(source.vertices) * transforms["scale"] + np.asarray(transforms["offset"])
    for frame in transforms["frames"]:
        ours = alpha_of(folder / frame["file_path"])[:, :, 3] >= 128
        theirs = silhouette(placed, np.asarray(source.faces), frame, SIZE)
        iou = (ours & theirs).sum() / max((ours | theirs).sum(), 1)
        assert iou >= 0.99, f"{folder.name} {frame['file_path']}: IoU {iou:.4f}"
        if surface is not None:
            m = np.asarray(frame["transform_matrix"])
            cam = (surface[:, :3] - m[:3, 3]) @ m[:3, :3]
            half = np.tan(frame["camera_angle_x"] / 2)
            px = ((cam[:, 0] / -cam[:, 2] / half + 1) * SIZE / 2).astype(int).clip(0, SIZE - 1)
            py = ((1 - cam[:, 1] / -cam[:, 2] / half) * SIZE / 2).astype(int).clip(0, SIZE - 1)
            # The samples are of the 64³ output, within about a voxel (1.5 pixels here).
            dilated = ours.copy()
            for dy in range(-2, 3):
                for dx in range(-2, 3):
                    dilated |= np.roll(np.roll(ours, dy, 0), dx, 1)
            inside = dilated[py, px].mean()
            assert inside >= 0.99, f"{frame['file_path']}: {inside:.3f} of the samples in view"


def load_render_hunyuan(path):
    """`load_render` for one image: RGBA composited on white, cropped to alpha > 0.3 ± 5."""
    image = alpha_of(path).astype(np.float32)
    alpha = image[:, :, 3:4] / 255
    composed = (image[:, :, :3] * alpha + 255 * (1 - alpha)).astype(np.uint8)
    mask = (alpha[:, :, 0] * 255).astype(np.uint8)
    nz = np.argwhere(mask > 0.3)
    (x0, y0), (x1, y1) = nz.min(axis=0), nz.max(axis=0)
    h, w = mask.shape
    return composed[max(x0 - 5, 0):min(x1 + 5, h), max(y0 - 5, 0):min(y1 + 5, w)]


def test_hunyuan3ds_loader_reads_all_24_views_of_every_item(job, tmp_path):
    out = tmp_path / "hy"
    said, record = exported(job, "hunyuan3d-2.1", out)
    assert "condition views" not in said, said
    meshes = sources(job)
    items = [d for d in out.iterdir() if d.is_dir()]
    assert len(items) == len(MESHES)
    for item in items:
        paths = [item / f"render_cond/{i:03d}.png" for i in range(24)]  # decode, L249
        for p in paths:
            crop = load_render_hunyuan(p)
            assert crop.ndim == 3 and min(crop.shape[:2]) > 10
        uid = item.name
        surface = np.load(item / "geo_data" / f"{uid}_surface.npz")["random_surface"]
        (rid,) = [k for k in meshes if uid.endswith(k[:12]) or k in uid]
        check_views(item / "render_cond", meshes[rid], [f"{i:03d}.png" for i in range(24)],
                    surface.astype(np.float64))


def load_image_step1x(path, background=(255, 255, 255), foreground_ratio=0.9):
    """`_load_image`'s `_process_img` (L205-229)."""
    from PIL import Image
    image = Image.open(path).copy()
    alpha = image.getchannel("A")
    image = Image.alpha_composite(Image.new("RGBA", image.size, (*background, 255)), image)
    image = image.crop(alpha.getbbox())
    resized = image.resize(tuple(int(d * foreground_ratio) for d in image.size))
    padded = Image.new("RGBA", image.size, (*background, 255))
    padded.paste(resized, ((image.width - resized.width) // 2,
                           (image.height - resized.height) // 2))
    side = max(padded.size)
    square = Image.new("RGBA", (side, side), (*background, 255))
    square.paste(padded, ((side - padded.width) // 2, (side - padded.height) // 2))
    return np.asarray(square.resize((512, 512)).convert("RGB"))


def test_step1x3ds_loader_reads_every_view_of_every_listed_uid(job, tmp_path):
    out = tmp_path / "step1x"
    exported(job, "step1x-3d", out)
    uids = json.loads((out / "train.json").read_text())
    meshes = sources(job)
    assert len(uids) == len(MESHES)
    for uid in uids:
        folder = out / "images" / "/".join(uid.split("/")[-2:])  # L240-242
        names = [f"{i:04d}_rgb.png" for i in range(24)]
        for name in names:
            assert load_image_step1x(folder / name).shape == (512, 512, 3)
        surface = np.load(out / "surfaces" / f"{uid}.npz")["surface"]
        (rid,) = [k for k in meshes if k in uid or uid.endswith(k[:12])]
        check_views(folder, meshes[rid], names, surface.astype(np.float64))


def test_fewer_views_than_hunyuan3d_reads_are_named_by_the_export(tmp_path):
    job = make_job(tmp_path, 4)
    said, _ = exported(job, "hunyuan3d-2.1", tmp_path / "hy")
    assert "fewer than the 24 condition views" in said and "views = 24" in said, said


def job_json(path):
    return json.loads((path / "job.json").read_text())


def test_renders_take_the_presets_recipe_and_a_job_without_them_keeps_its_fingerprint(tmp_path):
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"path\n{EXAMPLES / 'cube.off'}\n")
    samples = tmp_path / "samples.toml"
    samples.write_text("[samples]\nenabled = true\n")
    made = {}
    for name, flags in [("plain", ["--config", samples]), ("preset", ["--for", "hunyuan3d-2.1"]),
                        ("rendered", ["--for", "hunyuan3d-2.1", "--renders"]),
                        ("trellis2", ["--for", "trellis2@64", "--renders"])]:
        run("init", tmp_path / name, "--manifest", manifest, *flags)
        made[name] = job_json(tmp_path / name)
    assert "renders" not in made["preset"]["config"]
    assert made["preset"]["fingerprint"] == made["plain"]["fingerprint"]
    assert made["rendered"]["config"]["renders"] == {
        "enabled": True, "recipe": "trellis", "views": 24, "size": 512, "seed": 0}
    assert made["rendered"]["fingerprint"] != made["preset"]["fingerprint"]
    assert made["trellis2"]["config"]["renders"]["views"] == 16
    assert made["trellis2"]["config"]["renders"]["size"] == 1024


def own_surface(fmt, out, stem):
    """The export's own points of an item, in its frame: Dora's surface block, TripoSG's
    surface points, the vecset npz's surface points, cubvh's active cells' centres."""
    if fmt == "dora":
        return np.load(out / f"{stem}.npz")["fps_coarse_surface"].reshape(-1, 6)[:, :3]
    if fmt == "triposg":
        return np.load(out / f"{stem}.npy", allow_pickle=True).item()["surface_points"]
    if fmt == "vecset-npz":
        return np.load(out / f"{stem}.npz")["surface_points"]
    data = np.load(out / f"{stem}.npz")
    n = int(data["resolution"])
    cells = data["active_cells"].astype(np.int64)
    return np.stack([cells // (n * n), cells // n % n, cells % n], axis=1) + 0.5


@pytest.mark.parametrize("fmt", ["dora", "triposg", "vecset-npz", "cubvh"])
def test_the_other_formats_carry_the_views_in_the_plain_layout_in_their_own_frame(
        job, tmp_path, fmt):
    out = tmp_path / fmt
    exported(job, fmt, out)
    meshes = sources(job)
    folders = sorted((out / "renders").iterdir())
    assert len(folders) == len(MESHES)
    for folder in folders:
        stem = folder.name
        (rid,) = [k for k in meshes if k in stem or stem.endswith(k[:12])]
        surface = np.asarray(own_surface(fmt, out, stem), dtype=np.float64)
        check_views(folder, meshes[rid], [f"{i:03d}.png" for i in range(24)], surface)
    if fmt == "dora":
        listed = json.loads((out / "train.json").read_text())
        assert listed and not any("/renders/" in p for p in listed), listed[:3]
