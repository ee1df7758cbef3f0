#!/usr/bin/env python3
"""What the data determine beyond joint 1's readings: the default model, its physics alone, the
physics with joint 1's harmonics continued periodically, and that model's standard deviation.

For each case directory written by the accuracy suite's `--export DIR` (the nominal `robot.toml`,
`train.csv`, `test.csv`, and `truth.csv`, the test rows' noise-free points), through the files
like a user (standard library only):

1. `robocal calibrate` (the default, no `--config`; `--budget` passed on) into a model directory;
2. the same directory without `residual.json`: the chosen physics alone;
3. that without any harmonic's `reach` in `compliance.toml`: every harmonic continued at every
   angle (what the physics says far beyond the readings, where the default holds a harmonic
   beyond a quarter of its joint's span past them unless its blocks of joint 1 say otherwise);
4. `robocal predict --sigma` of (3) on the test rows: each point's standard deviation from the
   identified parameters' covariance under the harmonics' prior (`docs/formats.md`,
   `covariance.json`) — how far the data pin the continued physics down there.

Prints a Markdown table: case, test rows, noise floor (the measured test points' mean distance
from the noise-free ones), the default's mean error against the noise-free points and its ratio
to the floor, the physics alone, continued, the continued model's mean deviation and its ratio
to the floor, the root mean square of the continued errors over that of the deviations, and the
default's choice. Twins' numbers, never a real robot's.

    python scripts/extrapolation/reach.py CASES_DIR --robocal target/release/robocal [--only SUBSTR] [--budget S]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def points(path: Path) -> list[tuple[float, float, float]]:
    with path.open(newline="") as f:
        return [(float(r["x"]), float(r["y"]), float(r["z"])) for r in csv.DictReader(f)]


def distance(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return math.dist(a, b)


def mean(values: list[float]) -> float:
    return sum(values) / len(values)


def run(args: list[str]) -> str:
    done = subprocess.run(args, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return done.stdout


def evaluate(robocal: str, model: Path, truth: Path) -> float:
    return json.loads(run([robocal, "evaluate", "--model", str(model), "--data", str(truth), "--json"]))["mean"]


def case_row(robocal: str, case: Path, work: Path, budget: str | None) -> str:
    model = work / case.name
    calibrate = [robocal, "calibrate", "--robot", str(case / "robot.toml"), "--data", str(case / "train.csv"), "--out", str(model)]
    if budget:
        calibrate += ["--budget", budget]
    run(calibrate)
    physics = work / f"{case.name}.physics"
    shutil.copytree(model, physics)
    (physics / "residual.json").unlink(missing_ok=True)
    continued = work / f"{case.name}.continued"
    shutil.copytree(physics, continued)
    compliance = continued / "compliance.toml"
    if compliance.exists():
        text = compliance.read_text()
        compliance.write_text(re.sub(r"(?m)^reach = .*\n", "", text))
    predicted = work / f"{case.name}.continued.csv"
    run([robocal, "predict", "--model", str(continued), "--data", str(case / "truth.csv"), "--out", str(predicted), "--sigma"])

    truth = points(case / "truth.csv")
    floor = mean([distance(m, t) for m, t in zip(points(case / "test.csv"), truth)])
    with predicted.open(newline="") as f:
        rows = list(csv.DictReader(f))
    errors = [distance((float(r["x"]), float(r["y"]), float(r["z"])), t) for r, t in zip(rows, truth)]
    sigmas = [float(r["sigma"]) for r in rows] if rows and "sigma" in rows[0] else []
    default = evaluate(robocal, model, case / "truth.csv")
    alone = evaluate(robocal, physics, case / "truth.csv")
    report = json.loads((model / "report.json").read_text())
    chosen = next(
        (c["name"] for c in report["selection"]["candidates"] if c["status"].startswith("chosen")),
        "",
    )
    chosen = chosen.replace("kinematic + compliance", "…")
    if sigmas:
        sigma = mean(sigmas)
        ratio = math.sqrt(mean([e * e for e in errors]) / mean([s * s for s in sigmas]))
        spread = f"{sigma:.4f} | {sigma / floor:.2f}× | {ratio:.2f}"
    else:
        spread = "– | – | –"
    return (
        f"| {case.name} | {len(truth)} | {floor:.4f} | {default:.4f} | {default / floor:.2f}× | "
        f"{alone:.4f} | {mean(errors):.4f} | {spread} | {chosen} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", type=Path)
    parser.add_argument("--robocal", required=True)
    parser.add_argument("--only", default="")
    parser.add_argument("--budget")
    args = parser.parse_args()
    cases = sorted(p for p in args.cases.iterdir() if p.is_dir() and args.only in p.name)
    if not cases:
        sys.exit(f"{args.cases}: no case directory matches `{args.only}`")
    print(
        "| case | test rows | noise floor | default | vs floor | physics alone | harmonics continued "
        "| its mean σ | σ vs floor | rms error / rms σ | default's choice |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            print(case_row(args.robocal, case, Path(tmp), args.budget), flush=True)


if __name__ == "__main__":
    main()
