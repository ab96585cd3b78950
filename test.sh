#!/usr/bin/env bash
# The project's test command (README "Quick start"): formatting, lints, then every test.
set -euo pipefail
cd "$(dirname "$0")"
cargo fmt --all --check
cargo clippy --all-targets -- -D warnings
cargo test --workspace 2>&1
