#!/usr/bin/env bash
# The project's test command (README "Quick start"): every suite, then a summary of each.
#
#   formatting  cargo fmt --check
#   build       cargo test --workspace --no-run with clippy's lints, warnings denied: the same
#               lints as `cargo clippy --all-targets -- -D warnings`, in the one build of the
#               test targets (below). It also makes target/debug/sparc3d, the binary every
#               later suite runs: no crate is compiled twice.
#   rust        cargo test --workspace: unit, end-to-end and doc tests
#   python      tests/python, in a virtual environment this script makes and keeps
#               ($SPARC3D_VENV, default .venv) with tests/python/requirements.txt (torch,
#               pymeshlab, ray, ...) and the packages ./python and, when present, ./vae
#   vae         vae/tests, when the folder exists
#   ray         tests/cluster/ray_e2e.sh: the Ray driver (ops/ray/) on a private loopback Ray
#   slurm       tests/cluster/slurm_e2e.sh: a real single-node Slurm (root: starts its daemons)
#
# The first run downloads about 2.5 GB of Python wheels into uv's cache (torch is PyPI's CUDA
# build, see tests/python/requirements.txt); later runs reuse the environment and touch the
# network only when a requirement or the Python packages changed.
#
# Environment:
#   SPARC3D_CI=1            every suite and every test must run: a skip is a failure (.ci/run)
#   SPARC3D_VENV=DIR        the virtual environment to use or make (default .venv)
#   SPARC3D_SLURM_TEST=0|1  leave out / run the Slurm suite (default: run when root)
#   SPARC3D_RAY_TEST=0      leave out the Ray suite
set -uo pipefail
cd "$(dirname "$0")"
ROOT=$PWD
CI_MODE=${SPARC3D_CI:-0}
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
LOGS=$TARGET/test-logs
BIN=$TARGET/debug/sparc3d
VENV=${SPARC3D_VENV:-$ROOT/.venv}
# The package installer, pinned: uv keeps downloaded wheels in its cache whatever the registry's
# cache headers say (pip's HTTP cache stored nothing from the registry this project's machines
# reach, which answers without them) and links them into a new environment in seconds.
UV_VERSION=0.13.9
mkdir -p "$LOGS"
trap 'echo "interrupted" >&2; exit 130' INT TERM

# --- bookkeeping: one row per suite, printed at the end ---------------------------------------
NAMES=() STATES=() DETAILS=() NOTES=()
N_PASSED=0 N_FAILED=0 N_SKIPPED=0
record() { # record NAME STATE DETAIL [NOTES...]: STATE is ok, FAILED or skipped
  NAMES+=("$1") STATES+=("$2") DETAILS+=("$3")
  local notes=""
  shift 3
  for n in "$@"; do notes+="$n"$'\n'; done
  NOTES+=("$notes")
}
section() { printf '\n==> %s\n' "$*"; }
since() { echo "$(($(date +%s) - $1))s"; }

check() { # check NAME COMMAND...: a suite that is one command, counted as one test
  local name=$1 t0 rc
  shift
  section "$name: $*"
  t0=$(date +%s)
  "$@"
  rc=$?
  if [[ $rc -eq 0 ]]; then
    record "$name" ok "$(since "$t0")"
    N_PASSED=$((N_PASSED + 1))
  else
    record "$name" FAILED "$(since "$t0"); exit $rc: see above"
    N_FAILED=$((N_FAILED + 1))
  fi
}

skip_suite() { # skip_suite NAME WHY: a suite that cannot run here (a failure under SPARC3D_CI=1)
  if [[ $CI_MODE == 1 ]]; then
    record "$1" FAILED "not run under SPARC3D_CI=1: $2"
    N_FAILED=$((N_FAILED + 1))
  else
    record "$1" skipped "$2"
    N_SKIPPED=$((N_SKIPPED + 1))
  fi
}

# --- Rust -------------------------------------------------------------------------------------
check formatting cargo fmt --all --check

# Clippy's lints while the tests build: clippy-driver is rustc with the lints added, so with
# it as the workspace's compiler wrapper one build both lints every target of the workspace
# (libraries, binaries, unit and integration tests, as `cargo clippy --all-targets` does) and
# makes the test binaries. `cargo clippy` would check every dependency a second time, in check
# mode, before `cargo test` compiles them. Dependencies do not go through the wrapper, so they
# are shared with any other dev build. CLIPPY_ARGS is how cargo-clippy hands clippy-driver
# the arguments after `--`: here `-D warnings`.
build() {
  local driver
  driver=$(rustup which clippy-driver 2>/dev/null || command -v clippy-driver) || {
    echo "no clippy-driver: rustup component add clippy" >&2
    return 1
  }
  RUSTC_WORKSPACE_WRAPPER=$driver CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__" \
    cargo "$@"
}

rust_tests() {
  local t0 rc log=$LOGS/rust.log
  section "build: cargo test --workspace --no-run, with clippy's lints (-D warnings)"
  t0=$(date +%s)
  # Built first on its own, so that a failed build (or a lint) is told apart from failed tests,
  # and later suites never run a stale binary; `cargo test` then compiles nothing more.
  if ! build test --workspace --no-run; then
    record build FAILED "$(since "$t0"); a compile error or a clippy lint: see above"
    record rust FAILED "not run: the build failed"
    N_FAILED=$((N_FAILED + 2))
    return
  fi
  BUILD_OK=1
  record build ok "$(since "$t0"); clippy clean"
  N_PASSED=$((N_PASSED + 1))
  section "rust: cargo test --workspace"
  t0=$(date +%s)
  build test --workspace 2>&1 | tee "$log"
  rc=${PIPESTATUS[0]}
  local passed failed ignored
  read -r passed failed ignored < <(awk '/^test result:/ {
      for (i = 2; i <= NF; i++) {
        if ($i ~ /^passed;?$/) p += $(i - 1)
        if ($i ~ /^failed;?$/) f += $(i - 1)
        if ($i ~ /^ignored;?$/) g += $(i - 1)
      }
    } END { print p + 0, f + 0, g + 0 }' "$log")
  N_PASSED=$((N_PASSED + passed)) N_SKIPPED=$((N_SKIPPED + ignored))
  local notes=()
  while IFS= read -r line; do
    notes+=("ignored by design (not run in CI): ${line#test }")
  done < <(grep -E '^test .* \.\.\. ignored' "$log" | sed 's/ \.\.\. ignored,\{0,1\}/:/')
  if [[ $rc -eq 0 ]]; then
    record rust ok "$passed passed, $failed failed, $ignored ignored ($(since "$t0"))" "${notes[@]}"
  else
    [[ $failed -gt 0 ]] || failed=1 # a crashed test binary has no result line
    N_FAILED=$((N_FAILED + failed))
    record rust FAILED "$passed passed, $failed failed, $ignored ignored ($(since "$t0")): see $log" "${notes[@]}"
  fi
}
BUILD_OK=0
rust_tests

# --- Python -----------------------------------------------------------------------------------
python_inputs() { # what the environment is made from: a change means installing again
  echo "uv $UV_VERSION"
  cat tests/python/requirements.txt tests/python/excludes.txt
  find python vae -type f ! -path '*/__pycache__/*' ! -path '*.egg-info/*' ! -path '*/build/*' \
    ! -path 'vae/tests/*' -print0 2>/dev/null | sort -z | xargs -0 -r sha256sum
}

venv_setup() {
  local py=$VENV/bin/python stamp=$VENV/.sparc3d-inputs digest
  if [[ ! -x $py ]]; then
    python3 -m venv "$VENV" || return 1
  fi
  digest=$(python_inputs | sha256sum | cut -d' ' -f1)
  if [[ -f $stamp && $(cat "$stamp") == "$digest" ]]; then
    echo "up to date ($VENV)"
    return 0
  fi
  echo "installing tests/python/requirements.txt, ./python$([[ -f vae/pyproject.toml ]] && echo ' and ./vae') into $VENV"
  local pkgs=(./python)
  [[ -f vae/pyproject.toml ]] && pkgs+=(./vae)
  "$py" -m pip install -q "uv==$UV_VERSION" || return 1
  local uv=("$VENV/bin/uv" pip install -q --python "$py")
  "${uv[@]}" --excludes tests/python/excludes.txt -r tests/python/requirements.txt "${pkgs[@]}" || return 1
  # The project's own packages again, rebuilt: an edited module does not change their version.
  "${uv[@]}" --no-deps --reinstall "${pkgs[@]}" || return 1
  echo "$digest" >"$stamp"
}

pytest_suite() { # pytest_suite NAME DIR
  local name=$1 dir=$2 t0 rc xml=$LOGS/$1.xml
  section "$name: pytest $dir"
  t0=$(date +%s)
  rm -f "$xml"
  # -rfEs: failures, errors and skips with their reasons at the end
  PATH="$VENV/bin:$PATH" SPARC3D_BIN=$BIN "$VENV/bin/python" -m pytest -rfEs --junitxml "$xml" "$dir"
  rc=$?
  if [[ $rc -eq 5 ]]; then
    record "$name" ok "no tests in $dir"
    return
  fi
  if [[ ! -f $xml ]]; then
    record "$name" FAILED "pytest exited $rc without a report"
    N_FAILED=$((N_FAILED + 1))
    return
  fi
  local counts passed failed skipped reasons=()
  counts=$("$VENV/bin/python" - "$xml" <<'EOF'
import sys
import xml.etree.ElementTree as ET

passed = failed = 0
skips = []
for case in ET.parse(sys.argv[1]).getroot().iter("testcase"):
    name = "::".join(p for p in (case.get("classname"), case.get("name")) if p)
    skipped = case.find("skipped")
    if skipped is not None:
        skips.append(f"{name}: {skipped.get('message', '')}".replace("\n", " "))
    elif case.find("failure") is not None or case.find("error") is not None:
        failed += 1
    else:
        passed += 1
print(passed, failed, len(skips))
for s in skips:
    print(s)
EOF
  ) || counts="0 1 0"
  read -r passed failed skipped <<<"$(head -n1 <<<"$counts")"
  while IFS= read -r line; do [[ -n $line ]] && reasons+=("skipped: $line"); done < <(tail -n +2 <<<"$counts")
  N_PASSED=$((N_PASSED + passed))
  local detail="$passed passed, $failed failed, $skipped skipped ($(since "$t0"))"
  if [[ $rc -ne 0 || $failed -gt 0 ]]; then
    [[ $failed -gt 0 ]] || failed=1
    N_FAILED=$((N_FAILED + failed)) N_SKIPPED=$((N_SKIPPED + skipped))
    record "$name" FAILED "$detail" "${reasons[@]}"
  elif [[ $skipped -gt 0 && $CI_MODE == 1 ]]; then
    N_FAILED=$((N_FAILED + skipped))
    record "$name" FAILED "$detail; under SPARC3D_CI=1 a skip is a failure" "${reasons[@]}"
  else
    N_SKIPPED=$((N_SKIPPED + skipped))
    record "$name" ok "$detail" "${reasons[@]}"
  fi
}

section "python environment: $VENV"
VENV_OK=0
t0=$(date +%s)
if venv_setup; then
  VENV_OK=1
  echo "ready in $(since "$t0")"
fi
PY_SUITES=(python)
[[ -d vae/tests ]] && PY_SUITES+=(vae)
for suite in "${PY_SUITES[@]}"; do
  dir=tests/python
  [[ $suite == vae ]] && dir=vae/tests
  if [[ $BUILD_OK != 1 ]]; then
    record "$suite" FAILED "not run: the build failed"
    N_FAILED=$((N_FAILED + 1))
  elif [[ $VENV_OK != 1 ]]; then
    record "$suite" FAILED "not run: installing the Python environment failed (see above)"
    N_FAILED=$((N_FAILED + 1))
  else
    pytest_suite "$suite" "$dir"
  fi
done

# --- clusters ---------------------------------------------------------------------------------
if [[ ${SPARC3D_RAY_TEST:-1} == 0 ]]; then
  skip_suite ray "SPARC3D_RAY_TEST=0 (unset it to run tests/cluster/ray_e2e.sh)"
elif [[ $BUILD_OK != 1 || $VENV_OK != 1 ]]; then
  record ray FAILED "not run: the build or the Python environment failed"
  N_FAILED=$((N_FAILED + 1))
else
  check ray env PATH="$VENV/bin:$PATH" SPARC3D_BIN="$BIN" tests/cluster/ray_e2e.sh
fi

if [[ ${SPARC3D_SLURM_TEST:-} == 0 ]]; then
  skip_suite slurm "SPARC3D_SLURM_TEST=0 (unset it, as root, to run tests/cluster/slurm_e2e.sh)"
elif [[ $(id -u) -ne 0 ]]; then
  skip_suite slurm "needs root: it installs Debian's slurm packages and starts munged, slurmctld and slurmd (sudo ./test.sh, or as root: SPARC3D_BIN=$BIN tests/cluster/slurm_e2e.sh)"
elif [[ $BUILD_OK != 1 ]]; then
  record slurm FAILED "not run: the build failed"
  N_FAILED=$((N_FAILED + 1))
else
  check slurm env SPARC3D_BIN="$BIN" tests/cluster/slurm_e2e.sh
fi

# --- summary ----------------------------------------------------------------------------------
section "summary$([[ $CI_MODE == 1 ]] && echo ' (SPARC3D_CI=1: every suite must run)')"
for i in "${!NAMES[@]}"; do
  printf '  %-11s %-8s %s\n' "${NAMES[$i]}" "${STATES[$i]}" "${DETAILS[$i]}"
  while IFS= read -r note; do
    [[ -n $note ]] && printf '  %-11s %-8s   %s\n' "" "" "$note"
  done <<<"${NOTES[$i]}"
done
echo "total: $N_PASSED passed, $N_FAILED failed, $N_SKIPPED skipped"
[[ $N_FAILED -eq 0 ]]
