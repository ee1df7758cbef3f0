#!/usr/bin/env python3
"""robocal on real arms: the bundled laser-tracker datasets on fixed splits.

For each split, through the files like a user (`BIN calibrate`, then `BIN evaluate --json` on
the held-out rows): the nominal table with only base and tool fitted, kinematic identification
alone (`configs/stages/kinematic-lm.toml`), the default `calibrate` (its seconds and peak memory
too), the scipy + scikit-learn peer of `scripts/peer/lm_mlp.py` (independent of robocal), and the
number the dataset's source publishes on the same poses where it has one. Errors are the mean
Euclidean distance (mm) from the tracker's reading on poses never trained on: a real arm has no
noise-free point, so each error includes the tracker's noise and the arm's repeatability.

    python3 scripts/real/benchmark.py --robocal target/release/robocal [--write docs/accuracy.md]
        [--only NAME] [--no-peer]

With `--write FILE` the table replaces what lies between the lines `<!-- real-arms:begin -->` and
`<!-- real-arms:end -->` of FILE. `just accuracy-real` runs it with the peer's venv.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# name, dataset folder, training file, test file, what the split is, the source's published
# mean on the test rows (mm) and what made it.
SPLITS = [
    ("UR5 grid → 20 random", "ur5", "grid.csv", "random.csv",
     "1,000 grid poses → 20 random poses", 0.1549, "MDH + ASTGCN (thesis)"),
    ("WAM grid → 20 random", "wam", "grid.csv", "random.csv",
     "216 grid poses → 20 random poses", 2.9178, "MDH + ASTGCN (thesis)"),
]

BASE_TOOL = """[kinematic]
solver = "lm"
parameters = ["base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz", "tool.x", "tool.y", "tool.z"]
"""


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
    sys.path.insert(0, str(ROOT / "scripts" / "peer"))
    import lm_mlp  # noqa: E402  (numpy, scipy, scikit-learn)

    with tempfile.TemporaryDirectory() as tmp:
        case = Path(tmp)
        shutil.copy(robot, case / "robot.toml")
        shutil.copy(train, case / "train.csv")
        shutil.copy(test, case / "test.csv")
        shutil.copy(test, case / "truth.csv")
        _, corrected, seconds, _ = lm_mlp.peer(case)
    return corrected, seconds


def table(rows: list[dict]) -> str:
    head = ("| split | test poses | nominal (base, tool fitted) | kinematic | **default** "
            "(± 95 % interval) | peer (scipy LM + MLP) | default against the peer | published | "
            "default s | default MiB |")
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        peer = f"{r['peer']:.4f}" if r["peer"] is not None else "—"
        against = (f"{100 * (r['default'] / r['peer'] - 1):+.0f} %" if r["peer"] is not None
                   else "—")
        published = f"{r['published']:.4f} ({r['published_by']})" if r["published"] else "—"
        lines.append(
            f"| {r['name']} | {r['test_rows']} | {r['nominal']:.4f} | {r['kinematic']:.4f} | "
            f"**{r['default']:.4f}** (± {r['interval']:.4f}) | {peer} | {against} | {published} | "
            f"{r['seconds']:.0f} | {r['mib']:.0f} |")
    return "\n".join(lines)


def write_marked(path: Path, text: str):
    begin, end = "<!-- real-arms:begin -->", "<!-- real-arms:end -->"
    page = path.read_text()
    if begin not in page or end not in page:
        sys.exit(f"{path}: no `{begin}` … `{end}` section to write the table into")
    head, rest = page.split(begin, 1)
    _, tail = rest.split(end, 1)
    path.write_text(f"{head}{begin}\n{text}\n{end}{tail}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robocal", default=str(ROOT / "target/release/robocal"))
    parser.add_argument("--write", type=Path, help="rewrite this file's real-arms section")
    parser.add_argument("--only", default="", help="splits whose name contains this")
    parser.add_argument("--no-peer", action="store_true", help="leave the peer out")
    args = parser.parse_args()
    rows = []
    for name, folder, train_file, test_file, what, published, published_by in SPLITS:
        if args.only not in name:
            continue
        data = ROOT / "datasets" / folder
        robot, train, test = data / "robot.toml", data / train_file, data / test_file
        test_rows = sum(1 for _ in test.open()) - 1
        with tempfile.TemporaryDirectory() as tmp:
            base_tool = Path(tmp) / "base-tool.toml"
            base_tool.write_text(BASE_TOOL)
            nominal = calibrated_error(args.robocal, robot, train, test, base_tool)[0]
        kinematic = calibrated_error(args.robocal, robot, train, test,
                                     ROOT / "configs/stages/kinematic-lm.toml")[0]
        mean, std, seconds, mib = calibrated_error(args.robocal, robot, train, test, None)
        peer = None if args.no_peer else peer_error(robot, train, test)[0]
        row = dict(name=name, what=what, test_rows=test_rows, nominal=nominal,
                   kinematic=kinematic, default=mean, interval=1.96 * std / math.sqrt(test_rows),
                   peer=peer, published=published, published_by=published_by, seconds=seconds,
                   mib=mib)
        print(f"{name}: {json.dumps(row)}", file=sys.stderr)
        rows.append(row)
    text = table(rows)
    print(text)
    if args.write:
        write_marked(args.write, text)


if __name__ == "__main__":
    main()
