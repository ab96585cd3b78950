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




def read_png16(path):
    """A PNG's samples as an array of rows × columns × channels, 16-bit kept (pypng)."""
    import png
    width, height, rows, info = png.Reader(filename=str(path)).asDirect()
    assert info["bitdepth"] == 16, info
    return np.vstack([np.asarray(r, dtype=np.float64) for r in rows]).reshape(
        height, width, info["planes"])


def first_hits(eye, dirs, vertices, faces):
    """The nearest triangle each ray from `eye` along `dirs` hits (Möller–Trumbore over every
    triangle; -1 for none) and its distance."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    best_t = np.full(len(dirs), np.inf)
    best = np.full(len(dirs), -1)
    for start in range(0, len(dirs), 2048):
        d = dirs[start:start + 2048, None, :]
        p = np.cross(d, e2[None])
        det = (e1[None] * p).sum(-1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
        s = eye - a
        u = (s[None] * p).sum(-1) * inv
        q = np.cross(s, e1)
        v = (d * q[None]).sum(-1) * inv
        t = (e2[None] * q[None]).sum(-1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        t = np.where(hit, t, np.inf)
        idx = t.argmin(axis=1)
        nearest = t[np.arange(len(idx)), idx]
        best_t[start:start + 2048] = nearest
        best[start:start + 2048] = np.where(np.isfinite(nearest), idx, -1)
    return best, best_t


def hits_through(frame, vertices, faces, size):
    """This test's own ray cast through every pixel centre of `frame`'s camera: the hit
    points, the pixels they belong to (row-major index) and the triangles hit."""
    m = np.asarray(frame["transform_matrix"], dtype=np.float64)
    rot, eye = m[:3, :3], m[:3, 3]
    half = np.tan(frame["camera_angle_x"] / 2)
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    u, v = (2 * xs / size - 1) * half, (1 - 2 * ys / size) * half
    dirs = np.stack([u, v, -np.ones_like(u)], axis=-1).reshape(-1, 3) @ rot.T
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    tris, t = first_hits(eye, dirs, vertices, faces)
    rays = np.flatnonzero(tris >= 0)
    return eye + dirs[rays] * t[rays, None], rays, tris[rays], eye, rot


def test_passes_are_the_normals_depths_and_texture_colours_the_sources_own(tmp_path):
    """Each pass against this test's own ray cast of the source through `transforms.json`
    (every triangle against every pixel's centre ray):
    the normal pass within 2° (median) of the hit triangle's normal turned towards the camera,
    the depth pass within 1e-3 of the hit's distance from the camera's plane, the albedo pass
    within 12/255 (median) of the texture at the hit point (nearest texel, by trimesh), and
    the mask the view's alpha."""
    import trimesh
    from PIL import Image
    size, out = 96, tmp_path / "views"
    run("render", EXAMPLES / "box_textured.glb", "-o", out, "--views", 4, "--size", size,
        "--passes", "normal,depth,albedo,mask")
    transforms = json.loads((out / "transforms.json").read_text())
    source = trimesh.load(EXAMPLES / "box_textured.glb", force="mesh", process=False)
    vertices, faces = placed_mesh(EXAMPLES / "box_textured.glb", transforms)
    uv, texture = np.asarray(source.visual.uv), source.visual.material.baseColorTexture
    angles, depth_errors, colour_errors = [], [], []
    for i, frame in enumerate(transforms["frames"]):
        points, rays, tris, eye, rot = hits_through(frame, vertices, faces, size)
        assert len(rays) > 200, f"view {i} sees almost nothing"
        py, px = np.divmod(rays, size)
        # Normals: the triangle's own, facing the camera.
        a, b, c = (vertices[faces[tris, k]] for k in range(3))
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        n[(n * (points - eye)).sum(axis=1) > 0] *= -1
        normal = read_png16(out / f"{i:03d}_normal.png")
        assert normal.shape == (size, size, 4)
        seen = normal[py, px]
        assert (seen[:, 3] == 65535).mean() > 0.99, "the normal pass misses where rays hit"
        ours = seen[:, :3] / 65535 * 2 - 1
        cos = (ours * n).sum(axis=1) / np.linalg.norm(ours, axis=1)
        angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
        # Depth: the distance from the camera's plane, over the frame's range.
        lo, hi = frame["depth"]["min"], frame["depth"]["max"]
        depth = read_png16(out / f"{i:03d}_depth.png")[:, :, 0]
        planar = -((points - eye) @ rot[:, 2])
        depth_errors.append(np.abs(lo + depth[py, px] / 65535 * (hi - lo) - planar))
        # Albedo: the texture where the ray hit, away from the silhouette and the box's edges.
        bary = trimesh.triangles.points_to_barycentric(np.stack([a, b, c], axis=1), points)
        hit_uv = (uv[faces[tris]] * bary[:, :, None]).sum(axis=1)
        expected = trimesh.visual.color.uv_to_color(hit_uv, texture)[:, :3].astype(int)
        albedo = np.asarray(Image.open(out / f"{i:03d}_albedo.png")).astype(int)
        view = np.asarray(Image.open(out / f"{i:03d}.png"))
        interior = (albedo[py, px, 3] == 255) & (bary.min(axis=1) > 0.02)
        colour_errors.append(np.abs(albedo[py, px, :3] - expected)[interior].max(axis=1))
        mask = np.asarray(Image.open(out / f"{i:03d}_mask.png"))
        assert (mask == view[:, :, 3]).all(), "the mask is the view's alpha"
        assert (albedo[:, :, 3] == view[:, :, 3]).all(), "the albedo keeps the view's alpha"
    angles, depth_errors = np.concatenate(angles), np.concatenate(depth_errors)
    colour_errors = np.concatenate(colour_errors)
    assert np.median(angles) <= 2.0, f"normals: median {np.median(angles):.2f}°"
    assert np.median(depth_errors) <= 1e-3, f"depth: median {np.median(depth_errors):.2e}"
    assert len(colour_errors) > 500
    assert np.median(colour_errors) <= 12, f"albedo: median {np.median(colour_errors)}/255"


def test_a_render_without_passes_writes_none_and_an_unknown_pass_is_named(tmp_path):
    run("render", EXAMPLES / "cube.off", "-o", tmp_path / "a", "--views", 2, "--size", 32)
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == [
        "000.png", "001.png", "transforms.json"]
    assert "depth" not in (tmp_path / "a" / "transforms.json").read_text()
    r = run("render", EXAMPLES / "cube.off", "-o", tmp_path / "b", "--passes", "mist",
            check=False)
    assert r.returncode != 0 and "mist" in r.stderr and "albedo" in r.stderr, r.stderr
