"""Condition renders (issue 61): `sparc3d render MESH -o DIR --for trellis|trellis2` writes
RGBA views and a `transforms.json` whose cameras are the ones the views were traced with. Each
view's alpha is checked against a silhouette made here, independently of the renderer: the
source mesh read by trimesh, placed as `transforms.json` says (Blender's Y-up to Z-up turn,
then `scale` and `offset`), projected through each frame's `camera_angle_x` and camera-to-world
`transform_matrix` (Blender's camera: −Z forward, +Y up), and its triangles filled at pixel
centres. Same file and seed: the same bytes."""

import json

import numpy as np
import pytest

from sparc3d_cli import ROOT, run

EXAMPLES = ROOT / "examples"


def read_png_alpha(path):
    from PIL import Image
    with Image.open(path) as im:
        assert im.mode == "RGBA", im.mode
        return np.asarray(im)[:, :, 3]


def placed_mesh(path, transforms):
    import trimesh
    mesh = trimesh.load(path, force="mesh", process=False)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    z_up = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    return z_up * transforms["scale"] + np.asarray(transforms["offset"]), np.asarray(mesh.faces)


def silhouette(vertices, faces, frame, size, grid=4):
    """The pixels at least half covered by the asset: the triangles projected through the
    frame's camera and filled at the centres of a `grid` × `grid` raster in each pixel."""
    fine = centres_inside(vertices, faces, frame, size * grid)
    return fine.reshape(size, grid, size, grid).mean(axis=(1, 3)) >= 0.5


def centres_inside(vertices, faces, frame, size):
    """The pixels whose centre sees a triangle, projected through the frame's camera."""
    m = np.asarray(frame["transform_matrix"], dtype=np.float64)
    rot, eye = m[:3, :3], m[:3, 3]
    cam = (vertices - eye) @ rot  # world to camera: Rᵀ(p − e), one row per vertex
    depth = -cam[:, 2]
    assert (depth > 0).all(), "the asset is behind the camera"
    half = np.tan(frame["camera_angle_x"] / 2)
    px = (cam[:, 0] / depth / half + 1) * size / 2
    py = (1 - cam[:, 1] / depth / half) * size / 2
    mask = np.zeros((size, size), dtype=bool)
    for a, b, c in faces:
        xs, ys = px[[a, b, c]], py[[a, b, c]]
        x0, x1 = max(int(np.floor(xs.min())), 0), min(int(np.ceil(xs.max())), size - 1)
        y0, y1 = max(int(np.floor(ys.min())), 0), min(int(np.ceil(ys.max())), size - 1)
        if x0 > x1 or y0 > y1:
            continue
        gx, gy = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        d = (xs[1] - xs[0]) * (ys[2] - ys[0]) - (xs[2] - xs[0]) * (ys[1] - ys[0])
        if abs(d) < 1e-12:
            continue
        w1 = ((gx - xs[0]) * (ys[2] - ys[0]) - (xs[2] - xs[0]) * (gy - ys[0])) / d
        w2 = ((xs[1] - xs[0]) * (gy - ys[0]) - (gx - xs[0]) * (ys[1] - ys[0])) / d
        inside = (w1 >= 0) & (w2 >= 0) & (w1 + w2 <= 1)
        mask[y0:y1 + 1, x0:x1 + 1] |= inside
    return mask


@pytest.mark.parametrize("name,recipe", [("sphere.obj", "trellis2"), ("wuson.stl", "trellis"),
                                         ("cube.off", "trellis2")])
def test_every_views_alpha_is_the_silhouette_its_transforms_json_gives(tmp_path, name, recipe):
    size, views = 256, 6
    out = tmp_path / "views"
    run("render", EXAMPLES / name, "-o", out, "--for", recipe, "--views", views, "--size", size)
    transforms = json.loads((out / "transforms.json").read_text())
    assert transforms["aabb"] == [[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]]
    assert len(transforms["frames"]) == views
    vertices, faces = placed_mesh(EXAMPLES / name, transforms)
    extent = vertices.max(axis=0) - vertices.min(axis=0)
    assert abs(extent.max() - 1) < 1e-4, "scaled so that the longest side is 1"
    assert np.abs(vertices.max(axis=0) + vertices.min(axis=0)).max() < 1e-4, "centred"
    for i, frame in enumerate(transforms["frames"]):
        assert frame["file_path"] == f"{i:03d}.png"
        fov = np.degrees(frame["camera_angle_x"])
        assert 10 - 1e-6 <= fov <= 70 + 1e-6, fov
        alpha = read_png_alpha(out / frame["file_path"])
        assert alpha.shape == (size, size)
        ours, theirs = alpha >= 128, silhouette(vertices, faces, frame, size)
        iou = (ours & theirs).sum() / max((ours | theirs).sum(), 1)
        assert theirs.sum() > 50, f"view {i} sees almost nothing"
        assert iou >= 0.99, f"{name} view {i}: alpha IoU {iou:.4f} against the silhouette"


def test_the_same_file_and_seed_give_the_same_bytes_and_another_seed_other_views(tmp_path):
    args = ["--views", 3, "--size", 64]
    for name, seed in (("a", 0), ("b", 0), ("c", 1)):
        run("render", EXAMPLES / "box_textured.glb", "-o", tmp_path / name, "--seed", seed, *args)
    files = ["000.png", "001.png", "002.png", "transforms.json"]
    read = lambda d: [(tmp_path / d / f).read_bytes() for f in files]
    assert read("a") == read("b")
    assert read("a")[-1] != read("c")[-1]
    # The textured box is drawn in its texture's colours, not the plain grey.
    from PIL import Image
    with Image.open(tmp_path / "a" / "000.png") as im:
        px = np.asarray(im).reshape(-1, 4)
    seen = px[px[:, 3] == 255][:, :3].astype(int)
    assert (seen.max(axis=1) - seen.min(axis=1) > 40).mean() > 0.1, "no colour seen"


def test_a_mesh_without_triangles_and_a_bad_recipe_are_clear_errors(tmp_path):
    empty = tmp_path / "empty.off"
    empty.write_text("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n")
    r = run("render", empty, "-o", tmp_path / "out", check=False)
    assert r.returncode != 0 and "triangle" in r.stderr and "empty.off" in r.stderr, r.stderr
    assert not (tmp_path / "out").exists(), "nothing written for an asset that cannot render"
    r = run("render", EXAMPLES / "cube.off", "-o", tmp_path / "out", "--for", "blender",
            check=False)
    assert r.returncode != 0 and "trellis2" in r.stderr, r.stderr
