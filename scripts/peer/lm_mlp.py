#!/usr/bin/env python3
"""An outside comparison pipeline, independent of robocal, run on robocal's twin cases or any case folder.

A short scipy + scikit-learn calibration, written independently of robocal (nothing of robocal
is imported): the nominal table's base frame registered onto the tracker points (Kabsch), then
Levenberg-Marquardt (MINPACK, `scipy.optimize.least_squares(method="lm")`) on every identifiable
entry of the modified-DH table (Hayati beta where the file declares one), the base frame and the
tool point, on the rows at the lightest load, parameters the poses cannot determine (pivoted QR
of the column-scaled Jacobian there, relative tolerance 1e-6) held at their registered values; then one `MLPRegressor` per world axis on the kinematic residual of every training row,
inputs sin and cos of every joint angle and the load, standardized, early stopping on a 20 %
hold-out, the best of a 4-point grid of sizes and learning rates by the hold-out score.

Input: the case directories written by the accuracy suite's `--export DIR` (each holds the nominal
`robot.toml`, `train.csv`, `test.csv`, and `truth.csv`, the test rows' noise-free points). Every
error is the mean Euclidean distance (mm) from the noise-free point on the test rows. With
`--robocal BIN` the same case is also calibrated by `BIN calibrate` (the default, no `--config`)
and evaluated against `truth.csv` by `BIN evaluate --json`, through the files, like a user.

    python scripts/peer/lm_mlp.py CASES_DIR [--robocal target/release/robocal] [--only SUBSTR]

Prints a Markdown table: case, test rows, peer kinematic, peer LM + MLP, peer seconds, robocal
default, robocal seconds, robocal against the peer.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.linalg import qr
from scipy.optimize import least_squares
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from marked import write_marked  # noqa: E402

GRID = [((64, 64), 1e-3), ((64, 64), 3e-3), ((128, 128), 1e-3), ((128, 128), 3e-3)]


class Robot:
    """The robot file's table as a flat parameter vector (mm and rad)."""

    def __init__(self, path: Path):
        spec = tomllib.loads(path.read_text())
        self.names: list[str] = []
        values: list[float] = []
        self.layout: list[dict[str, int]] = []
        for i, joint in enumerate(spec["joint"], start=1):
            slots = {}
            for field in ("a", "alpha", "beta", "d", "theta"):
                if field not in joint:
                    continue
                slots[field] = len(values)
                angle = field in ("alpha", "beta", "theta")
                values.append(math.radians(joint[field]) if angle else float(joint[field]))
                self.names.append(f"j{i}.{field}")
            self.layout.append(slots)
        base = spec.get("base", {})
        self.base = len(values)
        values += [float(v) for v in base.get("xyz", [0.0, 0.0, 0.0])]
        values += [math.radians(v) for v in base.get("rpy", [0.0, 0.0, 0.0])]
        self.names += ["base.x", "base.y", "base.z", "base.roll", "base.pitch", "base.yaw"]
        self.tool = len(values)
        values += [float(v) for v in spec.get("tool", {}).get("xyz", [0.0, 0.0, 0.0])]
        self.names += ["tool.x", "tool.y", "tool.z"]
        self.nominal = np.array(values)

    def points(self, x: np.ndarray, q: np.ndarray) -> np.ndarray:
        """World positions of the tool point, rows of joint angles `q` (rad)."""
        n = q.shape[0]
        bx, by, bz, roll, pitch, yaw = x[self.base : self.base + 6]
        t = np.broadcast_to(
            _frame(_rz(yaw) @ _ry(pitch) @ _rx(roll), [bx, by, bz]), (n, 4, 4)
        ).copy()
        for i, slots in enumerate(self.layout):
            get = lambda f: x[slots[f]] if f in slots else 0.0  # noqa: E731
            fixed = _frame(_rx(get("alpha")), [0, 0, 0]) @ _frame(np.eye(3), [get("a"), 0, 0])
            fixed = fixed @ _frame(_ry(get("beta")), [0, 0, 0])
            angle = get("theta") + q[:, i]
            c, s = np.cos(angle), np.sin(angle)
            turn = np.zeros((n, 4, 4))
            turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = c, -s, s, c
            turn[:, 2, 2] = turn[:, 3, 3] = 1.0
            turn[:, 2, 3] = get("d")
            t = t @ fixed @ turn
        tool = x[self.tool : self.tool + 3]
        return np.einsum("nij,j->ni", t[:, :3, :3], tool) + t[:, :3, 3]


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _frame(r, p):
    f = np.eye(4)
    f[:3, :3] = r
    f[:3, 3] = p
    return f


def read_rows(path: Path, joints: int):
    """(joint angles rad, load kg, positions mm, pose ids) of a measurement CSV."""
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    q = np.radians([[float(r[f"q{k}"]) for k in range(1, joints + 1)] for r in rows])
    load = np.array([float(r.get("load") or 0.0) for r in rows])
    p = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])
    return q, load, p, [r["pose"] for r in rows]


def jacobian(robot: Robot, x: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Central differences of the stacked positions in every parameter."""
    cols = []
    for k in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[k]))
        up, down = x.copy(), x.copy()
        up[k] += h
        down[k] -= h
        cols.append(((robot.points(up, q) - robot.points(down, q)) / (2 * h)).ravel())
    return np.stack(cols, axis=1)


def register(robot: Robot, q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The nominal table with its base frame moved onto the measurements (Kabsch, SVD): the
    tracker frame is anywhere, and LM starts from here."""
    x = robot.nominal.copy()
    x[robot.base : robot.base + 6] = 0.0
    a = robot.points(x, q)
    ca, cp = a.mean(axis=0), p.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (p - cp))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    x[robot.base : robot.base + 3] = cp - r @ ca
    x[robot.base + 3 : robot.base + 6] = [
        math.atan2(r[2, 1], r[2, 2]),
        -math.asin(max(-1.0, min(1.0, r[2, 0]))),
        math.atan2(r[1, 0], r[0, 0]),
    ]
    return x


def identify(robot: Robot, q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """LM from the registered nominal table on the identifiable parameters (pivoted QR of the
    column-scaled Jacobian there); the rest held."""
    start = register(robot, q, p)
    j = jacobian(robot, start, q)
    norms = np.linalg.norm(j, axis=0)
    norms[norms == 0] = 1.0
    _, r, pivots = qr(j / norms, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > 1e-6 * diag[0]))
    free = np.sort(pivots[:rank])

    def residual(v):
        x = start.copy()
        x[free] = v
        return (robot.points(x, q) - p).ravel()

    fit = least_squares(residual, start[free], method="lm", x_scale="jac", max_nfev=20000)
    x = start.copy()
    x[free] = fit.x
    return x


def features(q: np.ndarray, load: np.ndarray) -> np.ndarray:
    return np.hstack([np.sin(q), np.cos(q), load[:, None]])


def peer(case: Path):
    """The peer pipeline on one case: (kinematic mean, LM + MLP mean, seconds, test rows)."""
    robot = Robot(case / "robot.toml")
    joints = len(robot.layout)
    q, load, p, _ = read_rows(case / "train.csv", joints)
    qt, loadt, _, _ = read_rows(case / "test.csv", joints)
    _, _, truth, _ = read_rows(case / "truth.csv", joints)
    start = time.perf_counter()
    light = load == load.min()
    x = identify(robot, q[light], p[light])
    residual = p - robot.points(x, q)
    inputs = StandardScaler().fit(features(q, load))
    xi, xt = inputs.transform(features(q, load)), inputs.transform(features(qt, loadt))
    kinematic = robot.points(x, qt)
    corrected = kinematic.copy()
    for axis in range(3):
        y = residual[:, axis]
        mean, scale = y.mean(), y.std() or 1.0
        best = None
        for hidden, rate in GRID:
            net = MLPRegressor(
                hidden_layer_sizes=hidden,
                learning_rate_init=rate,
                early_stopping=True,
                validation_fraction=0.2,
                n_iter_no_change=20,
                max_iter=2000,
                random_state=0,
            ).fit(xi, (y - mean) / scale)
            if best is None or net.best_validation_score_ > best.best_validation_score_:
                best = net
        corrected[:, axis] += mean + scale * best.predict(xt)
    seconds = time.perf_counter() - start
    error = lambda pred: float(np.linalg.norm(pred - truth, axis=1).mean())  # noqa: E731
    return error(kinematic), error(corrected), seconds, len(truth)


def robocal(binary: str, case: Path):
    """robocal's default calibrate on `train.csv`, evaluated on `truth.csv`: (mean, seconds)."""
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "model"
        start = time.perf_counter()
        subprocess.run(
            [binary, "calibrate", "--robot", case / "robot.toml", "--data", case / "train.csv",
             "--out", model],
            check=True, capture_output=True,
        )
        seconds = time.perf_counter() - start
        out = subprocess.run(
            [binary, "evaluate", "--model", model, "--data", case / "truth.csv", "--json"],
            check=True, capture_output=True, text=True,
        )
    return json.loads(out.stdout)["mean"], seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", type=Path)
    parser.add_argument("--robocal", help="robocal binary: also run its default calibrate")
    parser.add_argument("--only", default="", help="cases whose name contains this")
    parser.add_argument("--write", type=Path, help="also write the table into this Markdown file")
    parser.add_argument("--section", default="twins-peer", help="the marked section --write replaces")
    args = parser.parse_args()
    cases = sorted(c for c in args.cases.iterdir() if (c / "train.csv").exists())
    cases = [c for c in cases if args.only in c.name]
    if not cases:
        sys.exit(f"error: no case directories (with train.csv) under {args.cases}")
    lines = ["| case | test rows | peer kinematic | peer LM + MLP | peer s | robocal default | "
             "robocal s | robocal vs peer |", "|---|---|---|---|---|---|---|---|"]
    print("\n".join(lines))
    for case in cases:
        kin, mlp, secs, n = peer(case)
        row = f"| {case.name} | {n} | {kin:.4f} | {mlp:.4f} | {secs:.1f} |"
        if args.robocal:
            ours, ours_s = robocal(args.robocal, case)
            row += f" **{ours:.4f}** | {ours_s:.1f} | {100 * (ours / mlp - 1):+.0f} % |"
        else:
            row += " | | |"
        print(row, flush=True)
        lines.append(row)
    if args.write:
        write_marked(args.write, args.section, "\n".join(lines))

if __name__ == "__main__":
    main()
