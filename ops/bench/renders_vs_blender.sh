#!/usr/bin/env bash
# Condition renders side by side with the peers' own Blender scripts (issue 61, docs/RENDERS.md
# "Side by side with Blender"), in one run on this machine's CPU.
#
# What it measures, for each asset given (default: the three examples):
#   - Blender running TRELLIS.2's data_toolkit/blender_script/render_cond.py with its settings
#     (Cycles, 32 samples, box filter 1 px, 1 diffuse / 1 glossy bounce, 1024², transparent film)
#     and TRELLIS's dataset_toolkits/blender_script/render.py (the same with 128 samples and its
#     three-light rig), VIEWS views each, with OUR cameras (ops/bench/renders_vs_blender.py: it
#     loads their script as a module and runs what its main() does with their own functions,
#     placing the camera from our transforms.json, so the pictures share cameras);
#   - `sparc3d render ASSET --for trellis2|trellis --views VIEWS --size 1024`;
#   - memory: `/usr/bin/time -v` max RSS of that `sparc3d render` against that of
#     `sparc3d convert ASSET -o x.ply --resolution 1024` (the item's conversion peak).
# Seconds a view, start-up excluded on both sides:
#   - Blender: its own per-frame line " Time: MM:SS.ss (Saving: MM:SS.ss)" (Time counts the
#     save, so a view is Time − Saving: the scene sync, BVH build and path tracing that its
#     script pays on every bpy.ops.render.render); the first frame is skipped (it carries the
#     one-off shader/kernel loading and the first PNG save's initialisation), so the mean is
#     over frames 2..VIEWS. Blender's start, the import and normalize_scene are before
#     frame 1 and so excluded. Its sampling alone (from "Sample 0/N" to "Finished" in the same
#     log) is printed as well.
#   - ours: the per-view time `sparc3d render` prints (tracing only: reading the mesh, building
#     its BVH once and encoding the PNGs excluded).
# The speed targets of issue 61: ≥ 10× TRELLIS.2's script, ≥ 40× TRELLIS's; memory ≤ 1.5×.
#
# Installing Debian's Blender (Debian 12: 3.4.1), as root:
#   DEBIAN_FRONTEND=noninteractive apt-get install -y blender python3-numpy python3-pil
# python3-numpy is not pulled in by the blender package but the peers' scripts import numpy;
# python3-pil is for the side-by-side pictures (PICTURES=DIR). Debian's Blender 3.4.1 glTF importer
# still calls `np.bool`, which Debian 12's numpy 1.24 removed: the driver aliases it, without
# which every .glb fails to import. Debian's build has no OpenImageDenoiser.
#
# The peers' scripts: cloned from GitHub at the pinned commits below, or read from existing
# clones / bare mirrors given as TRELLIS_REPO and TRELLIS2_REPO (any git dir holding the commit).
# How they pick the GPU, and what the driver overrides after their init_render() runs:
#   TRELLIS.2 render_cond.py init_render():  bpy.context.scene.cycles.device = 'GPU'
#                                            ...cycles.use_denoising = True
#                                            ...preferences.compute_device_type = 'CUDA'
#   TRELLIS   render.py       init_render(): the same three lines (samples 128 instead of 32).
#   Overridden to: cycles.device = 'CPU'; preferences.compute_device_type = 'NONE';
#   cycles.use_denoising = False (denoising off on both sides: ours has none). Everything else is
#   theirs, unpatched. Cycles uses all cores (render.threads = nproc); so does `sparc3d render`.
#
# Usage: ops/bench/renders_vs_blender.sh [ASSET ...]
#   env: VIEWS (4), SIZE (1024), RECIPES ("trellis2 trellis"), WORK (/tmp/blender_bench/run),
#        SPARC3D (target/release/sparc3d), BLENDER (blender), PYTHON (/usr/bin/python3, for the
#        pictures), PICTURES (a folder: one side-by-side PNG an asset, views PICTURE_VIEWS "0 1",
#        TRELLIS.2 settings, 256 px a picture), TRELLIS_REPO, TRELLIS2_REPO.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
TRELLIS_COMMIT=6b0d64751ad54d9c32d7b05fec482eb29178f56f   # microsoft/TRELLIS, 2025-08-05
TRELLIS2_COMMIT=5565d240c4a494caaf9ece7a554542b76ffa36d3  # microsoft/TRELLIS.2, 2026-01-10
VIEWS=${VIEWS:-4}
SIZE=${SIZE:-1024}
RECIPES=${RECIPES:-trellis2 trellis}
WORK=${WORK:-/tmp/blender_bench/run}
SPARC3D=$(python3 "$HERE/benchlib.py" binary "${SPARC3D:-}")
BLENDER=${BLENDER:-blender}
PYTHON=${PYTHON:-/usr/bin/python3}
PICTURE_VIEWS=${PICTURE_VIEWS:-0 1}
if [ $# -gt 0 ]; then ASSETS=("$@"); else
  ASSETS=("$ROOT/examples/box_textured.glb" "$ROOT/examples/sphere.obj" "$ROOT/examples/wuson.stl")
fi
mkdir -p "$WORK/peers"

# The peers' Blender scripts at the pinned commits.
peer() { # peer REPO_VAR_VALUE GITHUB_NAME COMMIT PATH OUT
  local repo=$1 name=$2 commit=$3 path=$4 out=$5
  if [ -z "$repo" ]; then
    repo="$WORK/src/$name"
    [ -d "$repo" ] || git clone -q "https://github.com/microsoft/$name" "$repo"
  fi
  git -C "$repo" show "$commit:$path" > "$out"
}
peer "${TRELLIS2_REPO:-}" TRELLIS.2 $TRELLIS2_COMMIT data_toolkit/blender_script/render_cond.py "$WORK/peers/trellis2.py"
peer "${TRELLIS_REPO:-}" TRELLIS $TRELLIS_COMMIT dataset_toolkits/blender_script/render.py "$WORK/peers/trellis.py"

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $("$BLENDER" --version 2>/dev/null | head -1)"
echo "load before: $(uptime)"

maxrss() { awk -F': ' '/Maximum resident set size/ {print $2}' "$1"; }
ROWS="$WORK/rows.tsv"
: > "$ROWS"
for asset in "${ASSETS[@]}"; do
  name=$(basename "${asset%.*}")
  dir="$WORK/$name"
  rm -rf "$dir"; mkdir -p "$dir"
  /usr/bin/time -v "$SPARC3D" convert "$asset" -o "$dir/x.ply" --resolution 1024 > "$dir/convert.out" 2> "$dir/convert.time"
  conv_kb=$(maxrss "$dir/convert.time")
  for recipe in $RECIPES; do
    mkdir -p "$dir/$recipe"
    /usr/bin/time -v "$SPARC3D" render "$asset" -o "$dir/$recipe/ours" --for "$recipe" \
      --views "$VIEWS" --size "$SIZE" 2> "$dir/$recipe/ours.time" || { cat "$dir/$recipe/ours.time"; exit 1; }
    ours_s=$(sed -n 's/.*(\([0-9.]*\) s a view).*/\1/p' "$dir/$recipe/ours.time")
    ours_kb=$(maxrss "$dir/$recipe/ours.time")
    bl_rc=0
    "$BLENDER" --background --factory-startup --python "$HERE/renders_vs_blender.py" -- \
      --peer-script "$WORK/peers/$recipe.py" --recipe "$recipe" --object "$asset" \
      --transforms "$dir/$recipe/ours/transforms.json" --out "$dir/$recipe/blender" --size "$SIZE" \
      > "$dir/$recipe/blender.log" 2>&1 || bl_rc=$?
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$recipe" "$dir/$recipe/blender.log" "$bl_rc" \
      "$ours_s" "$ours_kb" "$conv_kb" >> "$ROWS"
    echo "done: $name $recipe (blender rc $bl_rc)" >&2
  done
done
echo "load after: $(uptime)"

python3 - "$ROWS" "$VIEWS" "$SIZE" <<'PY' | tee "$WORK/table.md"
import re, sys
rows, views, size = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
target = {'trellis2': 10, 'trellis': 40}
samples = {'trellis2': 32, 'trellis': 128}
def secs(t):  # [HH:]MM:SS.ss
    s = 0.0
    for part in t.split(':'):
        s = s * 60 + float(part)
    return s
print(f"{views} views of {size}², Blender s/view = mean of frames 2..{views} (Time − Saving); "
      f"ours = `sparc3d render`'s per-view time\n")
print("| asset | recipe (Blender samples) | Blender s/view | Blender sampling only | ours s/view | ratio | target | "
      "ours render RSS | convert RSS (1024) | memory ratio |")
print("|---|---|---:|---:|---:|---:|---|---:|---:|---:|")
for line in open(rows):
    name, recipe, log, rc, ours_s, ours_kb, conv_kb = line.rstrip('\n').split('\t')
    frames, start, finished = [], 0.0, 0.0
    for l in open(log, errors='replace'):
        m = re.search(r'\| Time:([\d:.]+) \|.*\| Sample 0/', l)
        if m: start = secs(m.group(1))
        m = re.search(r'\| Time:([\d:.]+) \|.*\| Finished', l)
        if m: finished = secs(m.group(1))
        m = re.match(r'\s*Time: ([\d:.]+) \(Saving: ([\d:.]+)\)', l)
        if m:
            frames.append((secs(m.group(1)) - secs(m.group(2)), finished - start))
    mem = int(ours_kb) / int(conv_kb)
    memory = f"{int(ours_kb)/1024:.0f} MB | {int(conv_kb)/1024:.0f} MB | {mem:.2f} {'≤' if mem <= 1.5 else '>'} 1.5"
    if rc != '0' or len(frames) < 2:
        print(f"| {name} | {recipe} ({samples[recipe]}) | failed (rc {rc}, {len(frames)} frames; {log}) | | {float(ours_s):.3f} | | | {memory} |")
        continue
    timed = frames[1:]
    bl = sum(f[0] for f in timed) / len(timed)
    sampling = sum(f[1] for f in timed) / len(timed)
    ratio = bl / float(ours_s)
    met = 'met' if ratio >= target[recipe] else 'NOT met'
    print(f"| {name} | {recipe} ({samples[recipe]}) | {bl:.2f} | {sampling:.2f} | {float(ours_s):.3f} | "
          f"{ratio:.0f}× | ≥ {target[recipe]}×: {met} | {memory} |")
PY

# Side-by-side pictures: Blender (TRELLIS.2's settings) | ours, same camera, on white, 256 px each.
if [ -n "${PICTURES:-}" ]; then
  mkdir -p "$PICTURES"
  for asset in "${ASSETS[@]}"; do
    name=$(basename "${asset%.*}")
    "$PYTHON" - "$WORK/$name/trellis2" "$PICTURES/renders_vs_blender_$name.png" $PICTURE_VIEWS <<'PY'
import sys
from PIL import Image, ImageDraw
src, out, views = sys.argv[1], sys.argv[2], [int(v) for v in sys.argv[3:]]
side, label = 256, 14
sheet = Image.new('RGB', (2 * side * len(views), side + label), 'white')
draw = ImageDraw.Draw(sheet)
for k, v in enumerate(views):
    for j, who in enumerate(['blender', 'ours']):
        im = Image.open(f'{src}/{who}/{v:03d}.png').convert('RGBA')
        white = Image.new('RGBA', im.size, 'white')
        white.alpha_composite(im)
        x = (2 * k + j) * side
        sheet.paste(white.convert('RGB').resize((side, side), Image.LANCZOS), (x, label))
        text = (f'Blender, TRELLIS.2 script · {v:03d}' if who == 'blender' else f'sparc3d render · {v:03d}')
        draw.text((x + 4, 1), text, fill=(0, 0, 0))
sheet.quantize(colors=256, method=Image.MEDIANCUT, dither=Image.NONE).save(out, optimize=True)
print(out)
PY
  done
fi
