# Everyday recipes. The README's commands work without `just`.

default:
    @just --list

# the tests (the README's test command)
test:
    cargo test --workspace

# formatting and lints, as CI runs them
lint:
    python3 scripts/import-cycles.py
    cargo fmt --all --check
    cargo clippy --workspace --all-targets -- -D warnings

# divan benchmarks
bench:
    cargo bench --workspace

# API documentation
doc:
    cargo doc --workspace --no-deps

# the main job: the paper's sections V-A and V-B on the bundled twin, every table and figure,
# report in reports/paper/ (the README's first command)
reproduce:
    cargo run --release -- run configs/experiments/paper.toml

# section V-A: Table 4, before/after kinematic calibration, cross-validation (reports/table4/)
table4:
    cargo run --release -- run configs/experiments/table4.toml

# Table 5: BFGS + SOMM on training, validation and test (reports/table5/)
table5:
    cargo run --release -- run configs/experiments/table5.toml

# Table 6: before, BFGS, BFGS + SOMM, BFGS + CA-SOMM on the 840 GB10 + GB30 rows (reports/table6/)
table6:
    cargo run --release -- run configs/experiments/table6.toml

# any experiment file, e.g. `just run configs/experiments/paper.toml`
run experiment:
    cargo run --release -- run {{experiment}}

# the twin's error budget and how bimodal its residual is, beside the paper's (TWIN: a twin file)
twin-budget twin="configs/twin/pmc6va030.toml":
    cargo run --release -p robocal-residual --example twin_budget -- {{twin}}

# regenerate the bundled twin dataset (a test checks it matches byte for byte)
twin:
    cargo run --release -- simulate --twin configs/twin/pmc6va030.toml --out datasets/pmc6va030

# fuzz the CSV and TOML loaders (proptest): CASES generated inputs per target, release build
fuzz cases="20000":
    PROPTEST_CASES={{cases}} cargo test --release --test fuzz_loaders

# the accuracy suite: default calibrate and each stage on twins of fourteen arms (two seeds, effects
# all on / modelled only / beyond the model family, configuration and extrapolation splits;
# `--effects` picks sets when run by hand), errors against the twins'
# noise-free points; the nine families kept aside (ARM6S, ARM6H, ARM6C, ARM6M, ARM6N, ARM6U,
# ARM6K, ARM6W, ARM6T) only with aside="--aside"
# (docs/accuracy.md)
accuracy seeds="2" aside="":
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds {{seeds}} {{aside}}

# writes docs/accuracy.md's table of the default against each stage alone (development twins, seed 0, beyond the model)
accuracy-docs:
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds 1 --effects beyond --no-compensation --write docs/accuracy.md

# the outside pipeline (scipy LM, then a scikit-learn MLP per axis on sin/cos of the joints and the
# load; scripts/peer/lm_mlp.py, independent of robocal) against robocal's default calibrate through
# the files, on the accuracy suite's cases; rewrites docs/accuracy.md's development table (or, with
# aside="--aside", the families kept aside); a venv with numpy, scipy and scikit-learn in target/peervenv
peer seeds="2" aside="":
    cargo build --release --bin robocal
    rm -rf target/peer-cases
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds {{seeds}} {{aside}} --export target/peer-cases
    test -x target/peervenv/bin/python || python3 -m venv target/peervenv
    target/peervenv/bin/pip install -q numpy scipy scikit-learn
    target/peervenv/bin/python scripts/peer/lm_mlp.py target/peer-cases --robocal target/release/robocal --write docs/accuracy.md --section {{ if aside == "" { "twins-peer-development" } else { "twins-peer-aside" } }}

# robocal on the real arms of datasets/ (UR5, WAM, UR10) on fixed splits: nominal, kinematic, the
# default with its time and memory, the peer and the published number; rewrites docs/accuracy.md's
# real-arms table (aside="--aside" adds UR10 Series B, kept aside while developing)
accuracy-real aside="":
    cargo build --release --bin robocal
    test -x target/peervenv/bin/python || python3 -m venv target/peervenv
    target/peervenv/bin/pip install -q numpy scipy scikit-learn
    target/peervenv/bin/python scripts/real/benchmark.py --robocal target/release/robocal --write docs/accuracy.md {{aside}}

# a network's seed and five networks averaged (members = 5) on one stage physics, through the
# files, on the development suite's cases beyond the model
network-seeds seeds="2" effects="all,beyond":
    cargo build --release --bin robocal
    rm -rf target/seed-cases
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds {{seeds}} --arms pmc6va030,arm7,arm5 --effects {{effects}} --export target/seed-cases
    python3 scripts/network_seeds.py target/seed-cases --robocal target/release/robocal

# bad shots: clean rows in robust σ, 1-3 shots of 20-50 mm named, the held-out change
accuracy-outliers seeds="3":
    cargo run --release -p robocal-pipeline --example accuracy -- --outliers --seeds {{seeds}}

# how far the model carries across a cell: each development twin's poses laid all around its base,
# trained within -60..30 deg of joint 1, tested on every other pose
accuracy-window seeds="1" effects="all,beyond":
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds {{seeds}} --arms arm7,arm5,pmc6va030 --splits window --effects {{effects}} --no-compensation

# what the data determine beyond joint 1's readings: on the window twins, the default, its physics
# alone, the physics with every harmonic continued, and that model's standard deviation against
# the noise floor (scripts/extrapolation/reach.py)
extrapolation-reach seeds="1" effects="all":
    cargo build --release --bin robocal
    rm -rf target/reach-cases
    cargo run --release -p robocal-pipeline --example accuracy -- --seeds {{seeds}} --arms arm7,arm5,pmc6va030 --splits window --effects {{effects}} --export target/reach-cases
    python3 scripts/extrapolation/reach.py target/reach-cases --robocal target/release/robocal

# the residual models side by side on the identified physics (paper's SOMM, robocal's, GP)
accuracy-networks seeds="1":
    cargo run --release -p robocal-pipeline --example accuracy -- --networks --seeds {{seeds}}

# CA-SOMM against the twin's truth: how often the paper's classes agree with the joint-4 flank,
# what oracle classes would give, how robocal's gate routes the Table 6 rows (docs/method.md)
casomm-ceiling:
    cargo run --release -p robocal-pipeline --example casomm_ceiling

# what a plan buys: planned against random pose sets on three twins, predicted against
# measured error (docs/accuracy.md, "Planned poses")
plan-benefit seeds="2":
    cargo run --release -p robocal-pipeline --example plan_benefit -- --seeds {{seeds}}

# the pictures of a calibration (docs/guide.md section 4): calibrate the bundled twin on the
# configurations whose number is not a multiple of 5, report on the others (held out), into
# reports/own/ (model/, fit/ for the training rows, held-out/)
report-example:
    mkdir -p reports/own
    awk -F, 'NR == 1 { print > "reports/own/train.csv"; print > "reports/own/test.csv"; next } { n = substr($1, 2) + 0; print > (n % 5 == 0 ? "reports/own/test.csv" : "reports/own/train.csv") }' datasets/pmc6va030/measurements.csv
    cargo run --release -- calibrate --robot configs/robots/pmc6va030.toml --data reports/own/train.csv --out reports/own/model --report reports/own/fit
    cargo run --release -- report --model reports/own/model --data reports/own/test.csv --out reports/own/held-out

# what three reflectors per pose buy (docs/accuracy.md "Several reflectors"): K random
# configurations calibrated from one reflector and from three, the error left on 48 never measured
reflectors seeds="10":
    cargo run --release -p robocal-pipeline --example reflectors -- --seeds {{seeds}}

# what a 6-DoF probe's orientations buy (docs/accuracy.md "A 6-DoF probe"): K random
# configurations calibrated from positions alone and with orientations, the error left on 48
# never measured (position and orientation, against the twin's truth)
probe seeds="5":
    cargo run --release -p robocal-pipeline --example probe -- --seeds {{seeds}}
