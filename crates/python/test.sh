#!/usr/bin/env bash
# Build the Python wheel with maturin and run the pytest suite, in a venv
# under target/ (created on first use; needs python3 ≥ 3.9 with venv and
# pip, and PyPI for maturin, numpy and pytest). The CLI is built too: the
# suite compares its meshes with the command line's.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="$root/target/python-venv"
wheels="$root/target/python-wheels"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.9,<2" numpy pytest
cargo build --release --locked -p surfrecon-cli
rm -rf "$wheels"
"$venv/bin/maturin" build --release --locked -q \
    -m "$root/crates/python/Cargo.toml" -i "$venv/bin/python" -o "$wheels"
"$venv/bin/python" -m pip install -q --disable-pip-version-check \
    --force-reinstall --no-deps "$wheels"/surfrecon-*.whl
cd "$root"
SURFRECON_CLI="$root/target/release/surfrecon" "$venv/bin/python" -m pytest -q crates/python/tests "$@"
