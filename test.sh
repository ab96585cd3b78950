#!/usr/bin/env bash
# The project's test command (README "Quick start"): formatting, lints, then every test.
set -euo pipefail
cd "$(dirname "$0")"
cargo fmt --all --check
cargo clippy --all-targets -- -D warnings
cargo test --workspace 2>&1
# The shard format as Python reads it (docs/FORMAT.md): needs pyarrow, numpy and pytest
# (`pip install -r tests/python/requirements.txt`); CI sets SPARC3D_REQUIRE_PYTHON=1.
PY="${PYTHON:-python3}"
if [ -x .venv/bin/python ] && [ -z "${PYTHON:-}" ]; then PY=.venv/bin/python; fi
if "$PY" -c "import pyarrow, numpy, pytest" 2>/dev/null; then
  cargo build -p sparc3d
  "$PY" -m pytest -q tests/python
elif [ "${SPARC3D_REQUIRE_PYTHON:-0}" = "1" ]; then
  echo "tests/python needs pyarrow, numpy and pytest" >&2
  exit 1
else
  echo "skipping tests/python (pip install -r tests/python/requirements.txt to run it)" >&2
fi
# The VAE (vae/, docs/VAE.md): needs torch and trimesh (`pip install ./python ./vae trimesh`);
# CI sets SPARC3D_REQUIRE_TORCH=1. About 2 minutes on 2 cores.
if "$PY" -c "import torch, trimesh, sparc3d_vae" 2>/dev/null; then
  cargo build -p sparc3d
  "$PY" -m pytest -q vae/tests
elif [ "${SPARC3D_REQUIRE_TORCH:-0}" = "1" ]; then
  echo "vae/tests needs torch, trimesh and sparc3d-vae (pip install ./python ./vae)" >&2
  exit 1
else
  echo "skipping vae/tests (pip install ./python ./vae to run it)" >&2
fi
# Cluster runs on a real Slurm (root, apt; about 2 minutes): .ci/run sets SPARC3D_SLURM_TEST=1.
if [[ ${SPARC3D_SLURM_TEST:-0} == 1 ]]; then
  tests/cluster/slurm_e2e.sh
fi
