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

# the paper's section V-A on the twin: Table 4, before/after, cross-validation, error vs load
table4:
    cargo run --release -p robocal-ident --example paper_v_a

# the paper's section V-B on the twin: GA/GB splits, SOMM / MOSM / CA-SOMM, Tables 5 and 6
table5:
    cargo run --release -p robocal-residual --example paper_v_b

# the twin's error budget and how bimodal its residual is, beside the paper's (TWIN: a twin file)
twin-budget twin="configs/twin/pmc6va030.toml":
    cargo run --release -p robocal-residual --example twin_budget -- {{twin}}

# regenerate the bundled twin dataset (a test checks it matches byte for byte)
twin:
    cargo run --release -- simulate --twin configs/twin/pmc6va030.toml --out datasets/pmc6va030
