#!/usr/bin/env bash
# The project's test command (README "Quick start"): formatting, lints, then every test.
set -euo pipefail
cd "$(dirname "$0")"
cargo fmt --all --check
cargo clippy --all-targets -- -D warnings
cargo test --workspace 2>&1
PY="${PYTHON:-python3}"
if [ -x .venv/bin/python ] && [ -z "${PYTHON:-}" ]; then PY=.venv/bin/python; fi
# pytest_if DIR IMPORTS REQUIRED INSTALL: run DIR's tests when IMPORTS import; otherwise fail
# when REQUIRED is 1 (CI), else say what to install.
pytest_if() {
  if "$PY" -c "import $2" 2>/dev/null; then
    cargo build -p sparc3d
    "$PY" -m pytest -q "$1"
  elif [ "$3" = "1" ]; then
    echo "$1 needs $2 ($4)" >&2
    exit 1
  else
    echo "skipping $1 ($4 to run it)" >&2
  fi
}
# The shard format as Python reads it (docs/FORMAT.md); CI sets SPARC3D_REQUIRE_PYTHON=1.
pytest_if tests/python "pyarrow, numpy, pytest" "${SPARC3D_REQUIRE_PYTHON:-0}" \
  "pip install -r tests/python/requirements.txt"
# The VAE (vae/, docs/VAE.md; about 3 minutes on 2 cores); CI sets SPARC3D_REQUIRE_TORCH=1.
pytest_if vae/tests "torch, trimesh, sparc3d_vae" "${SPARC3D_REQUIRE_TORCH:-0}" \
  "pip install ./python ./vae"
# Cluster runs on a real Slurm (root, apt; about 2 minutes): .ci/run sets SPARC3D_SLURM_TEST=1.
if [[ ${SPARC3D_SLURM_TEST:-0} == 1 ]]; then
  tests/cluster/slurm_e2e.sh
fi
