#!/usr/bin/env python3
"""A network's seed, and networks averaged over seeds, on robocal's own twin cases.

On each case directory written by the
accuracy suite's `--export DIR` (nominal `robot.toml`, `train.csv`, `test.csv`, and `truth.csv`,
the test rows' noise-free points), one physical model for all (a stage config: compliances,
transmission harmonics of orders 1 and 2, self-weight, backlash on either flank) with robocal's
SOMM on it, once per seed, and once as `members = 5` (five sets of networks averaged, member m
seeded seed + 1000 m, each on its own hold-out). Every calibration goes through the files,
`BIN calibrate --config` then `BIN predict`, like a user; errors are the mean Euclidean distance
(mm) from the noise-free point on the test rows.

    python3 scripts/network_seeds.py CASES_DIR [--robocal target/release/robocal]
        [--seeds 2020,1,2,3,4] [--members 5] [--only SUBSTR] [--keep DIR]

Prints a Markdown table: case, test rows, one network of the first seed, the seeds' mean
[min-max] and the first seed's rank among them, the members, and the members against the first
seed and against the seeds' mean; then the counts.
"""

from __future__ import annotations

import argparse
import csv
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PHYSICS = """[kinematic]
solver = "lm"

[compliance]

[joint_errors]
harmonics = 2
self_weight = true
backlash = true
backlash_torque = true
"""


def stage(seed: int, members: int) -> str:
    text = PHYSICS + f'\n[residual]\nmodel = "somm"\nseed = {seed}\nholdout = 0.2\n'
    return text + (f"members = {members}\n" if members > 1 else "")


def points(path: Path) -> list[tuple[float, float, float]]:
    with path.open() as f:
        return [(float(r["x"]), float(r["y"]), float(r["z"])) for r in csv.DictReader(f)]


def mean_error(pred: Path, truth: list[tuple[float, float, float]]) -> float:
    p = points(pred)
    if len(p) != len(truth):
        sys.exit(f"{pred}: {len(p)} rows, the truth has {len(truth)}")
    return sum(math.dist(a, b) for a, b in zip(p, truth)) / len(truth)


def run(binary: str, case: Path, work: Path, name: str, text: str) -> tuple[float, float]:
    """Calibrates `case` with the stage config `text` into `work/name`; (seconds, mean error)."""
    config = work / f"{name}.toml"
    config.write_text(text)
    model, pred = work / name, work / f"{name}.csv"
    start = time.monotonic()
    for args in (
        ["calibrate", "--robot", case / "robot.toml", "--data", case / "train.csv",
         "--config", config, "--out", model],
        ["predict", "--model", model, "--data", case / "test.csv", "--out", pred],
    ):
        done = subprocess.run([binary, *map(str, args)], capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"{case.name} {name}: {args[0]} failed:\n{done.stderr[-2000:]}")
        if args[0] == "calibrate":
            seconds = time.monotonic() - start
    return seconds, mean_error(pred, points(case / "truth.csv"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", type=Path)
    ap.add_argument("--robocal", default="target/release/robocal")
    ap.add_argument("--seeds", default="2020,1,2,3,4")
    ap.add_argument("--members", type=int, default=5)
    ap.add_argument("--only", default="")
    ap.add_argument("--keep", type=Path, help="write the models here instead of a temporary directory")
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    if len(seeds) < 2 or a.members < 2:
        sys.exit("give at least two seeds and two members")
    cases = sorted(d for d in a.cases.iterdir() if (d / "truth.csv").is_file() and a.only in d.name)
    if not cases:
        sys.exit(f"{a.cases}: no exported cases (directories with truth.csv)")
    print(f"| case | test rows | one network, seed {seeds[0]} | one network, mean of {len(seeds)} seeds "
          f"[min–max] | seed {seeds[0]}'s rank | {a.members} members | s | vs seed {seeds[0]} "
          f"| vs mean of seeds |")
    print("|---|---|---|---|---|---|---|---|---|")
    vs_first, vs_mean = [], []
    with tempfile.TemporaryDirectory() as tmp:
        root = a.keep or Path(tmp)
        for case in cases:
            work = root / case.name
            work.mkdir(parents=True, exist_ok=True)
            one = [run(a.robocal, case, work, f"seed{s}", stage(s, 1))[1] for s in seeds]
            seconds, avg = run(a.robocal, case, work, "members", stage(seeds[0], a.members))
            mean = sum(one) / len(one)
            rank = 1 + sum(e < one[0] for e in one)
            vs_first.append(avg / one[0] - 1)
            vs_mean.append(avg / mean - 1)
            rows = len(points(case / "truth.csv"))
            print(f"| {case.name} | {rows} | {one[0]:.4f} | {mean:.4f} [{min(one):.4f}–{max(one):.4f}] "
                  f"| {rank} | {avg:.4f} | {seconds:.1f} | {100 * vs_first[-1]:+.1f} % "
                  f"| {100 * vs_mean[-1]:+.1f} % |", flush=True)
    n = len(cases)
    print(f"\n{n} cases: {a.members} members lower than seed {seeds[0]} on "
          f"{sum(c < 0 for c in vs_first)} (mean {100 * sum(vs_first) / n:+.1f} %), than the "
          f"seeds' mean on {sum(c < 0 for c in vs_mean)} (mean {100 * sum(vs_mean) / n:+.1f} %)")


if __name__ == "__main__":
    main()
