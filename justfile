# Everyday recipes. The README's commands work without `just`.

default:
    @just --list

# the tests (the README's test command)
test:
    cargo test --workspace

# formatting and lints, as CI runs them
lint:
    cargo fmt --all --check
    cargo clippy --workspace --all-targets -- -D warnings

# divan benchmarks
bench:
    cargo bench --workspace

# API documentation
doc:
    cargo doc --workspace --no-deps
