#!/usr/bin/env bash
# Records every CLI output on the bundled data (stdout, stderr, exit status and every file
# written), timings masked, so that a refactor can be checked byte for byte:
#
#   scripts/cli-snapshot.sh target/release/robocal /tmp/before   # on the old commit
#   scripts/cli-snapshot.sh target/release/robocal /tmp/after    # on the new one
#   diff -r /tmp/before /tmp/after && echo identical
#
# The training file is every 3rd configuration of the bundled twin at 4 loads (small enough for
# seconds per calibration); the check file another 24 configurations at 2 other loads.
set -uo pipefail
bin=$(realpath "$1")
out=$2
root=$(cd "$(dirname "$0")/.." && pwd)
rm -rf "$out"
mkdir -p "$out/in"
data="$root/datasets/pmc6va030/measurements.csv"
robot="$root/configs/robots/pmc6va030.toml"
cd "$out"
# Configurations by their rank in the file: training every 3rd, check every 7th (from the second).
awk -F, 'NR == 1 { print; next } { if (!($1 in rank)) rank[$1] = n++; r = rank[$1]
  if (r % 3 == 0 && ($8 == 0 || $8 == 5 || $8 == 10 || $8 == 20)) print }' "$data" > in/train.csv
awk -F, 'NR == 1 { print; next } { if (!($1 in rank)) rank[$1] = n++; r = rank[$1]
  if (r % 7 == 1 && ($8 == 2 || $8 == 15)) print }' "$data" > in/check.csv
# Targets: the check rows' measured points, the seed their own command.
awk -F, 'NR == 1 { print "id,q1,q2,q3,q4,q5,q6,load,x,y,z"; next } NR <= 13 { $1 = "t" NR; print }' OFS=, in/check.csv > in/targets.csv
printf 'pose,q1,q2,q3,q4,q5,q6,load,x,y,z\nbad,1,2,3,4,5,not-a-number,0,1,2,3\n' > in/bad.csv

mask() {
  # Timings and the temporary directory's name are not behaviour.
  sed -E -e 's/"([a-z_]*_s|[a-z_]*seconds)": [0-9.e+-]+/"\1": T/g' \
    -e 's/[0-9]+(\.[0-9]+)? ?(s|ms|µs)\b/T/g' "$@"
}
step() {
  local name=$1
  shift
  "$@" > "$name.stdout" 2> "$name.stderr"
  echo $? > "$name.exit"
  mask -i "$name.stdout" "$name.stderr"
}

step calibrate-default "$bin" calibrate --robot "$robot" --data in/train.csv --validate in/check.csv --out m-default
for stage in kinematic-lm kinematic-bfgs compliance physics somm mosm ca-somm gp; do
  step "calibrate-$stage" "$bin" calibrate --robot "$robot" --data in/train.csv --validate in/check.csv \
    --out "m-$stage" --config "$root/configs/stages/$stage.toml"
done
for m in m-*; do
  step "predict-$m" "$bin" predict --model "$m" --data in/check.csv --out "$m.pred.csv"
  step "evaluate-$m" "$bin" evaluate --model "$m" --data in/check.csv
  step "evaluate-json-$m" "$bin" evaluate --model "$m" --data in/check.csv --json
  step "compensate-$m" "$bin" compensate --model "$m" --targets in/targets.csv --out "$m.commands.csv"
done
step predict-sigma "$bin" predict --model m-gp --data in/check.csv --out gp.sigma.csv --sigma
step predict-sigma-nogp "$bin" predict --model m-somm --data in/check.csv --out nogp.csv --sigma
step predict-robot "$bin" predict --robot "$robot" --data in/check.csv --out robot.pred.csv
step evaluate-robot "$bin" evaluate --robot "$robot" --data in/check.csv
step evaluate-missing "$bin" evaluate --model no-such-dir --data in/check.csv
mkdir -p not-a-model
step evaluate-not-model "$bin" evaluate --model not-a-model --data in/check.csv
cp -r m-somm m-future && sed -i 's/"model_format": 1/"model_format": 9/' m-future/report.json
step evaluate-future "$bin" evaluate --model m-future --data in/check.csv
step calibrate-bad "$bin" calibrate --robot "$robot" --data in/bad.csv --out m-bad
printf '[kinematic]\nsolver = "gn"\n' > in/bad-solver.toml
step calibrate-bad-solver "$bin" calibrate --robot "$robot" --data in/train.csv --out m-bad --config in/bad-solver.toml
printf '[residual]\nmodel = "svm"\n' > in/bad-model.toml
step calibrate-bad-model "$bin" calibrate --robot "$robot" --data in/train.csv --out m-bad --config in/bad-model.toml
printf '[residual]\nmodel = "somm"\n[residual.x]\nhidden = [4]\nlearning_rate = -1.0\n' > in/bad-rate.toml
step calibrate-bad-rate "$bin" calibrate --robot "$robot" --data in/train.csv --out m-bad --config in/bad-rate.toml
printf '[kinematic]\nsolver = "lm"\nspeed = 3\n' > in/bad-key.toml
step calibrate-bad-key "$bin" calibrate --robot "$robot" --data in/train.csv --out m-bad --config in/bad-key.toml
# The paper's experiment: its tables, results.json and report (figures not compared: PNG
# encoders may differ in bytes for the same picture).
step run-paper "$bin" run "$root/configs/experiments/paper.toml" --out paper-report
sed -i 's|paper-report/paper|REPORT|' run-paper.stderr
find paper-report -name '*.png' -delete
for f in m-*/report.json paper-report/paper/results.json paper-report/paper/report.md; do mask -i "$f"; done
rm -rf in
