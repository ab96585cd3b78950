# Blender side of ops/bench/renders_vs_blender.sh (issue 61): run inside Blender,
#   blender --background --factory-startup --python renders_vs_blender.py -- \
#       --peer-script PATH/render_cond.py|render.py --recipe trellis2|trellis \
#       --object ASSET --transforms OURS/transforms.json --out DIR
# It loads the peer's own Blender script as a module (its `if __name__ == '__main__'` part does
# not run) and does what that script's main() does, with its own functions: init_scene,
# load_object, normalize_scene, init_camera, the lights (TRELLIS.2: init_uniform_lighting, then
# init_random_lighting per view; TRELLIS: init_lighting) and init_render. Two things differ:
#   - after the peer's init_render (which sets `cycles.device = 'GPU'` and the preferences'
#     `compute_device_type = 'CUDA'`, and `use_denoising = True`) we set `cycles.device =
#     'CPU'`, `compute_device_type = 'NONE'` and `use_denoising = False`; samples (32 / 128),
#     the box filter, the bounces and the resolution stay theirs (--size overrides 1024);
#   - the cameras are ours: each frame of our transforms.json gives the camera's location (the
#     translation of its camera-to-world matrix, the TRACK_TO constraint of their init_camera
#     turning it to the origin as in their script) and its lens from camera_angle_x as their
#     `cam.data.lens = 16 / tan(fov / 2)` on a 32 mm sensor. After each render the matrix their
#     get_transform_matrix reads is compared with ours (printed as max |Δ|).
# TRELLIS.2's random lights draw from numpy, seeded here (np.random.seed(0)) for repeatable runs.
# Debian's glTF importer needs the `np.bool` alias below (numpy 1.24 dropped it).
# Per frame it records the wall time of bpy.ops.render.render (render + PNG save); Blender's
# own "Time: … (Saving: …)" line (render without the save) is what the shell script reads.
import argparse
import importlib.util
import json
import os
import sys
import time

import bpy
import numpy as np

# Debian's Blender 3.4.1 glTF importer still uses `np.bool`, which numpy 1.24 (Debian 12's
# python3-numpy) removed: without this alias every .glb import fails with AttributeError.
if 'bool' not in np.__dict__:
    np.bool = bool


def load_peer(path):
    spec = importlib.util.spec_from_file_location("peer_blender_script", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def force_cpu_no_denoise(samples_expected):
    scene = bpy.context.scene
    scene.cycles.device = 'CPU'
    prefs = bpy.context.preferences.addons['cycles'].preferences
    prefs.compute_device_type = 'NONE'
    scene.cycles.use_denoising = False
    assert scene.cycles.samples == samples_expected, scene.cycles.samples


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    p = argparse.ArgumentParser()
    p.add_argument('--peer-script', required=True)
    p.add_argument('--recipe', choices=['trellis2', 'trellis'], required=True)
    p.add_argument('--object', required=True)
    p.add_argument('--transforms', required=True)
    p.add_argument('--out', required=True)
    p.add_argument('--size', type=int, default=1024)
    p.add_argument('--views', type=int, default=0, help='first N frames only (0: all)')
    a = p.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    peer = load_peer(a.peer_script)
    ours = json.load(open(a.transforms))
    frames = ours['frames'][:a.views] if a.views else ours['frames']
    np.random.seed(0)

    t0 = time.perf_counter()
    if a.recipe == 'trellis':
        # TRELLIS render.py main(): init_render first, then the scene.
        peer.init_render(engine='CYCLES', resolution=a.size, geo_mode=False)
        force_cpu_no_denoise(128)
        peer.init_scene()
        peer.load_object(a.object)
        scale, offset = peer.normalize_scene()
        cam = peer.init_camera()
        peer.init_lighting()
    else:
        # TRELLIS.2 render_cond.py main(): the scene, camera and white world, then init_render.
        peer.init_scene()
        peer.load_object(a.object)
        scale, offset = peer.normalize_scene()
        cam = peer.init_camera()
        peer.init_uniform_lighting()
        peer.init_render(engine='CYCLES', resolution=a.size)
        force_cpu_no_denoise(32)
    setup = time.perf_counter() - t0
    print(f"[bench] setup (import, normalise, lights, render settings) {setup:.2f} s; "
          f"scale {scale:.6g} (ours {ours['scale']:.6g}), offset {tuple(round(x, 5) for x in offset)} "
          f"(ours {tuple(round(x, 5) for x in ours['offset'])}); threads {bpy.context.scene.render.threads}",
          flush=True)

    record = {'setup_s': setup, 'scale': scale, 'offset': list(offset), 'frames': []}
    for i, frame in enumerate(frames):
        m = np.array(frame['transform_matrix'], dtype=float)
        location = m[:3, 3]
        fov = frame['camera_angle_x']
        if a.recipe == 'trellis2':
            peer.init_random_lighting(location / np.linalg.norm(location))
        cam.location = tuple(location)
        cam.data.lens = 16 / np.tan(fov / 2)
        bpy.context.scene.render.filepath = os.path.join(a.out, f'{i:03d}.png')
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        wall = time.perf_counter() - t
        bpy.context.view_layer.update()
        theirs = np.array(peer.get_transform_matrix(cam), dtype=float)
        delta = float(np.abs(theirs - m).max())
        print(f"[bench] frame {i:03d} wall {wall:.3f} s, camera max |delta| vs ours {delta:.2e}", flush=True)
        record['frames'].append({'file_path': f'{i:03d}.png', 'wall_s': wall, 'camera_delta': delta,
                                 'transform_matrix': theirs.tolist(), 'camera_angle_x': fov})
    with open(os.path.join(a.out, 'bench.json'), 'w') as f:
        json.dump(record, f, indent=1)


main()
