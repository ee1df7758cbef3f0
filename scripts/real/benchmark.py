#!/usr/bin/env python3
"""robocal on real arms: the bundled laser-tracker datasets on fixed splits.

For each split, through the files like a user (`BIN calibrate`, then `BIN evaluate --json` on
the held-out rows): the nominal table with only base and tool fitted, kinematic identification
alone (`configs/stages/kinematic-lm.toml`), the default `calibrate` (its seconds and peak memory
too), on a 6-DoF probe's files (the UR10) the default again from the positions alone, the
scipy + scikit-learn peer of `scripts/peer/lm_mlp.py` (independent of robocal), and the
number the dataset's source publishes on the same poses where it has one. Errors are the mean
Euclidean distance (mm) from the tracker's reading on poses never trained on: a real arm has no
noise-free point, so each error includes the tracker's noise and the arm's repeatability.

    python3 scripts/real/benchmark.py --robocal target/release/robocal [--write docs/accuracy.md]
        [--only NAME] [--no-peer]

With `--write FILE` the table replaces what lies between the lines `<!-- real-arms:begin -->` and
`<!-- real-arms:end -->` of FILE. `just accuracy-real` runs it with the peer's venv. UR10 Series B
is kept aside while developing: `--aside` adds its splits, run once to report a decided change.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
from marked import write_marked  # noqa: E402

# Fixed splits: name, dataset folder, file, how the poses are split, the source's published mean
# on the test rows (mm) and what made it. Splits: ("file", TEST_FILE) — train on the file, test
# on another; ("random", fraction) — a seeded random share of the poses held out; ("q1", share)
# — the share of the poses with the highest joint-1 reading held out (an extrapolation);
# ("first", count) — the first `count` poses in a seeded random order trained on, the rest held
# out.
SPLITS = [
    ("UR5 grid → 20 random", "ur5", "grid.csv", ("file", "random.csv"), 0.1549,
     "MDH + ASTGCN (thesis)"),
    ("WAM grid → 20 random", "wam", "grid.csv", ("file", "random.csv"), 2.9178,
     "MDH + ASTGCN (thesis)"),
    ("UR10 A grid, 1,000 poses → the rest", "ur10-tmac", "series-a-grid.csv", ("first", 1000),
     None, None),
    ("UR10 A grid, random 30 %", "ur10-tmac", "series-a-grid.csv", ("random", 0.3), None, None),
    ("UR10 A grid, highest q1 quarter", "ur10-tmac", "series-a-grid.csv", ("q1", 0.25), None,
     None),
    ("UR10 C random poses, random 30 %", "ur10-tmac", "series-c-random.csv", ("random", 0.3),
     None, None),
    ("UR10 C random poses, highest q1 quarter", "ur10-tmac", "series-c-random.csv", ("q1", 0.25),
     None, None),
    ("UR10 D ISO cubes, random 30 %", "ur10-tmac", "series-d-iso-cubes.csv", ("random", 0.3),
     None, None),
    ("UR10 D ISO cubes, highest q1 quarter", "ur10-tmac", "series-d-iso-cubes.csv", ("q1", 0.25),
     None, None),
]

# Kept aside while developing (`--aside` runs them, once, to report a decided change).
ASIDE = [
    ("UR10 B joint configurations, random 30 %", "ur10-tmac",
     "series-b-joint-configurations.csv", ("random", 0.3), None, None),
    ("UR10 B joint configurations, highest q1 quarter", "ur10-tmac",
     "series-b-joint-configurations.csv", ("q1", 0.25), None, None),
]

SEED = 2020


def split_rows(path: Path, how: tuple, folder: Path) -> tuple[Path, Path]:
    """Writes the training and test files of `how` on `path` into `folder`."""
    lines = path.read_text().splitlines()
    header, rows = lines[0], lines[1:]
    cols = header.split(",")
    pose, q1 = cols.index("pose"), cols.index("q1")
    poses: dict[str, list[str]] = {}
    for r in rows:
        poses.setdefault(r.split(",")[pose], []).append(r)
    ids = list(poses)
    kind, arg = how
    if kind == "random":
        order = ids[:]
        random.Random(SEED).shuffle(order)
        test = set(order[: round(arg * len(order))])
    elif kind == "q1":
        by_q1 = sorted(ids, key=lambda p: float(poses[p][0].split(",")[q1]))
        test = set(by_q1[len(by_q1) - round(arg * len(by_q1)):])
    elif kind == "first":
        order = ids[:]
        random.Random(SEED).shuffle(order)
        test = set(order[arg:])
    else:
        raise ValueError(kind)
    train_file, test_file = folder / "train.csv", folder / "test.csv"
    train_file.write_text("\n".join([header] + [r for p in ids if p not in test for r in poses[p]]) + "\n")
    test_file.write_text("\n".join([header] + [r for p in ids if p in test for r in poses[p]]) + "\n")
    return train_file, test_file


def positions_only(path: Path, folder: Path) -> Path | None:
    """`path` without its orientation columns (`rx, ry, rz`), written into `folder`; `None` where
    it has none."""
    lines = path.read_text().splitlines()
    cols = lines[0].split(",")
    if "rx" not in cols:
        return None
    drop = {cols.index(c) for c in ("rx", "ry", "rz")}
    out = folder / "positions.csv"
    out.write_text("\n".join(",".join(v for i, v in enumerate(line.split(",")) if i not in drop)
                             for line in lines) + "\n")
    return out


def base_tool(robot: Path) -> str:
    """A stage config that fits only the base frame and the tool (its frame too where the robot
    file declares one: a 6-DoF probe's)."""
    names = ["base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz", "tool.x", "tool.y",
             "tool.z"]
    tool = robot.read_text().split("[tool]", 1)[-1]
    if "\nrpy" in tool:
        names += ["tool.rx", "tool.ry", "tool.rz"]
    return '[kinematic]\nsolver = "lm"\nparameters = [' + ", ".join(f'"{n}"' for n in names) + "]\n"


def run(cmd: list) -> str:
    """Runs a command and returns its standard output; stops with its error if it fails."""
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}):\n{proc.stderr}")
    return proc.stdout


def calibrated_error(binary: str, robot: Path, train: Path, test: Path, config: Path | None):
    """(mean error on the test rows, the errors' standard deviation, seconds, peak MiB)."""
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "model"
        cmd = [binary, "calibrate", "--robot", robot, "--data", train, "--out", model]
        if config is not None:
            cmd += ["--config", config]
        time_cmd = ["/usr/bin/time", "-f", "%M"] if shutil.which("/usr/bin/time") else []
        start = time.perf_counter()
        proc = subprocess.run([str(c) for c in time_cmd + cmd], capture_output=True, text=True)
        seconds = time.perf_counter() - start
        if proc.returncode != 0:
            sys.exit(f"{' '.join(map(str, cmd))} failed:\n{proc.stderr}")
        peak = float(proc.stderr.strip().splitlines()[-1]) / 1024.0 if time_cmd else float("nan")
        stats = json.loads(run([binary, "evaluate", "--model", model, "--data", test, "--json"]))
    return stats["mean"], stats["std"], seconds, peak


def peer_error(robot: Path, train: Path, test: Path):
    """The scipy + scikit-learn pipeline's mean error on the test rows (mm) and its seconds."""
    from peer import lm_mlp  # noqa: E402  (numpy, scipy, scikit-learn: imported when needed)

    with tempfile.TemporaryDirectory() as tmp:
        case = Path(tmp)
        shutil.copy(robot, case / "robot.toml")
        shutil.copy(train, case / "train.csv")
        shutil.copy(test, case / "test.csv")
        shutil.copy(test, case / "truth.csv")
        _, corrected, seconds, _ = lm_mlp.peer(case)
    return corrected, seconds


def table(rows: list[dict]) -> str:
    head = ("| split | test rows | nominal (base, tool fitted) | kinematic | **default** "
            "(± 95 % interval) | default from positions only | peer (scipy LM + MLP) | "
            "default against the peer | published | default s | default MiB |")
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        peer = f"{r['peer']:.4f}" if r["peer"] is not None else "—"
        test = f"{r['test_rows']:,}"
        positions = "—" if r["from_positions"] is None else f"{r['from_positions']:.4f}"
        against = (f"{100 * (r['default'] / r['peer'] - 1):+.0f} %" if r["peer"] is not None
                   else "—")
        published = f"{r['published']:.4f} ({r['published_by']})" if r["published"] else "—"
        lines.append(
            f"| {r['name']} | {test} | {r['nominal']:.4f} | {r['kinematic']:.4f} | "
            f"**{r['default']:.4f}** (± {r['interval']:.4f}) | {positions} | {peer} | {against} | {published} | "
            f"{r['seconds']:.0f} | {r['mib']:.0f} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robocal", default=str(ROOT / "target/release/robocal"))
    parser.add_argument("--write", type=Path, help="rewrite this file's real-arms section")
    parser.add_argument("--only", default="", help="splits whose name contains this")
    parser.add_argument("--no-peer", action="store_true", help="leave the peer out")
    parser.add_argument("--aside", action="store_true",
                        help="also the splits kept aside while developing (UR10 Series B)")
    args = parser.parse_args()
    rows = []
    for name, folder, file, how, published, published_by in SPLITS + (ASIDE if args.aside else []):
        if args.only not in name:
            continue
        data = ROOT / "datasets" / folder
        robot = data / "robot.toml"
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            if how[0] == "file":
                train, test = data / file, data / how[1]
            else:
                train, test = split_rows(data / file, how, tmp)
            test_rows = sum(1 for _ in test.open()) - 1
            stage = tmp / "base-tool.toml"
            stage.write_text(base_tool(robot))
            nominal = calibrated_error(args.robocal, robot, train, test, stage)[0]
            kinematic = calibrated_error(args.robocal, robot, train, test,
                                         ROOT / "configs/stages/kinematic-lm.toml")[0]
            mean, std, seconds, mib = calibrated_error(args.robocal, robot, train, test, None)
            positions = positions_only(train, tmp)
            from_positions = (None if positions is None else
                              calibrated_error(args.robocal, robot, positions, test, None)[0])
            peer = None if args.no_peer else peer_error(robot, train, test)[0]
        row = dict(name=name, test_rows=test_rows, nominal=nominal, kinematic=kinematic,
                   default=mean, from_positions=from_positions, interval=1.96 * std / math.sqrt(test_rows), peer=peer,
                   published=published, published_by=published_by, seconds=seconds, mib=mib)
        print(f"{name}: {json.dumps(row)}", file=sys.stderr, flush=True)
        rows.append(row)
    text = table(rows)
    print(text)
    if args.write:
        write_marked(args.write, "real-arms", text)


if __name__ == "__main__":
    main()
