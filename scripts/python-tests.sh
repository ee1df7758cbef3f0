#!/usr/bin/env bash
# The Python bindings' tests (crates/robocal-py/tests): a venv in target/pyvenv with maturin,
# numpy and pytest from PyPI, the extension built as a wheel (dev profile: it shares target/ with
# cargo) and installed, then pytest against the command-line binary built here. Arguments go
# to pytest (`-k several`).
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/pyvenv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.9,<2" "numpy>=1.21" "pytest>=7"
cargo build --bin robocal
rm -rf target/wheels-test
"$venv/bin/maturin" build --quiet -m crates/robocal-py/Cargo.toml --profile dev -o target/wheels-test
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels-test/robocal-*.whl
ROBOCAL_BIN="$PWD/target/debug/robocal" "$venv/bin/python" -m pytest -q crates/robocal-py/tests "$@"
